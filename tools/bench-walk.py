#!/usr/bin/env python3
"""Walkthrough figures of `oocfmt render --path`: cold start against warm frames, and a cache
budget a tenth of the container; or, with --strategies, the cache strategies side by side.

Generates and converts a Mandelbulb with the release binary (or takes --model), writes a path
that approaches the model while orbiting it, and renders it

  1. cold, async cache, --runs times (each a fresh process: only the root block and the
     proxies are resident); with --paired P, each run goes on over the path --paired-fill + P
     more times, and the P timed passes are the run's own warm frames, seconds after its cold
     ones; with --null N, N warm processes (--warm-fill passes, then one timed) alternate with
     the cold runs: each warm process against the others is the null test, how often a run that
     fetches nothing has a frame over 1.5x on this machine, and the cold runs are held to the
     same reference;
  2. warm: the same path --warm-fill + --warm-passes times in one process, fetching without a
     per-frame limit; the warm time of a frame is the median of the timed passes (after the
     fill passes every block the walk wants is resident and nothing is fetched, if the cache
     holds the walk: the figures say how many blocks the timed passes loaded);
  3. cold with --cache-mb a tenth of the container's size.

Prints per frame the warm milliseconds (the frame's rays plus the cache's step after it), each
cold run's milliseconds and ratio to the warm ones, the share of pixels still coarse (ending on
a voxel or proxy where the warm frame shows triangles), blocks loaded, the working set; then per
cold run the largest cold/warm ratio and the frame from which the cold images equal the warm
ones, and with --paired the largest ratio to the run's own later passes (a ratio measured in
one run); with --null, each cold run's and each warm process's worst frame against the warm
processes' median (the other ones' for a warm process), how many runs of each went over 1.5x
and the chance of as many cold runs over if cold and warm runs went over alike (Fisher's exact
test); how far each warm pass strays from the warm median (the same ratio, measured where
nothing is fetched: the spread of a frame's time on the machine); and the small budget's peak.
With --strategies: the same cold walkthrough, for each --cache-mb of --strategy-mb, with each
cache strategy (fetch order Afra or Wald, eviction LRU or second chance, look-ahead prefetching
off or on) and --accuracy: per strategy the medians over the frames of the frame time (the
frame's rays, the cache's step and the look-ahead), the largest frame time, the spikes (frames
over 1.5x the run's median), the misses (distinct blocks a frame wanted and did not find), the
blocks loaded per frame (median and the largest burst), the frames that missed blocks, the share
of coarse pixels, the accuracy (share of pixels equal to full detail: blocking cache, PoE 0) and
the error against the true picture (full detail at --reference-spp rays per pixel) on the
model's pixels, beside the aliasing floor (full detail at one ray per pixel against the same
reference) and the whole image's RMSE; and an SVG plot of the per-frame accuracy and blocks loaded (--plot).
Standard library only.

    cargo build --release -p oocfmt-cli
    python3 tools/bench-walk.py --tris 1e7
    python3 tools/bench-walk.py --model target/bench-render/mb10m.oocf --strategies
"""

import argparse
import hashlib
import json
import math
import os
import statistics
import tempfile

from benchlib import ROOT, path_cameras, require_binary, run


def render_path(model, cams, work, name, extra):
    """Renders `cams` as a walkthrough; returns its per-frame figures, each with the digest of
    its PNG (`png_sha256`). The run's files are deleted at once: a set of runs at 1024x768
    writes about 770 MiB of PNGs, which would otherwise stay on disk and in the page cache
    while the later runs are timed (docs/notes/2026-12-01-cold-start-frame-bound.md)."""
    path = os.path.join(work, f"{name}.json")
    with open(path, "w") as f:
        json.dump(cams, f)
    stats = os.path.join(work, f"{name}-stats.json")
    out = os.path.join(work, f"{name}.png")
    run(["render", model, "-o", out, "--path", path, "--stats-json", stats] + extra)
    with open(stats) as f:
        frames = json.load(f)
    for fr in frames:
        with open(fr["file"], "rb") as png:
            fr["png_sha256"] = hashlib.sha256(png.read()).hexdigest()
        os.remove(fr["file"])
    os.remove(stats)
    os.remove(path)
    return frames


