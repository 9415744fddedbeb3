#!/usr/bin/env python3
"""The cold-start bound (issue 28, items 6 and 7): cold walkthrough frames against warm ones,
render-thread waits on I/O per frame, and the memory of reading through the page cache or past
it.

For each configuration of --configs (`buffered`: the async cache reading through the page
cache; `direct`: the async cache with `--io direct`, past it; `mmap`: the mmap cache over an
uncompressed copy of the model; `blocking`: the blocking cache, buffered), renders the
walkthrough of bench-walk.py (`render --path`: approach and orbit, --frames cameras and --hold
still ones on the last) --runs times cold and --runs times warm, alternating, each a fresh
process:

  - cold: the model's pages are evicted from the page cache first (--evict: `drop` empties the
    whole page cache, `sync; echo 3 > /proc/sys/vm/drop_caches`, as root or through `sudo -n`;
    `fadvise` drops the model file's clean pages alone, posix_fadvise(POSIX_FADV_DONTNEED),
    which needs no root and leaves the other users of the machine their caches; `auto`: drop
    where allowed, else fadvise), so the process starts with only the root block and the
    proxies and reads everything else from the disk;
  - warm: --warm-fill passes over the path without a per-frame fetch limit, then one timed pass
    with every block the walk wants resident (and the file in the page cache, unless direct).

A frame's time is its rays plus the cache's step after it. Per configuration the script prints
the cold/warm ratios of every cold frame (the frame's time over the median of the warm runs'
same frame): the 50th and 95th percentile and the largest; beside it the warm runs' own spread,
each warm frame over the median of the other warm runs' same frame (the machine's noise,
measured where nothing is read); the bound, 95th percentile of the cold ratios <= 1.5; the
render-thread waits on I/O per frame (`waits` of the per-frame figures: 0 in every frame of the
async cache); the share of surface rays drawn on a proxy because their block was not resident
(what the async cache shows instead of waiting) and the blocks a cold run loads; the peak
resident set of the processes (the decoded blocks, the proxies, and for mmap the mapped pages
touched) and the bytes of the model in the page cache after a cold run
(`fincore`, where installed). --per-frame adds each configuration's first cold run frame by
frame, side by side: the time, the shares of surface rays ending at full detail, on a LOD record
and on a proxy, the blocks loaded, the working set (mmap: the bytes of blocks touched) and the
waits. Standard library only.

--memory-limit-mb M runs every render process in a memory control group (cgroup v2
`memory.max`, or v1 `memory.limit_in_bytes`; needs root) holding at most M MiB of the process's
memory and of the page cache it fills, so a model larger than M is larger than the memory the
renderer has, on a machine with more RAM than the model: the page cache cannot keep the file, and
mmap pages it in and out again. The script makes the group and removes it at the end.

    cargo build --release -p oocfmt-cli
    python3 tools/bench-cold.py --tris 1e6
    python3 tools/bench-cold.py --model big.oocf --mmap-model big-none.oocf --poe 3 --cache-mb 4096
    python3 tools/bench-cold.py --model big.oocf --mmap-model big-none.oocf --cache-mb 256 \
        --memory-limit-mb 768
"""

import argparse
import json
import os
import shutil
import statistics
import subprocess
import tempfile

from benchlib import BIN, ROOT, machine, path_cameras, require_binary, run

# (name, render flags, whether the configuration renders the uncompressed copy)
CONFIGS = {
    "buffered": (["--cache", "async", "--io", "buffered"], False),
    "direct": (["--cache", "async", "--io", "direct"], False),
    "mmap": (["--cache", "mmap"], True),
    "blocking": (["--cache", "blocking", "--io", "buffered"], False),
}

DROP = "sync && echo 3 > /proc/sys/vm/drop_caches"


def can_drop():
    """Whether this process may empty the page cache (root, or sudo without a password)."""
    cmd = ["sh", "-c", DROP] if os.geteuid() == 0 else ["sudo", "-n", "sh", "-c", DROP]
    return subprocess.run(cmd, capture_output=True).returncode == 0


