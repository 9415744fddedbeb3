"""What the benchmark scripts in tools/ share: where the release binary is, running it, and a
line naming the machine the figures come from."""

import math
import os
import platform
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# OOCFMT_BIN runs another build (say, a copy of an older one to compare with).
BIN = os.environ.get("OOCFMT_BIN") or os.path.join(ROOT, "target", "release", "oocfmt")


def require_binary():
    if not os.path.exists(BIN):
        sys.exit(f"{BIN} missing: run `cargo build --release -p oocfmt-cli` first")


def run(args):
    """Runs `oocfmt ARGS`, exits with its output when it fails, returns its stdout."""
    r = subprocess.run([BIN] + args, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"oocfmt {' '.join(args)} failed ({r.returncode}):\n{r.stdout}{r.stderr}")
    return r.stdout


def generated_scenes(scenes, work):
    """For each SCENE:TRIANGLES of the comma-separated `scenes` (scenes of `oocfmt gen`), the
    scene, its triangle count and the path stem in `work`, with `STEM.obj` generated if missing."""
    for spec in scenes.split(","):
        scene, _, tris = spec.partition(":")
        size = int(float(tris or "1e6"))
        stem = os.path.join(work, f"{scene}-{size}")
        if not os.path.exists(stem + ".obj"):
            run(["gen", scene, "--tris", str(size), "-o", stem + ".obj", "--quiet"])
        yield scene, size, stem


def machine():
    cpu = platform.processor() or "unknown CPU"
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} logical cores, {platform.system()} {platform.release()}"


def path_cameras(lo, hi, frames):
    """The walkthrough of the benchmarks: from the default framing distance to half of it,
    orbiting 60 degrees around +y, looking at the centre of the bounds lo..hi."""
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