# (label, flags): the strategies --strategies compares, the first the default.
STRATEGIES = [
    ("afra+lru", ["--fetch-order", "afra", "--eviction", "lru"]),
    ("afra+2nd-chance", ["--fetch-order", "afra", "--eviction", "second-chance"]),
    ("wald+lru", ["--fetch-order", "wald", "--eviction", "lru"]),
    ("wald+2nd-chance", ["--fetch-order", "wald", "--eviction", "second-chance"]),
    ("afra+lru+prefetch", ["--fetch-order", "afra", "--eviction", "lru", "--prefetch", "on"]),
    ("wald+2nd-chance+prefetch", ["--fetch-order", "wald", "--eviction", "second-chance", "--prefetch", "on"]),
]


def frame_ms(f):
    return f["ms"] + f["step_ms"] + f.get("prefetch_ms", 0.0)


def summarize(frames):
    """The per-strategy figures of one run's per-frame figures."""
    times = [frame_ms(f) for f in frames]
    med = statistics.median(times)
    rays = frames[0]["stats"]["primary_rays"]
    loaded = [f["blocks_loaded"] for f in frames]
    return {
        "median_ms": med,
        "max_ms": max(times),
        "spikes": sum(t > 1.5 * med for t in times),
        "median_missed": statistics.median(f["blocks_missed"] for f in frames),
        "total_missed": sum(f["blocks_missed"] for f in frames),
        "median_loaded": statistics.median(loaded),
        "max_loaded": max(loaded),
        "frames_missing": sum(f["blocks_missed"] > 0 for f in frames),
        "coarse_pct": 100 * statistics.median(f["coarse_pixels"] for f in frames) / rays,
        "accuracy_pct": 100 * statistics.median(f["accuracy"]["exact"] for f in frames),
        "min_accuracy_pct": 100 * min(f["accuracy"]["exact"] for f in frames),
        "model_rmse": statistics.median(f["accuracy"]["error"]["model"]["rmse"] for f in frames),
        "floor_rmse": statistics.median(f["accuracy"]["floor"]["model"]["rmse"] for f in frames),
        "model_bias": statistics.median(f["accuracy"]["error"]["model"]["bias"] for f in frames),
        "model_ssim": statistics.median(f["accuracy"]["error"]["model"]["ssim"] for f in frames),
        "whole_rmse": statistics.median(f["accuracy"]["error"]["whole"]["rmse"] for f in frames),
        "prefetched": sum(f.get("blocks_prefetched", 0) for f in frames),
        "prefetch_used": sum(f.get("blocks_prefetch_used", 0) for f in frames),
        "peak_mb": max(f["stats"]["cache"]["peak_bytes_resident"] for f in frames) / 2**20,
    }


COLOURS = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f"]


