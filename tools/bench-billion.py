#!/usr/bin/env python3
"""A model far larger than memory, end to end (issue 28, item 5): generate a Mandelbulb into a
pipe and convert it out of core, verify it, walk it from a cold start, and tabulate it as Áfra
(2012) does in Tables 5 and 6.

  1. `oocfmt gen mandelbulb --tris N -o - | oocfmt convert - --format obj --mem-limit M
     --codec none` (uncompressed, so the async cache, `--io direct` and mmap all read one file);
     skipped with --model, whose conversion report --report names;
  2. `verify --deep` with the page cache emptied first (root, or `sudo -n`), timed;
  3. the cold walkthrough of tools/bench-cold.py (approach and orbit, --frames + --hold frames,
     --cache-mb), with the async cache through the page cache, the async cache past it
     (`--io direct`) and mmap, --runs cold and warm runs each, frame by frame (--per-frame),
     optionally in a memory group of --memory-limit-mb;
  4. `curve` at PoE 1, 2 and 3 with the async cache: the warm frame time, the working set, and
     the error on the model's pixels against the true picture (full detail, --reference-spp
     rays per pixel, through a blocking cache of --reference-mb); with shadow rays `render
     --shadows --repeat 3` at each PoE with --shadow-cache-mb (the third, warm frame), and only
     with --shadow-error `curve --shadows` too: its full-detail shadowed reference sends shadow
     rays across most of the file, and through a cache smaller than the model it reads the file
     over and over (290 GB in 15 minutes on the 425M model, unfinished).

Prints the Áfra-style table as Markdown at the end: model, triangles, file size, conversion
time and peak memory and disk, and per PoE the frame time without and with shadows, the working
set and the error. Standard library only.

    cargo build --release -p oocfmt-cli
    python3 tools/bench-billion.py --tris 1e9 --dir /big/disk     # about 2 h on 2 cores
    python3 tools/bench-billion.py --model big.oocf --report big-report.json --runs 3
"""

import argparse
import json
import os
import subprocess
import sys
import time

from benchlib import BIN, ROOT, machine, require_binary, run

DROP = "sync && echo 3 > /proc/sys/vm/drop_caches"


def drop_caches():
    """Empties the page cache; False where this process may not."""
    cmd = ["sh", "-c", DROP] if os.geteuid() == 0 else ["sudo", "-n", "sh", "-c", DROP]
    return subprocess.run(cmd, capture_output=True).returncode == 0


def convert(a, model, report):
    """Step 1: the generator piped into the converter; returns the wall seconds."""
    gen = [BIN, "gen", "mandelbulb", "--tris", a.tris, "-o", "-", "--quiet"]
    conv = [BIN, "convert", "-", "--format", "obj", "--mem-limit", a.mem_limit, "--codec", "none",
            "-o", model, "--report-json", report, "--quiet"]
    print(f"$ {' '.join(gen[1:])} | {' '.join(conv[1:])}", flush=True)
    start = time.monotonic()
    g = subprocess.Popen(gen, stdout=subprocess.PIPE)
    c = subprocess.Popen(conv, stdin=g.stdout)
    if g.stdout:
        g.stdout.close()  # the converter holds the pipe's only reader
    c_rc, g_rc = c.wait(), g.wait()
    if c_rc != 0 or g_rc != 0:
        sys.exit(f"the conversion failed: gen exited {g_rc}, convert {c_rc}")
    return time.monotonic() - start


def verify(model):
    """Step 2: `verify --deep` from a cold page cache; returns (seconds, its summary line)."""
    cold = drop_caches()
    start = time.monotonic()
    out = run(["verify", "--deep", model])
    secs = time.monotonic() - start
    line = out.strip().splitlines()[-1] if out.strip() else ""
    print(f"verify --deep ({'cold' if cold else 'page cache not emptied'}): {secs:.1f} s: {line}", flush=True)
    return secs, line, cold


def walkthrough(a, model):
    """Step 3: tools/bench-cold.py over the three ways of reading; returns its JSON."""
    out = os.path.join(a.dir, "cold.json")
    cmd = [sys.executable, os.path.join(ROOT, "tools", "bench-cold.py"), "--model", model,
           "--configs", "buffered,direct,mmap", "--runs", str(a.runs), "--cache-mb", str(a.cache_mb),
           "--poe", a.walk_poe, "--frames", str(a.frames), "--hold", str(a.hold), "--per-frame",
           "--json", out, "--dir", a.dir]
    if a.memory_limit_mb:
        cmd += ["--memory-limit-mb", str(a.memory_limit_mb)]
    print("$ " + " ".join(cmd[1:]), flush=True)
    subprocess.run(cmd, check=True)
    with open(out) as f:
        return json.load(f)


def curve(a, model, shadows):
    """Step 4: `curve` at PoE 1, 2, 3 with the async cache; returns its JSON."""
    out = os.path.join(a.dir, f"curve-{'shadows' if shadows else 'headlight'}.json")
    args = ["curve", model, "--poe", "1,2,3", "--cache", "async", "--cache-mb", str(a.cache_mb),
            "--repeat", str(a.repeat), "--reference-spp", str(a.reference_spp),
            "--reference-mb", str(a.reference_mb), "--json", out]
    if shadows:
        args.append("--shadows")
    print("$ oocfmt " + " ".join(args), flush=True)
    start = time.monotonic()
    print(run(args), flush=True)
    print(f"({time.monotonic() - start:.0f} s)", flush=True)
    with open(out) as f:
        return json.load(f)


