#!/usr/bin/env python3
"""Prints `--hide NAME` arguments that hide the top-level parts of a container whose subtree
box centre lies below a percentile along an axis: a spatially coherent share of an assembly,
for measuring what hiding costs (docs/benchmarks.md, "Hiding parts").

    oocfmt render cad.oocf $(python3 tools/hide-globs.py cad.oocf --below 80) -o cut.png
"""
import argparse
import json
import subprocess
import sys


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file", help="a container with parts")
    ap.add_argument("--oocfmt", default="target/release/oocfmt", help="the oocfmt binary")
    ap.add_argument("--axis", type=int, default=0, choices=(0, 1, 2), help="0 x, 1 y, 2 z")
    ap.add_argument("--below", type=float, default=80.0, help="percentile of box centres")
    a = ap.parse_args()
    out = subprocess.run([a.oocfmt, "inspect", a.file, "--parts", "--json"],
                         check=True, capture_output=True, text=True).stdout
    top = [p for p in json.loads(out)["parts"]
           if p["parent"] is None and p["subtree_triangles"] > 0]
    if not top:
        sys.exit(f"{a.file}: no top-level part with triangles")
    centre = lambda p: (p["subtree_bounds_min"][a.axis] + p["subtree_bounds_max"][a.axis]) / 2
    cs = sorted(centre(p) for p in top)
    cut = cs[min(len(cs) - 1, int(len(cs) * a.below / 100))]
    names = [p["name"] for p in top if centre(p) < cut]
    # Names are matched as globs: escape the glob characters a name may hold.
    esc = lambda n: "".join(f"[{c}]" if c in "*?[]" else c for c in n)
    print(" ".join(f"--hide {esc(n)}" for n in names))


if __name__ == "__main__":
    main()
