#!/usr/bin/env python3
"""LOD against the true picture (issue 25's table): for each scene, converts it three ways
(`oocfmt convert --lod voxel --unfiltered`, the 1.1-style opaque voxels; `--lod voxel`,
pre-filtered voxels; and the default, pre-filtered R-LODs), prints each conversion's time and
file size, then runs `oocfmt curve --cache blocking --json` on each file at the default
(framing) view and at a close view (the eye at 0.35 of the framing distance). It prints per PoE
the warm frame time, its ratio to PoE 0 of the same file, the working set and the error against
full detail supersampled on the model's pixels: RMSE, SSIM, share within 8 levels and the mean
signed luminance bias. The first line of each table is the aliasing floor: full detail at one
ray per pixel against the same reference. Timings are medians of `--repeat` warm frames on a
shared machine: compare ratios within one run. The machine is printed first.

    cargo build --release -p oocfmt-cli
    python3 tools/bench-lod.py --scenes mandelbulb:1e6,cad:1e6 --dir /tmp/lod
    python3 tools/bench-lod.py --scenes mandelbulb:1e7 --dir /tmp/lod --views far
    python3 tools/bench-lod.py --files rlod,voxel --lighting shadows,ao:4 --dir /tmp/lod

`--shown translucent,opaque` renders each pre-filtered file both ways: its partly covering
LOD entries composited over what lies behind (the default) and with `--opaque-lod`.

`--lighting` lights every image and its reference alike: `headlight` (the default), `shadows`
(a point light with shadow rays), `ao:N` (N ambient-occlusion rays per hit) or both joined by
`+` (`shadows+ao:4`); one table per lighting.
"""

import argparse
import json
import math
import os
import sys
import tempfile
import time

from benchlib import generated_scenes, machine, require_binary, run

# The framing direction of `Camera::framing` (crates/oocfmt-trace/src/camera.rs).
FRAMING = (0.55, 0.45, 0.7)


# The files compared: a label, the file name's suffix and the `convert` flags.
FILES = (("voxels, opaque (--lod voxel --unfiltered)", "voxel-opaque", ["--lod", "voxel", "--unfiltered"]),
         ("voxels, pre-filtered (--lod voxel)", "voxel", ["--lod", "voxel"]),
         ("R-LODs, pre-filtered (the default)", "rlod", []))


def convert(obj, out, flags):
    """Converts `obj` (skipped when `out` exists) and returns (seconds or None, bytes)."""
    seconds = None
    if not os.path.exists(out):
        args = ["convert", obj, "-o", out, "--quiet"] + flags
        start = time.monotonic()
        run(args)
        seconds = time.monotonic() - start
    return seconds, os.path.getsize(out)


def close_view(model, size):
    """`--eye/--look-at` of the close view: the framing camera's direction, 0.35 of its distance
    from the centre (the framing distance is found as `Camera::framing` does)."""
    info = json.loads(run(["inspect", model, "--json"]))
    scene = info["metadata"]["scene"]
    lo, hi = scene["bounds_min"], scene["bounds_max"]
    origin = scene.get("origin", [0.0, 0.0, 0.0])
    c = [(a + b) / 2 for a, b in zip(lo, hi)]
    half = [(b - a) / 2 for a, b in zip(lo, hi)]
    n = math.sqrt(sum(x * x for x in FRAMING))
    u = [x / n for x in FRAMING]
    w, h = (int(v) for v in size.split("x"))
    up = (0.0, 1.0, 0.0)

    def cross(a, b):
        return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]

    def norm(a):
        m = math.sqrt(sum(x * x for x in a))
        return [x / m for x in a]

    def dot(a, b):
        return sum(x * y for x, y in zip(a, b))

    right = norm(cross([-x for x in u], up))
    cam_up = cross(right, [-x for x in u])
    tan_y = math.tan(math.radians(45.0 / 2))
    tan_x = tan_y * w / h
    dist = 0.0
    for corner in range(8):
        q = [half[k] if corner >> k & 1 else -half[k] for k in range(3)]
        along = dot(q, u)
        dist = max(dist, along + abs(dot(q, right)) / tan_x, along + abs(dot(q, cam_up)) / tan_y)
    dist *= 1.05 * 0.35
    eye = [origin[k] + c[k] + u[k] * dist for k in range(3)]
    at = [origin[k] + c[k] for k in range(3)]
    return ["--eye", ",".join(f"{x:.6g}" for x in eye), "--look-at", ",".join(f"{x:.6g}" for x in at)]


def lighting_flags(lighting):
    """`curve` flags of one `--lighting` entry."""
    flags = []
    for part in lighting.split("+"):
        if part == "headlight":
            continue
        if part == "shadows":
            flags.append("--shadows")
        elif part.startswith("ao:") and part[3:].isdigit():
            flags += ["--ao", part[3:]]
        else:
            sys.exit(f"bench-lod: unknown lighting {part!r} (headlight, shadows, ao:N)")
    return flags