def shadowed(a, model):
    """Step 4 with shadows, without the error: `render --shadows` per PoE, warm; returns
    [(poe, ms, working set MiB)]."""
    rows = []
    for poe in ("1", "2", "3"):
        stats = os.path.join(a.dir, f"shadows-{poe}.json")
        args = ["render", model, "--shadows", "--poe", poe, "--cache-mb", str(a.shadow_cache_mb),
                "--repeat", "3", "-o", os.path.join(a.dir, f"shadows-{poe}.png"), "--stats-json", stats]
        print("$ oocfmt " + " ".join(args), flush=True)
        run(args)
        with open(stats) as f:
            s = json.load(f)
        rows.append((float(poe), s["ms"], s["cache"]["bytes_resident"] / 2**20))
    return rows


def afra_table(model, report, wall, checked, lit, shadows):
    """The table of Áfra's Tables 5 and 6, one row per PoE, as Markdown."""
    size = os.path.getsize(model)
    tris = report.get("triangles_stored", 0)
    print(f"\nmodel {os.path.basename(model)}: {tris:,} triangles, {size / 1e9:.2f} GB "
          f"({size / 2**30:.2f} GiB, --codec none); conversion {report['seconds'] / 60:.1f} min "
          f"({report['triangles_per_second']:,.0f} triangles/s"
          + (f"; {wall / 60:.1f} min with the generator" if wall == wall else "") + "), "
          f"peak memory {report['peak_memory_bytes'] / 2**20:,.0f} MiB (limit "
          f"{report['mem_limit_bytes'] / 2**30:.1f} GiB), peak disk {report['peak_disk_bytes'] / 2**30:.1f} GiB "
          f"({report['spill_bytes_per_triangle']:.1f} bytes a triangle); verify --deep {checked[0]:.0f} s")
    print("\n| PoE | frame | RMSE / SSIM | working set | frame with shadows | working set with shadows |")
    print("|--:|--:|--:|--:|--:|--:|")
    for r, (_, ms, ws) in zip(lit["rows"], shadows):
        e = r["error"]["model"]
        print(f"| {r['poe']:g} | {r['ms']:.1f} ms | {e['rmse']:.2f} / {e['ssim']:.4f} | "
              f"{r['working_set_mb']:.0f} MiB | {ms:.1f} ms | {ws:.0f} MiB |")
    fl = lit["floor"]["error"]["model"]
    print(f"aliasing floor: RMSE {fl['rmse']:.2f}, SSIM {fl['ssim']:.4f}; reference "
          f"{lit['reference']['spp']} rays per pixel, {lit['reference']['ms'] / 1e3:.1f} s cold")


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--tris", default="1e9", help="Mandelbulb triangles to generate without --model")
    p.add_argument("--model", help="an existing container converted with --codec none")
    p.add_argument("--report", help="with --model: its conversion's --report-json")
    p.add_argument("--mem-limit", default="4G")
    p.add_argument("--runs", type=int, default=3, help="cold and warm walkthrough runs per way of reading")
    p.add_argument("--frames", type=int, default=30)
    p.add_argument("--hold", type=int, default=5)
    p.add_argument("--walk-poe", default="1")
    p.add_argument("--memory-limit-mb", type=int,
                   help="walk in a memory group of this many MiB (process and page cache; "
                   "tools/bench-cold.py): a model smaller than the machine's RAM is then larger "
                   "than the renderer's memory")
    p.add_argument("--cache-mb", type=int, default=2048)
    p.add_argument("--repeat", type=int, default=3, help="curve: timed frames per PoE")
    p.add_argument("--reference-spp", type=int, default=16)
    p.add_argument("--reference-mb", type=int, default=8192)
    p.add_argument("--shadow-cache-mb", type=int, default=8192,
                   help="the async cache of the shadowed frames (a shadowed view wants several "
                   "times the blocks)")
    p.add_argument("--shadow-error", action="store_true",
                   help="also `curve --shadows`, for the shadowed frames' error (see above)")
    p.add_argument("--skip", default="", help="comma-separated steps to leave out: verify, walk, curve")
    p.add_argument("--dir", default=os.path.join(ROOT, "target", "bench-billion"))
    a = p.parse_args()
    require_binary()
    if (a.model is None) != (a.report is None):
        sys.exit("--model and --report go together")
    skip = {s.strip() for s in a.skip.split(",") if s.strip()}
    os.makedirs(a.dir, exist_ok=True)
    print(f"machine: {machine()}", flush=True)
    model, report_path, wall = a.model, a.report, float("nan")
    if model is None:
        n = int(float(a.tris))
        model = os.path.join(a.dir, f"mandelbulb-{n}.oocf")
        report_path = os.path.join(a.dir, f"mandelbulb-{n}-report.json")
        wall = convert(a, model, report_path)
    with open(report_path) as f:
        report = json.load(f)
    checked = verify(model) if "verify" not in skip else (float("nan"), "", False)
    if "walk" not in skip:
        walkthrough(a, model)
    if "curve" not in skip:
        lit = curve(a, model, False)
        shadows = shadowed(a, model)
        if a.shadow_error:
            curve(a, model, True)
        afra_table(model, report, wall, checked, lit, shadows)


if __name__ == "__main__":
    main()
