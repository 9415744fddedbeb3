#!/usr/bin/env python3
"""Conversion benchmark: time against triangle count, in core and out of core.

Generates Mandelbulbs (and optionally the CAD scene) with `oocfmt gen`, converts each with the
release binary a few times, and prints a Markdown table of medians: seconds, triangles per second,
peak memory, file size and the per-phase times from `--report-json`. Ratios between rows are what
to compare; absolute figures depend on the machine, which is printed first.

    cargo build --release -p oocfmt-cli
    python3 tools/bench-convert.py --sizes 1e6,3e6,1e7 --runs 2
    python3 tools/bench-convert.py --sizes 1e6 --mem-limits 8G,256M,64M   # in core vs chunked
"""

import argparse
import json
import os
import statistics
import sys
import tempfile

from benchlib import machine, require_binary, run


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", default="1e6,3e6,1e7", help="triangle counts to generate")
    p.add_argument("--scene", default="mandelbulb", choices=["mandelbulb", "cad"])
    p.add_argument("--runs", type=int, default=2, help="conversions per row (the median is shown)")
    p.add_argument("--mem-limits", default="", help="comma-separated --mem-limit values (default: the converter's)")
    p.add_argument("--codec", default="lz4")
    p.add_argument("--dir", default=None, help="scratch folder (default: a temporary one)")
    a = p.parse_args()
    require_binary()
    limits = [x for x in a.mem_limits.split(",") if x] or [None]
    work = a.dir or tempfile.mkdtemp(prefix="oocfmt-bench-")
    print(f"machine: {machine()}")
    print(f"scene: {a.scene}, codec {a.codec}, {a.runs} run(s) per row, medians\n")
    print("| triangles | --mem-limit | chunks | seconds | triangles/s | peak memory | file | phases (s) |")
    print("|----------:|------------:|-------:|--------:|------------:|------------:|-----:|------------|")
    for size in [int(float(s)) for s in a.sizes.split(",")]:
        obj = os.path.join(work, f"{a.scene}-{size}.obj")
        if not os.path.exists(obj):
            run(["gen", a.scene, "--tris", str(size), "-o", obj, "--quiet"])
        for limit in limits:
            reports = []
            for k in range(a.runs):
                out = os.path.join(work, f"out-{size}.oocf")
                rep = os.path.join(work, f"report-{size}.json")
                args = ["convert", obj, "-o", out, "--codec", a.codec, "--quiet", "--report-json", rep]
                if limit:
                    args += ["--mem-limit", limit]
                run(args)
                with open(rep) as f:
                    reports.append(json.load(f))
                os.remove(out)
            med = lambda key: statistics.median(r[key] for r in reports)
            phases = {}
            for r in reports:
                for ph in r["phases"]:
                    phases.setdefault(ph["phase"], []).append(ph["seconds"])
            phase_text = ", ".join(f"{k} {statistics.median(v):.1f}" for k, v in phases.items())
            ooc = reports[0].get("out_of_core")
            chunks = ooc["chunks"] if ooc else "in core"
            peak = statistics.median((r["peak_memory_bytes"] or 0) for r in reports) / 2**20
            print(
                f"| {reports[0]['import']['triangles_in']:,} | {limit or 'default'} | {chunks} "
                f"| {med('seconds'):.2f} | {med('triangles_per_second'):,.0f} | {peak:,.0f} MiB "
                f"| {med('file_bytes') / 1e6:.1f} MB | {phase_text} |"
            )
            sys.stdout.flush()


if __name__ == "__main__":
    main()
