#!/usr/bin/env python3
"""Walkthrough figures of `oocfmt render --path`: cold start against warm frames, and a cache
budget a tenth of the container.

Generates and converts a Mandelbulb with the release binary (or takes --model), writes a path
that approaches the model while orbiting it, and renders it

  1. cold, async cache (a fresh process: only the root block and the proxies are resident);
  2. warm: the same path twice in one process, the second pass timed (everything it wants is
     resident, nothing is fetched);
  3. cold with --cache-mb a tenth of the container's size.

Prints per frame the cold and warm milliseconds (the frame's rays plus the cache's step after
it), their ratio, the share of pixels still coarse (ending on a voxel or proxy where the warm
frame shows triangles), blocks loaded, the working set; then the summary: the largest cold/warm
ratio, the frame from which the cold images equal the warm ones, and the small budget's peak.
Standard library only.

    cargo build --release -p oocfmt-cli
    python3 tools/bench-walk.py --tris 1e7
"""

import argparse
import json
import math
import os
import statistics
import tempfile

from benchlib import ROOT, require_binary, run


def path_cameras(lo, hi, frames):
    """From the default framing distance to half of it, orbiting 60 degrees around +y."""
    c = [(a + b) / 2 for a, b in zip(lo, hi)]
    radius = math.dist(lo, hi) / 2
    cams = []
    for i in range(frames):
        s = i / max(frames - 1, 1)
        d = radius * (2.8 - 1.2 * s)
        a = math.radians(25 + 60 * s)
        eye = [c[0] + d * math.sin(a), c[1] + 0.35 * d, c[2] + d * math.cos(a)]
        cams.append({"eye": eye, "look_at": c})
    return cams


def render_path(model, cams, work, name, extra):
    path = os.path.join(work, f"{name}.json")
    with open(path, "w") as f:
        json.dump(cams, f)
    stats = os.path.join(work, f"{name}-stats.json")
    out = os.path.join(work, f"{name}.png")
    run(["render", model, "-o", out, "--path", path, "--stats-json", stats] + extra)
    with open(stats) as f:
        return json.load(f)


def same_png(a, b):
    with open(a, "rb") as fa, open(b, "rb") as fb:
        return fa.read() == fb.read()


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--tris", default="1e7")
    p.add_argument("--model", help="an existing container (default: generate and convert one)")
    p.add_argument("--frames", type=int, default=30)
    p.add_argument("--hold", type=int, default=5, help="still frames on the last camera, to see the cold images converge")
    p.add_argument("--size", default="1024x768")
    p.add_argument("--poe", default="1")
    p.add_argument("--cache-mb", type=int, default=2048)
    p.add_argument("--fetchers", type=int, default=2)
    p.add_argument("--dir", default=os.path.join(ROOT, "target", "bench-walk"))
    a = p.parse_args()
    require_binary()
    os.makedirs(a.dir, exist_ok=True)
    model = a.model
    if model is None:
        n = int(float(a.tris))
        obj = os.path.join(a.dir, f"mandelbulb-{n}.obj")
        model = os.path.join(a.dir, f"mandelbulb-{n}.oocf")
        if not os.path.exists(model):
            run(["gen", "mandelbulb", "--tris", str(n), "-o", obj, "--quiet"])
            run(["convert", obj, "-o", model, "--quiet"])
            os.remove(obj)
    info = json.loads(run(["inspect", model, "--json"]))
    scene = info["metadata"]["scene"]
    origin = scene.get("origin", [0, 0, 0])
    lo = [o + v for o, v in zip(origin, scene["bounds_min"])]
    hi = [o + v for o, v in zip(origin, scene["bounds_max"])]
    size_mb = os.path.getsize(model) / 2**20
    cams = path_cameras(lo, hi, a.frames)
    cams += [cams[-1]] * a.hold
    frames = len(cams)
    common = ["--size", a.size, "--poe", a.poe, "--fetchers", str(a.fetchers)]
    with tempfile.TemporaryDirectory(dir=a.dir) as work:
        cold = render_path(model, cams, work, "cold", common + ["--cache-mb", str(a.cache_mb)])
        both = render_path(model, cams + cams, work, "warm", common + ["--cache-mb", str(a.cache_mb)])
        warm = both[frames:]
        small_mb = max(1, int(size_mb / 10))
        small = render_path(model, cams, work, "small", common + ["--cache-mb", str(small_mb)])
        equal = [same_png(c["file"], w["file"]) for c, w in zip(cold, warm)]

    def total(f):
        return f["ms"] + f["step_ms"]

    print(f"model {model}: {size_mb:.1f} MiB; {a.frames} frames + {a.hold} still, {a.size}, --poe {a.poe}, "
          f"{a.fetchers} fetchers, render threads: all cores ({cold[0]['stats']['threads']})")
    print("coarse: pixels ending on a voxel or proxy (at --poe > 0 the warm frames have some too); "
          "=warm: the cold frame's image equals the warm one's")
    print(f"{'frame':>5} {'cold ms':>8} {'warm ms':>8} {'ratio':>6} {'coarse %':>8} {'warm %':>6} {'loaded':>7} "
          f"{'MiB':>7} {'=warm':>5} | {'small ms':>8} {'coarse %':>8} {'MiB':>6}")
    rays = cold[0]["stats"]["rays"]
    ratios = []
    for i, (c, w, s) in enumerate(zip(cold, warm, small)):
        ratio = total(c) / total(w)
        ratios.append(ratio)
        print(f"{i:5} {total(c):8.1f} {total(w):8.1f} {ratio:6.2f} "
              f"{100 * c['coarse_pixels'] / rays:8.2f} {100 * w['coarse_pixels'] / rays:6.2f} {c['blocks_loaded']:7} "
              f"{c['working_set_mb']:7.1f} {'yes' if equal[i] else 'no':>5} | "
              f"{total(s):8.1f} {100 * s['coarse_pixels'] / rays:8.2f} {s['working_set_mb']:6.1f}")
    first_equal = next((i for i in range(frames) if all(equal[i:])), None)
    peak = max(f["stats"]["cache"]["peak_bytes_resident"] for f in small) / 2**20
    worst = max(range(frames), key=lambda i: ratios[i])
    print(f"cold/warm frame time: max {ratios[worst]:.2f} (frame {worst}), median {statistics.median(ratios):.2f}; "
          f"warm median {statistics.median(total(w) for w in warm):.1f} ms")
    print(f"cold frames equal the warm ones from frame {first_equal}" if first_equal is not None
          else "cold frames never all equal the warm ones")
    print(f"--cache-mb {small_mb} ({size_mb / small_mb:.1f}x smaller than the container): peak "
          f"{peak:.1f} MiB held, median frame {statistics.median(total(s) for s in small):.1f} ms, "
          f"coarse pixels in the last frame {100 * small[-1]['coarse_pixels'] / rays:.2f} %")


if __name__ == "__main__":
    main()
