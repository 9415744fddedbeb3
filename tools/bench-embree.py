#!/usr/bin/env python3
"""Primary-ray throughput of `oocfmt render --poe 0` against Embree, same model, same rays.

Installs its own dependencies (numpy and embreex, Embree's Python binding, from PyPI) into
target/bench-venv on first use, generates and converts a Mandelbulb with the release binary,
renders one view with `oocfmt render --cache blocking --poe 0` (warm: `--repeat 3`) and traces
the very same primary rays (pixel centres, row 0 at the top, the tracer's camera formula) with
Embree. Prints rays per second of both, their ratio, and how far the two depth images agree.

embreex's `run` calls rtcIntersect1 ray by ray on one thread, so both sides are timed on one
thread (`--threads 1`); with all cores Embree would scale about linearly as oocfmt does.

    cargo build --release -p oocfmt-cli
    python3 tools/bench-embree.py --tris 1e6
"""

import argparse
import json
import os
import subprocess
import sys
import time

from benchlib import ROOT, require_binary, run
VENV = os.path.join(ROOT, "target", "bench-venv")


def ensure_venv():
    """Re-runs this script inside target/bench-venv, creating it with numpy and embreex."""
    py = os.path.join(VENV, "bin", "python")
    if os.path.realpath(sys.prefix) == os.path.realpath(VENV):
        return
    if not os.path.exists(py):
        print(f"creating {VENV} with numpy and embreex (once)", file=sys.stderr)
        subprocess.run([sys.executable, "-m", "venv", VENV], check=True)
        subprocess.run([py, "-m", "pip", "install", "-q", "numpy", "embreex"], check=True)
    os.execv(py, [py] + sys.argv)


def read_obj(path, np):
    verts, faces = [], []
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                verts.append(line.split()[1:4])
            elif line.startswith("f "):
                faces.append([int(x.split("/")[0]) - 1 for x in line.split()[1:4]])
    return np.array(verts, dtype=np.float32), np.array(faces, dtype=np.int32)


def read_pfm(path, np):
    with open(path, "rb") as f:
        assert f.readline().strip() == b"Pf"
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        data = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4").reshape(h, w)
    return data[::-1]  # PFM rows are bottom-up


def primary_rays(np, eye, look_at, up, fov_y, w, h):
    """The tracer's camera (crates/oocfmt-trace/src/camera.rs), in f64 then f32."""
    eye, look_at, up = (np.array(v, dtype=np.float64) for v in (eye, look_at, up))
    fwd = look_at - eye
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, up)
    right /= np.linalg.norm(right)
    up2 = np.cross(right, fwd)
    t = np.tan(np.radians(fov_y) / 2)
    xs = (2 * (np.arange(w) + 0.5) / w - 1) * t * w / h
    ys = (1 - 2 * (np.arange(h) + 0.5) / h) * t
    sx, sy = np.meshgrid(xs, ys)
    d = fwd + sx[..., None] * right + sy[..., None] * up2
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    d = d.reshape(-1, 3).astype(np.float32)
    o = np.broadcast_to(eye.astype(np.float32), d.shape).copy()
    return o, d


def main():
    ensure_venv()
    import numpy as np
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--tris", default="1e6")
    p.add_argument("--size", default="1024x768")
    p.add_argument("--eye", default="0.2,0.45,1.9")
    p.add_argument("--look-at", default="0,0,0")
    p.add_argument("--fov-y", type=float, default=45.0)
    p.add_argument("--repeat", type=int, default=3, help="timed passes of each (the best is kept)")
    p.add_argument("--dir", default=os.path.join(ROOT, "target", "bench-embree"))
    a = p.parse_args()
    require_binary()
    os.makedirs(a.dir, exist_ok=True)
    n = int(float(a.tris))
    obj = os.path.join(a.dir, f"mandelbulb-{n}.obj")
    model = os.path.join(a.dir, f"mandelbulb-{n}.oocf")
    if not os.path.exists(obj):
        run(["gen", "mandelbulb", "--tris", str(n), "-o", obj, "--quiet"])
    if not os.path.exists(model):
        run(["convert", obj, "-o", model, "--quiet"])
    w, h = map(int, a.size.split("x"))
    eye = [float(c) for c in a.eye.split(",")]
    look = [float(c) for c in a.look_at.split(",")]

    depth = os.path.join(a.dir, "oocfmt-depth.pfm")
    stats = os.path.join(a.dir, "oocfmt-stats.json")
    best = None
    for _ in range(a.repeat):
        run(["render", model, "-o", os.path.join(a.dir, "oocfmt.png"), "--size", a.size,
             "--eye", a.eye, "--look-at", a.look_at, "--fov-y", str(a.fov_y), "--poe", "0",
             "--cache", "blocking", "--repeat", "3", "--threads", "1",
             "--depth-out", depth, "--stats-json", stats])
        with open(stats) as f:
            s = json.load(f)
        best = s if best is None or s["ms"] < best["ms"] else best

    verts, faces = read_obj(obj, np)
    scene = rtcs.EmbreeScene()
    TriangleMesh(scene, verts, faces)
    o, d = primary_rays(np, eye, look, [0, 1, 0], a.fov_y, w, h)
    scene.run(o[:1], d[:1])  # builds the BVH outside the timing
    times = []
    for _ in range(a.repeat):
        t = time.perf_counter()
        hits = scene.run(o, d, output=1)
        times.append(time.perf_counter() - t)
    emb_s = min(times)
    rays = w * h
    emb_rps = rays / emb_s
    oocf_rps = rays / (best["ms"] / 1000)

    t_emb = np.where(hits["primID"] >= 0, hits["tfar"], np.inf).reshape(h, w)
    t_oocf = read_pfm(depth, np)
    hit_e, hit_o = np.isfinite(t_emb), np.isfinite(t_oocf)
    both = hit_e & hit_o
    rel = np.abs(t_oocf[both] - t_emb[both]) / t_emb[both]
    print(f"model {model}: {len(faces):,} triangles; view eye {a.eye} look-at {a.look_at}, {w}x{h}, one thread")
    print(f"oocfmt render --poe 0 (blocking, warm): {best['ms']:.1f} ms, {oocf_rps / 1e6:.3f} Mrays/s")
    print(f"Embree (embreex, rtcIntersect1):       {emb_s * 1000:.1f} ms, {emb_rps / 1e6:.3f} Mrays/s")
    print(f"oocfmt / Embree time: {emb_rps / oocf_rps:.2f}x")
    print(f"hits: oocfmt {hit_o.sum():,}, Embree {hit_e.sum():,}; hit/miss disagree on {(hit_e != hit_o).sum():,} pixels "
          f"({100 * (hit_e != hit_o).mean():.4f} %); relative depth difference where both hit: "
          f"median {np.median(rel):.2e}, max {rel.max():.2e}, > 1e-5 on {(rel > 1e-5).sum():,} pixels")


if __name__ == "__main__":
    main()
