#!/usr/bin/env python3
"""Who had the CPU during a walkthrough's slow frames: cold runs and warm processes of
`oocfmt render --path` under a scheduler trace (`perf record -e sched:sched_switch`, Linux,
root or perf_event_paranoid <= 0).

Renders the walk of tools/bench-walk.py cold --runs times and warm --null times (each warm
process renders --warm-fill passes, then one timed), alternating, all under one trace. A frame's
time span runs from the write of the previous frame's PNG to the end of its rays (PNG write
times, kept by the file system to its clock tick of a few milliseconds). Prints every frame
over --flag times the warm processes' median (a warm process against the others'), with the
CPU milliseconds in its span of the render threads, the fetchers (the process's threads at a
lower priority than its render threads), the other processes by name, and idle cores; then the
mean other processes' CPU over those frames against the rest.

    cargo build --release -p oocfmt-cli
    python3 tools/frame-sched.py --model target/bench-scale/mandelbulb-100000000.oocf --poe 3 \\
        --cache-mb 4096 --frames 30 --hold 12
Standard library only; needs `perf`.
"""

import argparse
import bisect
import collections
import glob
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

from benchlib import BIN, ROOT, path_cameras, require_binary, run

SWITCH = re.compile(r"\[(\d+)\]\s+([\d.]+):\s+prev_comm=(.*?) prev_pid=(\d+) prev_prio=(\d+) .*"
                    r"==> next_comm=(.*?) next_pid=(\d+) next_prio=(\d+)")


def render(model, cams, work, name, extra):
    """Renders `cams`; returns the per-frame figures and each PNG's write time (monotonic
    seconds, perf's clock with `-k mono`)."""
    d = os.path.join(work, name)
    os.makedirs(d)
    with open(os.path.join(d, "path.json"), "w") as f:
        json.dump(cams, f)
    out = subprocess.run([BIN, "render", model, "-o", os.path.join(d, "f.png"), "--path",
                          os.path.join(d, "path.json"), "--stats-json", os.path.join(d, "s.json")] + extra,
                         capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"oocfmt render failed ({out.returncode}):\n{out.stderr}")
    with open(os.path.join(d, "s.json")) as f:
        frames = json.load(f)
    offset = time.clock_gettime(time.CLOCK_REALTIME) - time.clock_gettime(time.CLOCK_MONOTONIC)
    pngs = sorted(glob.glob(os.path.join(d, "f-*.png")))
    written = [os.stat(p).st_mtime_ns / 1e9 - offset for p in pngs]
    # As in bench-walk.py's render_path: no hundreds of MiB of PNGs left behind while later runs
    # are traced.
    for p in pngs:
        os.remove(p)
    return frames, written


def on_cpu(trace):
    """Per task (pid, name, priority): the starts and ends of the spans it ran, in time order,
    from a sched_switch trace."""
    spans, current = collections.defaultdict(lambda: ([], [])), {}
    for line in trace.splitlines():
        m = SWITCH.search(line)
        if not m:
            continue
        cpu, t = int(m.group(1)), float(m.group(2))
        if cpu in current:
            start, task = current[cpu]
            spans[task][0].append(start)
            spans[task][1].append(t)
        current[cpu] = (t, (int(m.group(7)), m.group(6), int(m.group(8))))
    return spans