def evict(method, path):
    """Empties the page cache (`drop`) or drops the clean pages of `path` (`fadvise`)."""
    if method == "drop":
        cmd = ["sh", "-c", DROP] if os.geteuid() == 0 else ["sudo", "-n", "sh", "-c", DROP]
        subprocess.run(cmd, check=True, capture_output=True)
        return
    os.sync()
    fd = os.open(path, os.O_RDONLY)
    try:
        os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_DONTNEED)
    finally:
        os.close(fd)


def cached_bytes(path):
    """Bytes of `path` in the page cache (`fincore`), or None where fincore is missing."""
    if shutil.which("fincore") is None:
        return None
    r = subprocess.run(["fincore", "--bytes", "--noheadings", "--output", "RES", path],
                       capture_output=True, text=True)
    try:
        return int(r.stdout.split()[0])
    except (IndexError, ValueError):
        return None


class MemoryGroup:
    """A memory control group of `limit_mb` MiB that the render processes join (see the module
    text); None-like when no limit is asked for."""

    def __init__(self, limit_mb):
        self.path = None
        if limit_mb is None:
            return
        name = f"oocfmt-bench-cold-{os.getpid()}"
        v2 = os.path.exists("/sys/fs/cgroup/cgroup.controllers")
        base = "/sys/fs/cgroup" if v2 else "/sys/fs/cgroup/memory"
        limit_file = "memory.max" if v2 else "memory.limit_in_bytes"
        path = os.path.join(base, name)
        try:
            os.mkdir(path)
            with open(os.path.join(path, limit_file), "w") as f:
                f.write(str(limit_mb * 2**20))
        except OSError as e:
            if os.path.isdir(path):
                os.rmdir(path)
            raise SystemExit(f"--memory-limit-mb: cannot make the memory group {path}: {e} "
                             "(it needs root and a mounted memory controller)")
        self.path = path

    def join(self):
        """Moves the calling process into the group (a Popen preexec_fn)."""
        if self.path is not None:
            with open(os.path.join(self.path, "cgroup.procs"), "w") as f:
                f.write(str(os.getpid()))

    def close(self):
        if self.path is None:
            return
        empty = os.path.join(self.path, "memory.force_empty")
        if os.path.exists(empty):
            with open(empty, "w") as f:
                f.write("0")
        os.rmdir(self.path)
        self.path = None


GROUP = MemoryGroup(None)


def walk(model, cams, work, name, flags):
    """Renders `cams` as one walkthrough in a fresh process; returns its per-frame figures and
    the process's peak resident set in MiB. Its PNGs are deleted at once, so they do not fill
    the page cache of the later runs."""
    path = os.path.join(work, f"{name}.json")
    with open(path, "w") as f:
        json.dump(cams, f)
    stats = os.path.join(work, f"{name}-stats.json")
    args = ["render", model, "-o", os.path.join(work, f"{name}.png"), "--path", path,
            "--stats-json", stats] + flags
    p = subprocess.Popen([BIN] + args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                         preexec_fn=GROUP.join)
    err = p.stderr.read() if p.stderr else ""
    _, status, usage = os.wait4(p.pid, 0)
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"oocfmt {' '.join(args)} failed:\n{err}")
    with open(stats) as f:
        frames = json.load(f)
    for fr in frames:
        os.remove(fr["file"])
    os.remove(stats)
    os.remove(path)
    return frames, usage.ru_maxrss / 1024


def total(f):
    return f["ms"] + f["step_ms"]


def proxy_share(f):
    """The share of a frame's surface rays that ended on a proxy: their block was not resident
    (the async cache draws the proxy instead of waiting; 0 for a cache that waits)."""
    e = f["stats"].get("primary", {})
    surface = sum(e.get(k, 0) for k in ("triangle", "voxel", "rlod", "proxy"))
    return e.get("proxy", 0) / surface if surface else 0.0


