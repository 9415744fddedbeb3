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

With --assembly K it measures an update instead: K Mandelbulbs of size/K triangles side by side
along x, one file each, planned in the first --subsets count; then one vertex of the middle file
moves, and `plan --update`, the subsets it lists and the merge with the others reused are timed
against a full rebuild from the new plan (plan, every subset, merge), whose bytes they must equal.

    python3 tools/bench-subsets.py --size 1e7 --assembly 8 --subsets 16 --mem-limit 256M
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
    p.add_argument("--assembly", type=int, default=0, help="measure an update of a K-file assembly")
    a = p.parse_args()
    require_binary()
    work = a.dir or tempfile.mkdtemp(prefix="oocfmt-subsets-")
    size = int(float(a.size))
    if a.assembly:
        update(a, work, size)
        return
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


def assembly(work, size, k):
    """K copies of a Mandelbulb of size/K triangles, the i-th moved 2.5 * i along x."""
    one = os.path.join(work, f"mandelbulb-{size // k}.obj")
    if not os.path.exists(one):
        run(["gen", "mandelbulb", "--tris", str(size // k), "-o", one, "--quiet"])
    files = []
    for i in range(k):
        path = os.path.join(work, f"part{i}.obj")
        with open(one) as src, open(path, "w") as dst:
            for line in src:
                if line.startswith("v "):
                    x, y, z = line.split()[1:4]
                    line = f"v {float(x) + 2.5 * i!r} {y} {z}\n"
                dst.write(line)
        files.append(path)
    return files


def nudge(path):
    """Moves the first vertex of `path` a little towards its neighbours (within the bounds)."""
    with open(path) as f:
        lines = f.readlines()
    for n, line in enumerate(lines):
        if line.startswith("v "):
            x, y, z = (float(c) for c in line.split()[1:4])
            lines[n] = f"v {x!r} {y!r} {z * 0.99!r}\n"
            break
    with open(path, "w") as f:
        f.writelines(lines)


def build(plan, work, tag, subsets):
    """Builds `subsets` of `plan`; returns their files and the seconds."""
    parts, secs = {}, 0.0
    for i in subsets:
        part = os.path.join(work, f"{tag}-{i}.oocfp")
        r, _ = report(["convert", "--plan", plan, "--subset", str(i), "-o", part], os.path.join(work, "sub.json"))
        parts[i] = part
        secs += r["seconds"]
    return parts, secs


def update(a, work, size):
    k = a.assembly
    n = int(a.subsets.split(",")[0])
    files = assembly(work, size, k)
    print(f"machine: {machine()}")
    print(f"assembly: {k} Mandelbulbs of {size // k} triangles, {n} subsets, --mem-limit {a.mem_limit}\n")
    old = os.path.join(work, "old.json")
    run(["plan", *files, "--subsets", str(n), "--mem-limit", a.mem_limit, "-o", old, "--quiet"])
    with open(old) as f:
        m = json.load(f)["subsets"]
    old_parts, _ = build(old, work, "old", range(m))
    nudge(files[k // 2])
    new = os.path.join(work, "new.json")
    t = time.monotonic()
    out = run(["plan", "--update", old, "-o", new, "--json", "--quiet"])
    update_plan_s = time.monotonic() - t
    rebuild = json.loads(out)["rebuild"]
    new_parts, rebuild_s = build(new, work, "new", rebuild)
    parts = [new_parts.get(i, old_parts[i]) for i in range(m)]
    updated = os.path.join(work, "updated.oocf")
    mr, _ = report(["merge", "--plan", new, *parts, "-o", updated], os.path.join(work, "merge.json"))
    update_s = update_plan_s + rebuild_s + mr["convert"]["seconds"]
    # The full rebuild from the same new plan: a fresh plan's time, every subset, the merge.
    t = time.monotonic()
    run(["plan", *files, "--subsets", str(n), "--mem-limit", a.mem_limit, "-o", os.path.join(work, "fresh.json"), "--quiet"])
    plan_s = time.monotonic() - t
    all_parts, all_s = build(new, work, "all", range(m))
    full = os.path.join(work, "full.oocf")
    fr, _ = report(["merge", "--plan", new, *[all_parts[i] for i in range(m)], "-o", full], os.path.join(work, "merge.json"))
    full_s = plan_s + all_s + fr["convert"]["seconds"]
    same = subprocess.run(["cmp", "-s", updated, full]).returncode == 0
    print("| | plan s | subsets built | subsets s | merge s | total s |")
    print("|--|--:|--:|--:|--:|--:|")
    print(f"| update | {update_plan_s:.1f} | {len(rebuild)} of {m} | {rebuild_s:.1f} | {mr['convert']['seconds']:.1f} | {update_s:.1f} |")
    print(f"| full rebuild | {plan_s:.1f} | {m} of {m} | {all_s:.1f} | {fr['convert']['seconds']:.1f} | {full_s:.1f} |")
    print(f"\nupdate / full: {update_s / full_s:.2f}; the two containers are {'identical' if same else 'DIFFERENT'}")
    if not same:
        sys.exit(1)


if __name__ == "__main__":
    main()
