#!/usr/bin/env python3
"""Models larger than memory: the tables of docs/benchmarks.md after Table 5 and 6 of the Áfra paper.

For each Mandelbulb size in --tris (generated once, kept in --dir), converts it under
--mem-limit (default 2G) and reports the conversion: wall time, triangles per second, the
converter's own peak-memory figure and the process's peak resident set, the file size and the
compression ratio (stored bytes of all blocks over their decoded bytes). Then renders a
walkthrough (the approach-and-orbit path of bench-walk.py) with an async cache of --cache-mb (default 512)
that starts cold, twice in one process: the first pass is the cold start, the second the
steady state. Per shading (primary rays; with point-light shadows; with shadows and two
ambient-occlusion rays per hit, as the three columns of Table 5) it prints the median frame
time and frames per second of the steady pass, the largest ratio of a cold frame's time to
the same camera's steady time (a stall shows as a large ratio) and the slowest cold frame, the
working set, the cache's peak of decoded bytes held and the process's peak resident set.
Standard library only.

    cargo build --release -p oocfmt-cli
    python3 tools/bench-scale.py --tris 1e6,1e7,1e8
"""

import argparse
import json
import os
import statistics
import subprocess
import tempfile
import time

from benchlib import BIN, ROOT, machine, path_cameras, require_binary, run


def timed(args):
    """Runs `oocfmt ARGS`; returns (wall seconds, peak resident MiB) of that process alone."""
    start = time.monotonic()
    p = subprocess.Popen([BIN] + args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    _, status, usage = os.wait4(p.pid, 0)
    wall = time.monotonic() - start
    err = p.stderr.read() if p.stderr else ""
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"oocfmt {' '.join(args)} failed:\n{err}")
    return wall, usage.ru_maxrss / 1024


def model_for(n, a):
    obj = os.path.join(a.dir, f"mandelbulb-{n}.obj")
    model = os.path.join(a.dir, f"mandelbulb-{n}.oocf")
    report = os.path.join(a.dir, f"mandelbulb-{n}.json")
    if os.path.exists(model) and os.path.exists(report):
        with open(report) as f:
            return model, json.load(f)
    if not os.path.exists(obj):
        run(["gen", "mandelbulb", "--tris", str(n), "-o", obj, "--quiet"])
    args = ["convert", obj, "-o", model, "--mem-limit", a.mem_limit, "--quiet", "--report-json", report + ".tmp"]
    wall, rss = timed(args)
    with open(report + ".tmp") as f:
        conv = json.load(f)
    conv["bench"] = {"wall_s": wall, "max_rss_mib": rss, "mem_limit": a.mem_limit, "obj_bytes": os.path.getsize(obj)}
    with open(report, "w") as f:
        json.dump(conv, f)
    os.remove(report + ".tmp")
    if not a.keep_obj:
        os.remove(obj)
    return model, conv