def frame_row(f):
    """What a person reads of one frame: its time, where its surface rays ended (full detail,
    a LOD record, or a proxy because the block was not resident), the blocks it loaded, the
    decoded (mmap: touched) bytes resident and the render-thread waits on I/O."""
    e = f["stats"].get("primary", {})
    surface = sum(e.get(k, 0) for k in ("triangle", "voxel", "rlod", "proxy")) or 1
    return {
        "ms": total(f),
        "full_detail": e.get("triangle", 0) / surface,
        "lod": (e.get("voxel", 0) + e.get("rlod", 0)) / surface,
        "proxy": e.get("proxy", 0) / surface,
        "blocks_loaded": f.get("blocks_loaded", 0),
        "working_set_mb": f.get("working_set_mb", 0.0),
        "waits": f.get("waits", 0),
    }


def print_per_frame(results):
    """The first cold run of each configuration, frame by frame, side by side."""
    cols = "{:>9} {:>6} {:>6} {:>6} {:>7} {:>8} {:>6}"
    head = "frame " + " | ".join(f"{r['config'] + ' (' + r['cache'] + ')':^55}" for r in results)
    print(head)
    print("      " + " | ".join(cols.format("ms", "full%", "lod%", "proxy%", "loaded", "WS MiB", "waits")
                                for _ in results))
    for i in range(min(len(r["first_cold"]) for r in results)):
        cells = []
        for r in results:
            f = r["first_cold"][i]
            cells.append(cols.format(f"{f['ms']:.1f}", f"{100 * f['full_detail']:.1f}", f"{100 * f['lod']:.1f}",
                                     f"{100 * f['proxy']:.1f}", f["blocks_loaded"],
                                     f"{f['working_set_mb']:.1f}", f["waits"]))
        print(f"{i:>5} " + " | ".join(cells))


def pct(values, q):
    """The q-th percentile (0..100) of `values`, linear between the nearest ranks."""
    v = sorted(values)
    if not v:
        return float("nan")
    k = (len(v) - 1) * q / 100
    lo, hi = int(k), min(int(k) + 1, len(v) - 1)
    return v[lo] + (v[hi] - v[lo]) * (k - lo)


def spread(values):
    return f"{pct(values, 50):.2f} / {pct(values, 95):.2f} / {max(values):.2f}"