def curve(model, a, view_args, out, extra):
    run(["curve", model, "--cache", "blocking", "--poe", a.poe, "--size", a.size,
         "--repeat", str(a.repeat), "--reference-spp", str(a.reference_spp), "--json", out]
        + view_args + extra)
    with open(out) as f:
        return json.load(f)


def cells(e):
    m = e["model"]
    return f"{m['rmse']:.2f} | {m['ssim']:.4f} | {100 * m['within_tolerance']:.1f} % | {m['bias']:+.2f}"


def table(title, curves):
    print(f"\n{title}")
    print("| records | PoE | frame ms | vs PoE 0 | working set | RMSE | SSIM | within 8 | bias |")
    print("|---|--:|--:|--:|--:|--:|--:|--:|--:|")
    floor = curves[0][1]["floor"]
    print(f"| full detail, 1 ray/pixel (the floor) | 0 | | | | {cells(floor['error'])} |")
    for kind, c in curves:
        base = next((r["ms"] for r in c["rows"] if r["poe"] == 0), None)
        for r in c["rows"]:
            ratio = f"{base / r['ms']:.2f}x" if base and r["ms"] > 0 else ""
            print(f"| {kind} | {r['poe']:g} | {r['ms']:.1f} | {ratio} | {r['working_set_mb']:.1f} MiB "
                  f"| {cells(r['error'])} |")
    sys.stdout.flush()


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scenes", default="mandelbulb:1e6,cad:1e6",
                   help="comma-separated SCENE:TRIANGLES (scenes of `oocfmt gen`)")
    p.add_argument("--views", default="far,close", help="far (the framing view), close, or both")
    p.add_argument("--size", default="1024x768")
    p.add_argument("--poe", default="0,1,2,4")
    p.add_argument("--repeat", type=int, default=5, help="timed warm frames per PoE (median)")
    p.add_argument("--reference-spp", type=int, default=16, help="rays per pixel of the reference")
    p.add_argument("--dir", default=None, help="scratch folder, kept (default: a temporary one)")
    p.add_argument("--files", default=",".join(f[1] for f in FILES),
                   help="which conversions: voxel-opaque, voxel, rlod (comma-separated)")
    p.add_argument("--shown", default="translucent",
                   help="how LOD entries are shown, comma-separated: translucent (the default), "
                        "opaque (--opaque-lod); files without coverage are shown once")
    p.add_argument("--lighting", default="headlight",
                   help="comma-separated: headlight, shadows, ao:N, or joined by + (shadows+ao:4)")
    a = p.parse_args()
    files = [f for f in FILES if f[1] in a.files.split(",")]
    if not files:
        sys.exit(f"bench-lod: --files names none of {', '.join(f[1] for f in FILES)}")
    lightings = [(name, lighting_flags(name)) for name in a.lighting.split(",")]
    shown = a.shown.split(",")
    if not shown or any(m not in ("translucent", "opaque") for m in shown):
        sys.exit("bench-lod: --shown takes translucent, opaque or both")
    require_binary()
    work = a.dir or tempfile.mkdtemp(prefix="oocfmt-lod-")
    os.makedirs(work, exist_ok=True)
    print(f"machine: {machine()}")
    for scene, size, stem in generated_scenes(a.scenes, work):
        obj = stem + ".obj"
        series = []
        for label, suffix, flags in files:
            path = f"{stem}-{suffix}.oocf"
            seconds, size_bytes = convert(obj, path, flags)
            took = f"{seconds:.1f} s" if seconds is not None else "(kept from an earlier run)"
            print(f"{scene} {size}: {label}: convert {took}, {size_bytes / 2**20:.1f} MiB")
            for mode in shown if suffix != "voxel-opaque" else shown[:1]:
                opaque = mode == "opaque" and suffix != "voxel-opaque"
                series.append((label + (", --opaque-lod" if opaque else ""), path,
                               ["--opaque-lod"] if opaque else []))
        for name, light in lightings:
            for view in a.views.split(","):
                curves = []
                for label, path, shown_flags in series:
                    args = close_view(path, a.size) if view == "close" else []
                    tag = name.replace(':', '').replace('+', '-') + "".join(shown_flags).replace("-", "")
                    out = f"{path}.{view}.{tag}.curve.json"
                    curves.append((label, curve(path, a, args, out, light + shown_flags)))
                table(f"{scene} {size}, {view} view, {name}, {a.size}, blocking cache, error "
                      f"against {a.reference_spp} rays per pixel on the model's pixels", curves)


if __name__ == "__main__":
    main()
