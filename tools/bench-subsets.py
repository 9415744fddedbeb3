#!/usr/bin/env python3
"""Split builds: a plan, its subsets built one after another as separate processes (as the
tasks of a batch array would run on one machine), and the merge, against a plain convert of the
same model with the same memory limit.

Prints, per subset count, the plan's time, each subset's time and peak memory (median and
largest), the merge's time and peak memory, the total against the plain convert, and what the
merge copied (blocks and raw bytes; it rebuilds nothing). Each row also checks that the merged
container is byte for byte the one `convert --plan` writes when asked (--check; costs one more
full build).

    cargo build --release -p oocfmt-cli
    python3 tools/bench-subsets.py --size 1e7 --subsets 4,8 --mem-limit 256M
    python3 tools/bench-subsets.py --size 1e8 --subsets 4,8 --mem-limit 2G --dir /big/scratch
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

from benchlib import BIN, machine, require_binary, run


def report(args, path):
    """Runs `oocfmt ARGS --quiet --report-json PATH`; returns the report and the wall time."""
    t = time.monotonic()
    run(args + ["--quiet", "--report-json", path])
    took = time.monotonic() - t
    with open(path) as f:
        return json.load(f), took


def mib(b):
    return f"{b / 1048576:.0f} MiB" if b else "n/a"


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--size", default="1e7", help="Mandelbulb triangles to generate")
    p.add_argument("--subsets", default="4,8", help="comma-separated subset counts")
    p.add_argument("--mem-limit", default="256M", help="--mem-limit of every build")
    p.add_argument("--dir", default=None, help="scratch folder (default: a temporary one)")
    p.add_argument("--check", action="store_true", help="also compare with `convert --plan`")
    a = p.parse_args()
    require_binary()
    work = a.dir or tempfile.mkdtemp(prefix="oocfmt-subsets-")
    size = int(float(a.size))
    obj = os.path.join(work, f"mandelbulb-{size}.obj")
    if not os.path.exists(obj):
        run(["gen", "mandelbulb", "--tris", str(size), "-o", obj, "--quiet"])
    print(f"machine: {machine()}")
    print(f"model: {obj} ({os.path.getsize(obj)} bytes), --mem-limit {a.mem_limit}\n")

    plain_out = os.path.join(work, "plain.oocf")
    plain, _ = report(["convert", obj, "-o", plain_out, "--mem-limit", a.mem_limit], os.path.join(work, "plain.json"))
    os.remove(plain_out)
    print(f"plain convert: {plain['seconds']:.1f} s, peak {mib(plain.get('peak_memory_bytes'))}, "
          f"{plain['file_bytes']} bytes\n")
    print("| subsets | plan s | subset s (median / max) | subset peak memory (max) | merge s | merge peak memory "
          "| total s | total / plain | copied blocks | copied raw bytes |")
    print("|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|")
    for n in [int(x) for x in a.subsets.split(",") if x]:
        plan = os.path.join(work, f"plan-{n}.json")
        t = time.monotonic()
        out = run(["plan", obj, "--subsets", str(n), "--mem-limit", a.mem_limit, "-o", plan, "--json", "--quiet"])
        plan_s = time.monotonic() - t
        m = json.loads(out)["subsets"]
        parts, subs = [], []
        for i in range(m):
            part = os.path.join(work, f"part-{n}-{i}.oocfp")
            r, _ = report(["convert", "--plan", plan, "--subset", str(i), "-o", part], os.path.join(work, "sub.json"))
            subs.append(r)
            parts.append(part)
        merged = os.path.join(work, f"merged-{n}.oocf")
        mr, _ = report(["merge", *parts, "-o", merged], os.path.join(work, "merge.json"))
        if a.check:
            single = os.path.join(work, f"single-{n}.oocf")
            run(["convert", "--plan", plan, "-o", single, "--quiet"])
            same = subprocess.run(["cmp", "-s", merged, single]).returncode == 0
            os.remove(single)
            if not same:
                sys.exit(f"{n} subsets: the merge differs from convert --plan")
        for part in parts:
            os.remove(part)
        os.remove(merged)
        secs = [s["seconds"] for s in subs]
        peak = max(s.get("peak_memory_bytes") or 0 for s in subs)
        total = plan_s + sum(secs) + mr["convert"]["seconds"]
        print(f"| {m} | {plan_s:.1f} | {statistics.median(secs):.1f} / {max(secs):.1f} | {mib(peak)} "
              f"| {mr['convert']['seconds']:.1f} | {mib(mr['convert'].get('peak_memory_bytes'))} "
              f"| {total:.1f} | {total / plain['seconds']:.2f} | {mr['copied_blocks']} | {mr['copied_bytes']} |")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
