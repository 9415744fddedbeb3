#!/usr/bin/env python3
"""Out of core against in core, per triangle (issue 28, item 4): alternates, round by round, an
in-core conversion of a smaller Mandelbulb with out-of-core conversions of a larger one under
--mem-limit, by this build and optionally by a --baseline binary (an older build to compare
with), and prints each round's seconds and the ratio of the time per triangle out of core to
the time per triangle in core of the same round, then the medians. The machine's speed wanders
by 10-15 % within minutes, so only ratios within a round are compared.

    cargo build --release -p oocfmt-cli
    cp target/release/oocfmt /tmp/oocfmt-old     # before the change
    python3 tools/bench-ooc.py --in-core 1e7 --out-of-core 1e8 --mem-limit 2G --runs 3 \\
        --baseline /tmp/oocfmt-old

The OBJ files are generated once into --dir and kept. Standard library only.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys

from benchlib import BIN, ROOT, machine, require_binary


def convert(binary, obj, out, limit):
    """One conversion; returns its --report-json."""
    report = out + ".json"
    args = [binary, "convert", obj, "-o", out, "--quiet", "--report-json", report]
    if limit:
        args += ["--mem-limit", limit]
    r = subprocess.run(args, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"{' '.join(args)} failed ({r.returncode}):\n{r.stdout}{r.stderr}")
    with open(report) as f:
        rep = json.load(f)
    os.remove(out)
    return rep


def model(binary, work, tris):
    obj = os.path.join(work, f"mandelbulb-{tris}.obj")
    if not os.path.exists(obj):
        subprocess.run([binary, "gen", "mandelbulb", "--tris", str(tris), "-o", obj, "--quiet"],
                       check=True)
    return obj


def per_triangle(rep):
    return rep["seconds"] / rep["import"]["triangles_out"]


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--in-core", default="1e7", help="triangles of the model converted in core")
    p.add_argument("--out-of-core", default="1e8", help="triangles of the model converted out of core")
    p.add_argument("--mem-limit", default="2G", help="--mem-limit of the out-of-core conversions")
    p.add_argument("--in-core-limit", default="", help="--mem-limit of the in-core one (default: the converter's)")
    p.add_argument("--baseline", help="another oocfmt binary, converting out of core in each round too")
    p.add_argument("--runs", type=int, default=3, help="rounds")
    p.add_argument("--dir", default=os.path.join(ROOT, "target", "bench-ooc"))
    a = p.parse_args()
    require_binary()
    os.makedirs(a.dir, exist_ok=True)
    small = model(BIN, a.dir, int(float(a.in_core)))
    big = model(BIN, a.dir, int(float(a.out_of_core)))
    builds = [("this build", BIN)] + ([("baseline", a.baseline)] if a.baseline else [])
    print(f"machine: {machine()}")
    print(f"in core: {os.path.basename(small)}; out of core: {os.path.basename(big)} "
          f"under --mem-limit {a.mem_limit}\n")
    print("| round | in core | " + " | ".join(f"out of core, {n}" for n, _ in builds) + " |")
    print("|--:|--:|" + "--:|" * len(builds))
    ratios = {n: [] for n, _ in builds}
    for k in range(a.runs):
        inside = convert(BIN, small, os.path.join(a.dir, "in.oocf"), a.in_core_limit)
        if inside.get("out_of_core"):
            sys.exit("the in-core model was built out of core: raise --in-core-limit")
        order = builds if k % 2 == 0 else list(reversed(builds))
        cells = {}
        for name, binary in order:
            rep = convert(binary, big, os.path.join(a.dir, "out.oocf"), a.mem_limit)
            if not rep.get("out_of_core"):
                sys.exit("the out-of-core model was built in core: lower --mem-limit")
            ratio = per_triangle(rep) / per_triangle(inside)
            ratios[name].append(ratio)
            chunks = rep["out_of_core"]["chunks"]
            cells[name] = (f"{rep['seconds']:.1f} s, {rep['triangles_per_second']:,.0f}/s, "
                           f"{chunks} chunks, {rep['peak_memory_bytes'] / 2**20:,.0f} MiB: {ratio:.3f}×")
        print(f"| {k + 1} | {inside['seconds']:.1f} s, {inside['triangles_per_second']:,.0f}/s | "
              + " | ".join(cells[n] for n, _ in builds) + " |", flush=True)
    print()
    for name, _ in builds:
        print(f"{name}: out of core / in core per triangle, median {statistics.median(ratios[name]):.3f} "
              f"(rounds: {', '.join(f'{r:.3f}' for r in ratios[name])})")


if __name__ == "__main__":
    main()