def svg_plot(path, title, rows):
    """A plain SVG of rows of panels; each panel (title, y label, series) with series
    (label, [y per frame]) drawn as lines over the frame number, the legend below. Standard
    library only."""
    pw, ph, left, top, gap = 420, 220, 70, 50, 60
    cols = max(len(r) for r in rows)
    legend = rows[0][0][2]
    width = left + cols * (pw + left) + 10
    height = top + len(rows) * (ph + gap) + 18 * len(legend) + 10
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
           f'font-family="sans-serif" font-size="12">',
           f'<rect width="{width}" height="{height}" fill="white"/>',
           f'<text x="{width / 2}" y="18" text-anchor="middle" font-size="14">{title}</text>']
    cells = [(r, k, panel) for r, row in enumerate(rows) for k, panel in enumerate(row)]
    for r, k, (ptitle, ylabel, series) in cells:
        x0 = left + k * (pw + left)
        top_r = top + r * (ph + gap)
        ys = [y for _, v in series for y in v]
        frames = max(len(v) for _, v in series)
        lo, hi = min(ys + [0]), max(ys + [1e-9])
        if hi <= lo:
            hi = lo + 1
        sx = lambda i: x0 + pw * i / max(frames - 1, 1)
        sy = lambda y: top_r + ph - ph * (y - lo) / (hi - lo)
        out.append(f'<rect x="{x0}" y="{top_r}" width="{pw}" height="{ph}" fill="none" stroke="#888"/>')
        out.append(f'<text x="{x0 + pw / 2}" y="{top_r - 8}" text-anchor="middle">{ptitle}</text>')
        for t in range(5):
            y = lo + (hi - lo) * t / 4
            out.append(f'<line x1="{x0 - 4}" x2="{x0 + pw}" y1="{sy(y):.1f}" y2="{sy(y):.1f}" stroke="#eee"/>')
            out.append(f'<text x="{x0 - 6}" y="{sy(y) + 4:.1f}" text-anchor="end">{y:.3g}</text>')
        for t in range(0, frames, max(1, frames // 6)):
            out.append(f'<text x="{sx(t):.1f}" y="{top_r + ph + 16}" text-anchor="middle">{t}</text>')
        out.append(f'<text x="{x0 + pw / 2}" y="{top_r + ph + 32}" text-anchor="middle">frame</text>')
        out.append(f'<text x="{x0 - 45}" y="{top_r + ph / 2}" text-anchor="middle" '
                   f'transform="rotate(-90 {x0 - 45} {top_r + ph / 2})">{ylabel}</text>')
        for j, (label, v) in enumerate(series):
            c = COLOURS[j % len(COLOURS)]
            pts = " ".join(f"{sx(i):.1f},{sy(y):.1f}" for i, y in enumerate(v))
            out.append(f'<polyline fill="none" stroke="{c}" stroke-width="1.5" points="{pts}"/>')
    for j, (label, _) in enumerate(legend):
        y = top + len(rows) * (ph + gap) + 18 * j
        c = COLOURS[j % len(COLOURS)]
        out.append(f'<line x1="{left}" x2="{left + 24}" y1="{y - 4}" y2="{y - 4}" stroke="{c}" stroke-width="3"/>')
        out.append(f'<text x="{left + 30}" y="{y}">{label}</text>')
    out.append("</svg>")
    with open(path, "w") as f:
        f.write("\n".join(out) + "\n")


def compare_strategies(a, model, cams, common, size_mb):
    budgets = [int(m) for m in a.strategy_mb.split(",")]
    runs = {}
    with tempfile.TemporaryDirectory(dir=a.dir) as work:
        for mb in budgets:
            for label, flags in STRATEGIES:
                extra = common + ["--cache-mb", str(mb), "--accuracy",
                                  "--reference-spp", str(a.reference_spp),
                                  "--prefetch-mb", str(a.prefetch_mb)] + flags
                name = f"s{mb}-{label.replace('+', '-')}"
                runs[(mb, label)] = render_path(model, cams, work, name, extra)
    print(f"model {model}: {size_mb:.1f} MiB; {a.frames} frames + {a.hold} still, {a.size}, --poe {a.poe}, "
          f"{a.fetchers} fetchers, --prefetch-mb {a.prefetch_mb}; cold cache each run")
    print("ms: frame's rays + cache step + look-ahead; spikes: frames over 1.5x the run's median; missed: "
          "distinct blocks a frame wanted and did not find; loaded: blocks published after a frame; "
          "acc%: pixels equal to full detail (blocking, PoE 0); RMSE, SSIM, bias: on the model's pixels "
          f"(hit in either image) against full detail at {a.reference_spp} rays per pixel; floor: full detail "
          "at 1 ray per pixel against the same reference; all: RMSE over the whole image (medians over the frames)")
    head = (f"{'MiB':>4} {'strategy':<25} {'med ms':>7} {'max ms':>7} {'spikes':>6} {'missed':>6} "
            f"{'loaded':>6} {'burst':>5} {'frames':>6} {'coarse%':>7} {'acc%':>6} {'min%':>6} "
            f"{'RMSE':>6} {'floor':>6} {'SSIM':>6} {'bias':>6} {'all':>6} {'pf used':>9} {'peak':>6}")
    print(head)
    for (mb, label), frames in runs.items():
        s = summarize(frames)
        pf = f"{s['prefetch_used']}/{s['prefetched']}" if s["prefetched"] else "-"
        print(f"{mb:>4} {label:<25} {s['median_ms']:7.1f} {s['max_ms']:7.1f} {s['spikes']:6} "
              f"{s['median_missed']:6.0f} {s['median_loaded']:6.0f} {s['max_loaded']:5} "
              f"{s['frames_missing']:6} {s['coarse_pct']:7.2f} {s['accuracy_pct']:6.2f} "
              f"{s['min_accuracy_pct']:6.2f} {s['model_rmse']:6.2f} {s['floor_rmse']:6.2f} "
              f"{s['model_ssim']:6.4f} {s['model_bias']:+6.2f} {s['whole_rmse']:6.2f} {pf:>9} {s['peak_mb']:6.1f}")
    print("frames: frames that missed blocks (of %d); pf used: prefetched blocks a later frame used / "
          "blocks prefetched; peak: most MiB held" % len(cams))
    if a.plot:
        rows = [[(f"--cache-mb {mb}: accuracy", "pixels equal to full detail",
                  [(l, [f["accuracy"]["exact"] for f in runs[(mb, l)]]) for l, _ in STRATEGIES]),
                 (f"--cache-mb {mb}: blocks loaded per frame", "blocks",
                  [(l, [f["blocks_loaded"] for f in runs[(mb, l)]]) for l, _ in STRATEGIES])]
                for mb in budgets]
        svg_plot(a.plot, f"Cold walkthrough of {os.path.basename(model)}, {a.size}, --poe {a.poe}", rows)
        print(f"wrote {a.plot}")


def fisher_greater(a, n1, b, n2):
    """One-sided Fisher's exact test: the chance that a sample of n1 runs out of n1 + n2, of which
    a + b went over, holds a or more of them, if which runs went over had nothing to do with the
    sample they were in. Small: the first sample goes over more often than the second."""
    k, n = a + b, n1 + n2
    return sum(math.comb(k, x) * math.comb(n - k, n1 - x) for x in range(a, min(k, n1) + 1)) / math.comb(n, n1)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--tris", default="1e7")
    p.add_argument("--model", help="an existing container (default: generate and convert one)")
    p.add_argument("--frames", type=int, default=30)
    p.add_argument("--hold", type=int, default=5, help="still frames on the last camera, to see the cold images converge")
    p.add_argument("--size", default="1024x768")
    p.add_argument("--poe", default="1")
    p.add_argument("--cache-mb", type=int, default=2048)
    p.add_argument("--fetchers", type=int, help="fetcher threads (default: render's, half the cores)")
    p.add_argument("--runs", type=int, default=3, help="cold runs, each a fresh process")
    p.add_argument("--paired", type=int, default=0,
                   help="timed passes each cold run renders after its cold one and --paired-fill more, in "
                        "the same process: its own warm reference, measured seconds later (0: none)")
    p.add_argument("--paired-fill", type=int, default=2,
                   help="untimed passes each cold run renders between its cold one and the --paired ones, "
                        "to load what the cold pass passed by")
    p.add_argument("--null", type=int, default=0,
                   help="warm processes alternating with the cold runs, each --warm-fill passes and one "
                        "timed pass: how often a run that fetches nothing has a frame over 1.5x the others' "
                        "median (the machine's spread), next to the cold runs held to the same median")
    p.add_argument("--warm-passes", type=int, default=3,
                   help="timed warm passes (after --warm-fill passes); warm = their median")
    p.add_argument("--warm-fill", type=int, default=3,
                   help="untimed passes that fill the cache before the warm ones: a moving camera "
                        "passes blocks by before they arrive, so one pass leaves some behind")
    p.add_argument("--render-args", default="", help="more `oocfmt render` flags for every run, "
                   "space-separated, e.g. '--fetch-priority normal'")
    p.add_argument("--nice", type=int, default=0,
                   help="run every render this many nice levels from this script's (below 0 needs "
                        "root): -10 gives the render threads the CPU before the system's own threads, "
                        "and the fetchers keep their distance below the render threads")
    p.add_argument("--dir", default=os.path.join(ROOT, "target", "bench-walk"))
    p.add_argument("--strategies", action="store_true",
                   help="compare the cache strategies on one cold walkthrough instead")
    p.add_argument("--strategy-mb", default="26,64", help="--strategies: the cache budgets, MiB")
    p.add_argument("--prefetch-mb", default="4", help="--strategies: the per-frame prefetch budget")
    p.add_argument("--plot", help="--strategies: write the per-frame plot to this SVG file")
    p.add_argument("--reference-spp", type=int, default=16,
                   help="--strategies: rays per pixel of the --accuracy reference")
    a = p.parse_args()
    require_binary()
    if a.nice:
        # The renders are this script's children and start at its nice value.
        os.nice(a.nice)
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
    common = ["--size", a.size, "--poe", a.poe] + a.render_args.split()
    if a.fetchers:
        common += ["--fetchers", str(a.fetchers)]
    if a.strategies:
        compare_strategies(a, model, cams, common, size_mb)
        return
    with tempfile.TemporaryDirectory(dir=a.dir) as work:
        # With --paired, each cold run goes on over the path: --paired-fill passes to load what
        # the cold pass passed by, then --paired timed ones, its own warm frames measured in the
        # same process seconds later, so that the machine's slow spells of several seconds weigh
        # on a cold frame and its reference alike.
        later = a.paired_fill + a.paired if a.paired else 0
        # With --null, warm processes alternate with the cold runs, so that both meet the
        # machine's same slow minutes.
        runs, nulls = [], []
        # Warm processes fetch without a per-frame limit, so that their fill passes leave every
        # block the walk wants resident (a cache that holds the walk then fetches nothing in the
        # timed passes).
        unlimited = [] if "--fetch-share" in common else ["--fetch-share", "inf"]
        for r in range(max(a.runs, a.null)):
            if r < a.runs:
                runs.append(render_path(model, cams * (1 + later), work, f"cold{r}",
                                        common + ["--cache-mb", str(a.cache_mb)]))
            if r < a.null:
                passes = render_path(model, cams * (a.warm_fill + 1), work, f"null{r}",
                                     common + ["--cache-mb", str(a.cache_mb)] + unlimited)
                nulls.append(passes[a.warm_fill * frames:])
        colds = [passes[:frames] for passes in runs]
        fill = a.warm_fill
        passes = render_path(model, cams * (fill + a.warm_passes), work, "warm",
                             common + ["--cache-mb", str(a.cache_mb)] + unlimited)
        warm_passes = [passes[k * frames:(k + 1) * frames] for k in range(fill, fill + a.warm_passes)]
        small_mb = max(1, int(size_mb / 10))
        small = render_path(model, cams, work, "small", common + ["--cache-mb", str(small_mb)])
        warm_pngs = [f["png_sha256"] for f in warm_passes[0]]
        equal = [[c["png_sha256"] == w for c, w in zip(cold, warm_pngs)] for cold in colds]

    def total(f):
        return f["ms"] + f["step_ms"]

    # The warm frame time of a camera: the median of its timed warm passes. The same rule
    # applied to each warm pass shows how far one frame's time strays on this machine.
    warm = [statistics.median(total(p[i]) for p in warm_passes) for i in range(frames)]
    noise = [max(total(p[i]) / warm[i] for i in range(frames)) for p in warm_passes]
    warm_loaded = [sum(f["blocks_loaded"] for f in p) for p in warm_passes]
    ratios = [[total(c) / w for c, w in zip(cold, warm)] for cold in colds]
    # A frame's cold time over the runs: their median drops a spike one run had (the warm
    # passes show the machine makes those with nothing fetched), not a stall every run has.
    median_ratios = [statistics.median(total(c[i]) for c in colds) / warm[i] for i in range(frames)]
    # Per run: the cold frame over the median of the same camera in the run's later passes.
    paired, paired_loaded = [], []
    if a.paired:
        timed = range(1 + a.paired_fill, 1 + a.paired_fill + a.paired)
        paired = [[total(c[i]) / statistics.median(total(c[k * frames + i]) for k in timed)
                   for i in range(frames)] for c in runs]
        paired_loaded = [sum(f["blocks_loaded"] for f in c[timed.start * frames:]) for c in runs]
    cold = colds[0]
    print(f"model {model}: {size_mb:.1f} MiB; {a.frames} frames + {a.hold} still, {a.size}, --poe {a.poe}, "
          f"--cache-mb {a.cache_mb}, fetchers: {a.fetchers or 'default'}, render threads: all cores "
          f"({cold[0]['stats']['threads']}), nice {os.nice(0)}; {a.runs} cold runs, warm = median of "
          f"{a.warm_passes} passes")
    print("ratio: the cold frame (rays + the cache's step) over the warm median; fetch: the fetchers' CPU "
          "ms between the steps around the frame; coarse: pixels ending on a voxel or proxy (at --poe > 0 "
          "the warm frames have some too), run 1; =warm: the cold frame's image equals the warm one's, per run")
    print(f"{'frame':>5} {'warm ms':>8} {'cold ms, ratio, fetch per run':>{18 * a.runs}} {'coarse %':>8} {'warm %':>6} "
          f"{'loaded':>7} {'MiB':>7} {'=warm':>{4 * a.runs}} | {'small ms':>8} {'coarse %':>8} {'MiB':>6}")
    rays = cold[0]["stats"]["rays"]
    for i in range(frames):
        c, w, s = cold[i], warm_passes[0][i], small[i]
        per_run = " ".join(f"{total(colds[r][i]):6.1f} {ratios[r][i]:4.2f} {colds[r][i].get('fetch_cpu_ms', 0):5.1f}"
                           for r in range(a.runs))
        same = " ".join(f"{'yes' if equal[r][i] else 'no':>3}" for r in range(a.runs))
        print(f"{i:5} {warm[i]:8.1f} {per_run:>{18 * a.runs}} "
              f"{100 * c['coarse_pixels'] / rays:8.2f} {100 * w['coarse_pixels'] / rays:6.2f} {c['blocks_loaded']:7} "
              f"{c['working_set_mb']:7.1f} {same:>{4 * a.runs}} | "
              f"{total(s):8.1f} {100 * s['coarse_pixels'] / rays:8.2f} {s['working_set_mb']:6.1f}")
    for r in range(a.runs):
        worst = max(range(frames), key=lambda i: ratios[r][i])
        first_equal = next((i for i in range(frames) if all(equal[r][i:])), None)
        print(f"cold run {r + 1}: worst frame {ratios[r][worst]:.2f}x warm (frame {worst}), median "
              f"{statistics.median(ratios[r]):.2f}; "
              + (f"images equal the warm ones from frame {first_equal}" if first_equal is not None
                 else f"images never all equal the warm ones (last frame {100 * colds[r][-1]['coarse_pixels'] / rays:.2f} "
                      f"% coarse against {100 * warm_passes[0][-1]['coarse_pixels'] / rays:.2f} %)"))
    for r, pr in enumerate(paired):
        worst = max(range(frames), key=lambda i: pr[i])
        print(f"cold run {r + 1} against its own {a.paired} later passes: worst frame {pr[worst]:.2f}x "
              f"(frame {worst}), median {statistics.median(pr):.2f}; blocks those passes loaded: "
              f"{paired_loaded[r]}")
    worst = max(range(frames), key=lambda i: median_ratios[i])
    print(f"median of the {a.runs} cold runs per frame: worst frame {median_ratios[worst]:.2f}x warm (frame {worst})")
    if nulls:
        # The null test: a warm process fetches nothing, so a frame of its timed pass over 1.5x
        # the other warm processes' median is the machine's spread, not a stall. The cold runs
        # are held to the median of all the warm processes.
        def worst_of(run, others):
            r = [total(run[i]) / statistics.median(total(o[i]) for o in others) for i in range(frames)]
            i = max(range(frames), key=lambda k: r[k])
            return r[i], i

        def listed(worsts):
            return " ".join(f"{w:.2f} ({i})" for w, i in worsts)

        null_worst = [worst_of(n, nulls[:k] + nulls[k + 1:]) for k, n in enumerate(nulls)] if len(nulls) > 1 else []
        cold_worst = [worst_of(c, nulls) for c in colds]
        over = sum(w > 1.5 for w, _ in cold_worst)
        print(f"against {len(nulls)} warm processes (the median of each frame over them): cold runs' worst frames "
              f"(frame) {listed(cold_worst)}; {over} of {len(colds)} runs over 1.5x")
        walk = statistics.median(sum(map(total, c)) for c in colds) / statistics.median(sum(map(total, n)) for n in nulls)
        print(f"whole walk: the cold runs' median {walk:.2f}x the warm processes' median")
        if null_worst:
            null_over = sum(w > 1.5 for w, _ in null_worst)
            print(f"each warm process against the other warm processes: worst frames (frame) {listed(null_worst)}; "
                  f"{null_over} of {len(null_worst)} runs over 1.5x, with nothing fetched")
            print(f"chance of {over} or more of {len(colds)} cold runs over 1.5x if cold and warm runs went over "
                  f"alike (Fisher's exact test, one-sided): {fisher_greater(over, len(colds), null_over, len(null_worst)):.2f}")
    print(f"warm: median frame {statistics.median(warm):.1f} ms; each warm pass against the median: worst frame "
          + ", ".join(f"{n:.2f}x" for n in noise) + " (the spread of one frame's time on this machine)"
          + f"; blocks the timed warm passes loaded: {', '.join(map(str, warm_loaded))}"
          + ("" if sum(warm_loaded) < frames else " (the cache does not hold the walk: warm means steady)"))
    peak = max(f["stats"]["cache"]["peak_bytes_resident"] for f in small) / 2**20
    print(f"--cache-mb {small_mb} ({size_mb / small_mb:.1f}x smaller than the container): peak "
          f"{peak:.1f} MiB held, median frame {statistics.median(total(s) for s in small):.1f} ms, "
          f"coarse pixels in the last frame {100 * small[-1]['coarse_pixels'] / rays:.2f} %")


if __name__ == "__main__":
    main()