def cpu_in(spans, a, b):
    """Seconds a task ran between a and b: its spans do not overlap, so their ends are in order
    too, and the first that ends after a is found by bisection."""
    starts, ends = spans
    total, i = 0.0, bisect.bisect_right(ends, a)
    while i < len(starts) and starts[i] < b:
        total += min(ends[i], b) - max(starts[i], a)
        i += 1
    return total


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--model", required=True)
    p.add_argument("--frames", type=int, default=30)
    p.add_argument("--hold", type=int, default=12)
    p.add_argument("--size", default="1024x768")
    p.add_argument("--poe", default="3")
    p.add_argument("--cache-mb", type=int, default=4096)
    p.add_argument("--runs", type=int, default=4, help="cold runs")
    p.add_argument("--null", type=int, default=3, help="warm processes (at least 2)")
    p.add_argument("--warm-fill", type=int, default=3)
    p.add_argument("--flag", type=float, default=1.3, help="list frames over this ratio to warm")
    p.add_argument("--render-args", default="")
    a = p.parse_args()
    require_binary()
    if shutil.which("perf") is None:
        sys.exit("perf missing: install linux-tools (or your distribution's perf package)")
    if a.null < 2:
        sys.exit("--null must be at least 2: a warm process is held to the others' median")
    info = json.loads(run(["inspect", a.model, "--json"]))
    scene = info["metadata"]["scene"]
    origin = scene.get("origin", [0, 0, 0])
    lo = [o + v for o, v in zip(origin, scene["bounds_min"])]
    hi = [o + v for o, v in zip(origin, scene["bounds_max"])]
    cams = path_cameras(lo, hi, a.frames)
    cams += [cams[-1]] * a.hold
    n = len(cams)
    common = ["--size", a.size, "--poe", a.poe, "--cache-mb", str(a.cache_mb)] + a.render_args.split()
    os.makedirs(os.path.join(ROOT, "target", "frame-sched"), exist_ok=True)
    with tempfile.TemporaryDirectory(dir=os.path.join(ROOT, "target", "frame-sched")) as work:
        data = os.path.join(work, "sched.data")
        perf = subprocess.Popen(["perf", "record", "-q", "-k", "mono", "-e", "sched:sched_switch", "-a",
                                 "-o", data], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        time.sleep(1)
        if perf.poll() is not None:
            sys.exit(f"perf record failed: {perf.stderr.read()}")
        runs = []
        for r in range(max(a.runs, a.null)):
            if r < a.runs:
                frames, written = render(a.model, cams, work, f"cold{r}", common)
                # A cold frame starts when the previous frame's PNG is written (the first: none).
                runs.append(("cold", r, frames, [None] + written[:-1]))
            if r < a.null:
                frames, written = render(a.model, cams * (a.warm_fill + 1), work, f"warm{r}",
                                         common + ["--fetch-share", "inf"])
                k = a.warm_fill * n
                runs.append(("warm", r, frames[k:], written[k - 1:k - 1 + n]))
        perf.send_signal(2)
        perf.wait()
        trace = subprocess.run(["perf", "script", "-i", data, "-F", "cpu,time,trace"],
                               capture_output=True, text=True).stdout
    spans = on_cpu(trace)

    def total(f):
        return f["ms"] + f["step_ms"]

    warm = [x for x in runs if x[0] == "warm"]
    flagged, rest = [], []
    print(f"{a.model}: {a.runs} cold runs, {a.null} warm processes, {a.size}, --poe {a.poe}, "
          f"--cache-mb {a.cache_mb}; frames over {a.flag}x the warm processes' median:")
    print(f"{'run':>8} {'frame':>5} {'ratio':>5} {'ms':>6} | CPU ms in the frame: {'render':>6} {'fetch':>5} "
          f"{'idle':>5}  other processes")
    for kind, r, frames, starts in runs:
        others = [w for w in warm if not (kind == "warm" and w[1] == r)]
        for k in range(1, n):
            if starts[k] is None:
                continue
            ref = statistics.median(total(o[2][k]) for o in others)
            ratio = total(frames[k]) / ref
            a0, b0 = starts[k], starts[k] + frames[k]["ms"] / 1e3
            mine = {t: cpu_in(s, a0, b0) for t, s in spans.items() if t[1] == "oocfmt"}
            # The render threads have the process's highest priority; the fetchers run below it.
            top = min((t[2] for t, v in mine.items() if v > 0), default=120)
            fetch = sum(v for t, v in mine.items() if t[2] > top)
            rend = sum(v for t, v in mine.items() if t[2] == top)
            idle = sum(cpu_in(s, a0, b0) for t, s in spans.items() if t[0] == 0)
            other = collections.Counter()
            for t, s in spans.items():
                if t[0] != 0 and t[1] != "oocfmt":
                    v = cpu_in(s, a0, b0)
                    if v > 0:
                        other[t[1]] += v
            row = (kind, r, k, ratio, total(frames[k]), rend, fetch, idle, other)
            (flagged if ratio > a.flag else rest).append(row)
            if ratio > a.flag:
                names = ", ".join(f"{name} {1e3 * v:.1f}" for name, v in other.most_common(3))
                print(f"{kind:>5} {r + 1:2} {k:5} {ratio:5.2f} {row[4]:6.1f} | {'':20} {1e3 * rend:6.1f} "
                      f"{1e3 * fetch:5.1f} {1e3 * idle:5.1f}  {names}")
    for name, rows in (("over", flagged), ("the rest", rest)):
        if rows:
            print(f"frames {name} ({len(rows)}): other processes' CPU {1e3 * statistics.mean(sum(x[8].values()) for x in rows):.1f} ms "
                  f"a frame on average, idle {1e3 * statistics.mean(x[7] for x in rows):.1f} ms")


if __name__ == "__main__":
    main()
