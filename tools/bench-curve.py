#!/usr/bin/env python3
"""Speed against error: generates scenes, converts them and runs `oocfmt curve --json` on each,
printing the Markdown table of docs/benchmarks.md (per PoE: warm frame time and its ratio to PoE 0, rays per
second, nodes per ray, working set, blocks touched, the share of rays ending on voxels or R-LODs,
and beside every speed the error against full detail supersampled, on the model's pixels and on
the whole image; first the aliasing floor, full detail at one ray per pixel against the same
reference). Writes each scene's plot and contact sheet beside its container.
Timings are medians of `--repeat` warm frames; compare ratios within one run. The machine is
printed first.

    cargo build --release -p oocfmt-cli
    python3 tools/bench-curve.py --scenes mandelbulb:1e6,cad:1e6 --dir /tmp/curve
    python3 tools/bench-curve.py --scenes mandelbulb:1e7 --dir /tmp/curve --cache async,blocking
"""

import argparse
import json
import os
import sys
import tempfile

from benchlib import generated_scenes, machine, require_binary, run


def psnr(v):
    return "inf" if v is None else f"{v:.1f}"


def error_cells(e, n):
    """The error columns of a row: the model's pixels first, then the whole image."""
    m, w, d = e["model"], e["whole"], e["depth"]
    return (f"| {m['rmse']:.2f} | {psnr(m['psnr_db'])} | {m['ssim']:.4f} | {100 * m['within_tolerance']:.1f} % "
            f"| {m['bias']:+.2f} | {w['rmse']:.2f} | {psnr(w['psnr_db'])} | {100 * m['pixels'] / n:.1f} % "
            f"| {100 * d['hit_miss_differ'] / n:.2f} % | {d['median_relative']:.1e} / {d['max_relative']:.1e} |")


def table(name, curve):
    rows = curve["rows"]
    ref, floor = curve["reference"], curve["floor"]
    tol = curve["tolerance"]
    print(f"\n{name}: {curve['width']}x{curve['height']}, {curve['threads']} threads, "
          f"median of {curve['repeat']} warm frames; error against full detail at {ref['spp']} rays per "
          f"pixel on the model's pixels (hit in either image), then the whole image (all)")
    print("| cache | PoE | frame ms | vs PoE 0 | Mrays/s | nodes/ray | working set | blocks "
          f"| LOD rays | RMSE | PSNR dB | SSIM | within {tol} | bias | all RMSE | all PSNR dB | model pixels "
          "| hit/miss differ | depth err (median / max) |")
    print("|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|")
    fp = floor["primary"]
    n = max(1, fp["triangle"] + fp["voxel"] + fp.get("rlod", 0) + fp["proxy"] + fp["miss"])
    print(f"| aliasing floor: full detail, 1 ray/pixel, blocking | 0 | {floor['ms']:.1f} (cold) | | | | | | "
          f"{error_cells(floor['error'], n)}")
    base = {}
    for r in rows:
        if r["poe"] == 0:
            base[(r["cache"], r["lod"])] = r["ms"]
    for r in rows:
        p = r["primary"]
        n = max(1, p["triangle"] + p["voxel"] + p.get("rlod", 0) + p["proxy"] + p["miss"])
        hits = max(1, n - p["miss"])
        ratio = base.get((r["cache"], r["lod"]), 0) / r["ms"] if r["ms"] > 0 else 0
        lod_rays = p["voxel"] + p.get("rlod", 0)
        cache = r["cache"] if r["lod"] == "voxel" else f"{r['cache']} {r['lod']}"
        print(
            f"| {cache} | {r['poe']:g} | {r['ms']:.1f} | {ratio:.2f}x | {r['rays_per_second'] / 1e6:.2f} "
            f"| {r['nodes_per_ray']:.1f} | {r['working_set_mb']:.1f} MiB | {r['blocks_touched']} "
            f"| {100 * lod_rays / hits:.1f} % {error_cells(r['error'], n)}"
        )
    sys.stdout.flush()


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scenes", default="mandelbulb:1e6,cad:1e6",
                   help="comma-separated SCENE:TRIANGLES (scenes of `oocfmt gen`)")
    p.add_argument("--size", default="1024x768")
    p.add_argument("--poe", default="0,0.5,1,2,4,8,16")
    p.add_argument("--cache", default="async", help="comma-separated caches, one series each")
    p.add_argument("--repeat", type=int, default=5, help="timed warm frames per PoE (median)")
    p.add_argument("--reference-spp", type=int, default=16, help="rays per pixel of the reference")
    p.add_argument("--codec", default="lz4", help="codec of the conversions (mmap needs none)")
    p.add_argument("--extra", default="", help="more `oocfmt curve` arguments, space-separated")
    p.add_argument("--dir", default=None, help="scratch folder, kept (default: a temporary one)")
    a = p.parse_args()
    require_binary()
    work = a.dir or tempfile.mkdtemp(prefix="oocfmt-curve-")
    os.makedirs(work, exist_ok=True)
    print(f"machine: {machine()}")
    for scene, size, stem in generated_scenes(a.scenes, work):
        model = f"{stem}-{a.codec.replace(':', '')}.oocf"
        if not os.path.exists(model):
            run(["convert", stem + ".obj", "-o", model, "--codec", a.codec, "--quiet"])
        args = ["curve", model, "--size", a.size, "--poe", a.poe, "--cache", a.cache,
                "--repeat", str(a.repeat), "--reference-spp", str(a.reference_spp),
                "--json", stem + "-curve.json",
                "--plot", stem + "-curve.png", "--sheet", stem + "-sheet.png"]
        args += [x for x in a.extra.split(" ") if x]
        run(args)
        with open(stem + "-curve.json") as f:
            table(f"{scene}, {size:,} triangles", json.load(f))
        print(f"plot {stem}-curve.png, sheet {stem}-sheet.png")


if __name__ == "__main__":
    main()