def measure(name, a, model, cams, work, method, common):
    """The cold and warm runs of one configuration, alternating; prints its figures and
    returns them."""
    flags, _ = CONFIGS[name]
    frames = len(cams)
    unlimited = [] if "--fetch-share" in common else ["--fetch-share", "inf"]
    colds, warms, cold_rss, warm_rss, cached = [], [], [], [], []
    for r in range(a.runs):
        evict(method, model)
        fr, rss = walk(model, cams, work, f"{name}-cold{r}", common + flags)
        colds.append(fr)
        cold_rss.append(rss)
        cached.append(cached_bytes(model))
        fr, rss = walk(model, cams * (a.warm_fill + 1), work, f"{name}-warm{r}",
                       common + flags + (unlimited if name in ("buffered", "direct") else []))
        warms.append(fr[a.warm_fill * frames:])
        warm_rss.append(rss)
    warm_median = [statistics.median(total(w[i]) for w in warms) for i in range(frames)]
    ratios = [total(c[i]) / warm_median[i] for c in colds for i in range(frames)]
    noise = []
    for k, w in enumerate(warms):
        others = warms[:k] + warms[k + 1:]
        for i in range(frames):
            noise.append(total(w[i]) / statistics.median(total(o[i]) for o in others))
    cold_waits = [f.get("waits", 0) for c in colds for f in c]
    cold_proxy = [proxy_share(f) for c in colds for f in c]
    warm_proxy = [proxy_share(f) for w in warms for f in w]
    warm_waits = [f.get("waits", 0) for w in warms for f in w]
    io = colds[0][0]["stats"]["cache"].get("io", "?")
    mode = colds[0][0]["stats"]["cache"]["mode"]
    res = {
        "config": name,
        "cache": mode,
        "io": io,
        "warm_ms": statistics.median(warm_median),
        "cold_p50": pct(ratios, 50),
        "cold_p95": pct(ratios, 95),
        "cold_max": max(ratios),
        "warm_p50": pct(noise, 50) if noise else float("nan"),
        "warm_p95": pct(noise, 95) if noise else float("nan"),
        "warm_max": max(noise) if noise else float("nan"),
        "cold_waits_per_frame_median": statistics.median(cold_waits),
        "cold_waits_per_frame_max": max(cold_waits),
        "cold_frames_waiting": sum(w > 0 for w in cold_waits),
        "warm_waits_max": max(warm_waits),
        "cold_proxy_share_median": statistics.median(cold_proxy),
        "cold_proxy_share_max": max(cold_proxy),
        "warm_proxy_share_median": statistics.median(warm_proxy),
        "cold_blocks_loaded": statistics.median(c[-1]["stats"]["cache"]["blocks_loaded"] for c in colds),
        "cold_rss_mib": statistics.median(cold_rss),
        "cold_rss_max_mib": max(cold_rss),
        "warm_rss_mib": statistics.median(warm_rss),
        "peak_decoded_mib": max(f["stats"]["cache"]["peak_bytes_resident"] for c in colds for f in c) / 2**20,
        "warm_peak_decoded_mib": max(f["stats"]["cache"]["peak_bytes_resident"] for w in warms for f in w) / 2**20,
        "page_cache_after_cold_mib": (statistics.median(cached) / 2**20) if None not in cached else None,
    }
    res["bound_holds"] = res["cold_p95"] <= 1.5
    res["first_cold"] = [frame_row(f) for f in colds[0]]
    print(f"{name:>8} ({mode}, io {io}): warm frame {res['warm_ms']:.1f} ms (median); cold/warm ratio "
          f"p50 / p95 / max {spread(ratios)}; warm runs' own spread {spread(noise) if noise else 'n/a'}; "
          f"bound p95 <= 1.5: {'holds' if res['bound_holds'] else 'FAILS'}")
    in_cache = res["page_cache_after_cold_mib"]
    cache_line = (f"; the model in the page cache after a cold run {in_cache:.1f} MiB (with the RSS "
                  f"{res['cold_rss_mib'] + in_cache:.0f} MiB)" if in_cache is not None else "")
    print(f"{'':>8} waits on I/O per cold frame: median {res['cold_waits_per_frame_median']}, max "
          f"{res['cold_waits_per_frame_max']}, {res['cold_frames_waiting']} of {len(cold_waits)} frames "
          f"waited (warm frames: max {res['warm_waits_max']}); peak RSS cold {res['cold_rss_mib']:.0f} MiB "
          f"(max {res['cold_rss_max_mib']:.0f}), warm {res['warm_rss_mib']:.0f} MiB; decoded blocks peak "
          f"{res['peak_decoded_mib']:.1f} MiB cold, {res['warm_peak_decoded_mib']:.1f} MiB warm{cache_line}")
    print(f"{'':>8} rays drawn on a proxy (block not resident): median {100 * res['cold_proxy_share_median']:.2f} % "
          f"of a cold frame's surface rays (most {100 * res['cold_proxy_share_max']:.2f} %), "
          f"{100 * res['warm_proxy_share_median']:.2f} % warm; blocks loaded in a cold run "
          f"{res['cold_blocks_loaded']:.0f} (median)")
    return res