def walk(model, cams, work, name, extra):
    path = os.path.join(work, f"{name}.json")
    with open(path, "w") as f:
        json.dump(cams + cams, f)
    stats = os.path.join(work, f"{name}-stats.json")
    _, rss = timed(["render", model, "-o", os.path.join(work, f"{name}.png"), "--path", path,
                    "--stats-json", stats] + extra)
    with open(stats) as f:
        frames = json.load(f)
    for fr in frames:
        os.remove(fr["file"])
    return frames[:len(cams)], frames[len(cams):], rss


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--tris", default="1e6,1e7,1e8", help="comma-separated triangle counts")
    p.add_argument("--mem-limit", default="2G")
    p.add_argument("--cache-mb", type=int, default=512)
    p.add_argument("--frames", type=int, default=30)
    p.add_argument("--size", default="1024x768")
    p.add_argument("--poe", default="3", help="pixels of error (Table 5 of the paper uses 3)")
    p.add_argument("--shading", default="primary,shadows,ao", help="any of primary, shadows, ao")
    p.add_argument("--keep-obj", action="store_true", help="keep the generated OBJ files")
    p.add_argument("--render-args", default="", help="more `oocfmt render` flags for the walkthroughs, "
                   "space-separated, e.g. '--fetch-priority normal'")
    p.add_argument("--dir", default=os.path.join(ROOT, "target", "bench-scale"))
    a = p.parse_args()
    require_binary()
    os.makedirs(a.dir, exist_ok=True)
    shadings = {"primary": [], "shadows": ["--shadows"], "ao": ["--shadows", "--ao", "2"]}
    wanted = [s for s in a.shading.split(",") if s]
    for s in wanted:
        if s not in shadings:
            raise SystemExit(f"--shading: unknown {s!r}, expected some of {', '.join(shadings)}")
    print(machine())
    built = []
    for n in (int(float(t)) for t in a.tris.split(",")):
        model, conv = model_for(n, a)
        built.append((n, model, conv))

    print(f"\nconversion (--mem-limit {a.mem_limit}); stored %: stored block bytes / decoded block bytes, as Table 6's compression ratio")
    print(f"{'triangles':>11} {'file GiB':>8} {'stored %':>8} {'time':>9} {'tri/s':>8} {'peak MiB':>8} {'RSS MiB':>8}")
    for n, model, conv in built:
        raw = sum(b["raw_bytes"] for b in conv["blocks"].values())
        stored = sum(b["stored_bytes"] for b in conv["blocks"].values())
        wall = conv["bench"]["wall_s"]
        tris = conv["triangles_stored"]
        print(f"{tris:11,} {os.path.getsize(model) / 2**30:8.2f} {100 * stored / raw:8.1f} "
              f"{int(wall // 60):3d}m {wall % 60:4.1f}s {tris / wall:8,.0f} {(conv['peak_memory_bytes'] or 0) / 2**20:8.0f} "
              f"{conv['bench']['max_rss_mib']:8.0f}")

    print(f"\nwalkthrough: {a.frames} frames {a.size}, --poe {a.poe}, async cache --cache-mb {a.cache_mb} "
          "starting cold, run twice in one process; ms/fps: median of the second pass; "
          "stall: the largest ratio of a first-pass frame to the same camera's second-pass frame; "
          "worst: the slowest first-pass frame")
    print(f"{'triangles':>11} {'shading':>8} {'ms':>7} {'fps':>6} {'stall':>6} {'worst ms':>8} {'WS MiB':>7} {'cache peak':>10} "
          f"{'RSS MiB':>8} {'coarse %':>8}")
    for n, model, conv in built:
        info = json.loads(run(["inspect", model, "--json"]))
        scene = info["metadata"]["scene"]
        origin = scene.get("origin", [0, 0, 0])
        lo = [o + v for o, v in zip(origin, scene["bounds_min"])]
        hi = [o + v for o, v in zip(origin, scene["bounds_max"])]
        cams = path_cameras(lo, hi, a.frames)
        common = ["--size", a.size, "--poe", a.poe, "--cache-mb", str(a.cache_mb)] + a.render_args.split()
        with tempfile.TemporaryDirectory(dir=a.dir) as work:
            for s in wanted:
                cold, steady, rss = walk(model, cams, work, s, common + shadings[s])
                total = [f["ms"] + f["step_ms"] for f in steady]
                median = statistics.median(total)
                stall = max((c["ms"] + c["step_ms"]) / t for c, t in zip(cold, total))
                worst = max(c["ms"] + c["step_ms"] for c in cold)
                ws = statistics.median(f["working_set_mb"] for f in steady)
                peak = max(f["stats"]["cache"]["peak_bytes_resident"] for f in cold + steady) / 2**20
                rays = steady[0]["stats"]["rays"]
                coarse = statistics.median(100 * f["coarse_pixels"] / rays for f in steady)
                print(f"{conv['triangles_stored']:11,} {s:>8} {median:7.1f} {1000 / median:6.2f} "
                      f"{stall:6.2f} {worst:8.1f} {ws:7.1f} {peak:10.1f} {rss:8.0f} {coarse:8.2f}")


if __name__ == "__main__":
    main()