def generated(a):
    """The model, and its uncompressed copy for mmap: given, or generated and converted in
    --dir."""
    os.makedirs(a.dir, exist_ok=True)
    model, plain = a.model, a.mmap_model
    if model is None:
        n = int(float(a.tris))
        obj = os.path.join(a.dir, f"mandelbulb-{n}.obj")
        model = os.path.join(a.dir, f"mandelbulb-{n}.oocf")
        plain = plain or os.path.join(a.dir, f"mandelbulb-{n}-none.oocf")
        if not (os.path.exists(model) and os.path.exists(plain)):
            run(["gen", "mandelbulb", "--tris", str(n), "-o", obj, "--quiet"])
            run(["convert", obj, "-o", model, "--quiet"])
            run(["convert", obj, "-o", plain, "--codec", "none", "--quiet"])
            os.remove(obj)
    return model, plain


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--tris", default="1e6", help="Mandelbulb triangles to generate without --model")
    p.add_argument("--model", help="an existing container (default: generate and convert one)")
    p.add_argument("--mmap-model", help="the container converted with --codec none, for mmap "
                   "(default with --model: the model itself, which must then be uncompressed)")
    p.add_argument("--configs", default="buffered,direct,mmap",
                   help="comma-separated, of: " + ", ".join(CONFIGS))
    p.add_argument("--runs", type=int, default=10, help="cold runs, and as many warm ones")
    p.add_argument("--warm-fill", type=int, default=2, help="passes a warm run renders before its timed one")
    p.add_argument("--frames", type=int, default=30)
    p.add_argument("--hold", type=int, default=5, help="still frames on the last camera")
    p.add_argument("--size", default="1024x768")
    p.add_argument("--poe", default="1")
    p.add_argument("--cache-mb", type=int, default=1024)
    p.add_argument("--evict", choices=["auto", "drop", "fadvise"], default="auto",
                   help="how a cold run empties the page cache (see above)")
    p.add_argument("--render-args", default="", help="more `oocfmt render` flags for every run")
    p.add_argument("--memory-limit-mb", type=int,
                   help="run the renders in a memory group of this many MiB (see above)")
    p.add_argument("--per-frame", action="store_true",
                   help="also print the first cold run of every configuration frame by frame, side by side")
    p.add_argument("--json", help="also write the figures to this file")
    p.add_argument("--dir", default=os.path.join(ROOT, "target", "bench-cold"))
    a = p.parse_args()
    require_binary()
    names = [c.strip() for c in a.configs.split(",") if c.strip()]
    for n in names:
        if n not in CONFIGS:
            raise SystemExit(f"--configs: unknown `{n}` (expected {', '.join(CONFIGS)})")
    if a.memory_limit_mb is not None and a.memory_limit_mb < 64:
        raise SystemExit("--memory-limit-mb: at least 64 (the renderer itself needs more)")
    if a.runs < 2:
        raise SystemExit("--runs: at least 2 (a warm run's spread is measured against the others)")
    model, plain = generated(a)
    plain = plain or model
    method = a.evict
    if method == "auto":
        method = "drop" if can_drop() else "fadvise"
    elif method == "drop" and not can_drop():
        raise SystemExit("--evict drop: neither root nor `sudo -n` may write /proc/sys/vm/drop_caches")
    info = json.loads(run(["inspect", model, "--json"]))
    scene = info["metadata"]["scene"]
    origin = scene.get("origin", [0, 0, 0])
    lo = [o + v for o, v in zip(origin, scene["bounds_min"])]
    hi = [o + v for o, v in zip(origin, scene["bounds_max"])]
    cams = path_cameras(lo, hi, a.frames)
    cams += [cams[-1]] * a.hold
    global GROUP
    GROUP = MemoryGroup(a.memory_limit_mb)
    common = ["--size", a.size, "--poe", a.poe, "--cache-mb", str(a.cache_mb)] + a.render_args.split()
    print(f"machine: {machine()}")
    print(f"model {model} ({os.path.getsize(model) / 2**20:.1f} MiB); {a.frames} frames + {a.hold} still, "
          f"{a.size}, --poe {a.poe}, --cache-mb {a.cache_mb}; {a.runs} cold and {a.runs} warm runs per "
          f"configuration, alternating; cold: "
          + ("the page cache emptied (drop_caches)" if method == "drop"
             else "the model's clean pages dropped (posix_fadvise DONTNEED)")
          + (f"; every render in a memory group of {a.memory_limit_mb} MiB (process and page cache)"
             if a.memory_limit_mb else ""))
    print("ratios: p50 / p95 / max; cold: each cold frame over the warm runs' median of that frame; "
          "warm spread: each warm frame over the other warm runs' median")
    results = []
    try:
        with tempfile.TemporaryDirectory(dir=a.dir) as work:
            for n in names:
                results.append(measure(n, a, plain if CONFIGS[n][1] else model, cams, work, method, common))
    finally:
        GROUP.close()
    if a.per_frame:
        print_per_frame(results)
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"model": model, "evict": method, "runs": a.runs, "frames": len(cams),
                       "size": a.size, "poe": a.poe, "cache_mb": a.cache_mb,
                       "memory_limit_mb": a.memory_limit_mb, "results": results}, f, indent=1)


if __name__ == "__main__":
    main()
