#!/usr/bin/env python3
"""`oocfmt view` as a person uses it, measured in headless chromium: an orbit drag of
--seconds (a mouse move every 16 ms), then the mouse released; cold (a fresh server) and warm
(the same drag again). Prints per phase: the frames shown per second while moving, the median
and 95th-percentile frame time (render and cache step) against the target, the resolution and
PoE the schedule took, the median encode time and bytes per frame, the camera-to-frame latency
(a camera sent to the first frame showing it, on the page's clock), and the time from the
drag's last camera to the final frame of the still view.

    cargo build --release -p oocfmt-cli
    target/browser-venv/bin/python tools/bench-view.py --model bulb.oocf --size 1024x768

Needs the browser tests' venv (tools/browser-tests.sh makes it) and /usr/bin/chromium.
"""

import argparse
import os
import pathlib
import signal
import statistics
import subprocess
import time

from playwright.sync_api import sync_playwright

ROOT = pathlib.Path(__file__).resolve().parents[1]


def pct(values, q):
    v = sorted(values)
    return v[min(len(v) - 1, int(q * len(v)))] if v else float("nan")


def drag(page, seconds):
    box = page.locator("#frame").bounding_box()
    x0, y0 = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    page.mouse.move(x0, y0)
    page.mouse.down()
    start = time.monotonic()
    i = 0
    while time.monotonic() - start < seconds:
        i += 1
        page.mouse.move(x0 + 3 * (i % 200) - 300, y0 + 40 * ((i // 200) % 2))
        time.sleep(0.016)
    page.mouse.up()


def phase(page, name, seconds, target):
    n0 = len(page.evaluate("() => window.oocfmt.history"))
    t0 = page.evaluate("() => performance.now()")
    drag(page, seconds)
    page.wait_for_function(
        "() => { const l = window.oocfmt.last; return l && l.figures.last; }", timeout=600_000
    )
    page.wait_for_timeout(300)
    hist = page.evaluate("() => window.oocfmt.history")[n0:]
    stop = page.evaluate("() => window.oocfmt.lastSentMs")
    moving = [h for h in hist if h["header"]["figures"]["stage"] == "moving" and h["at"] <= stop + 1]
    final = [h for h in hist if h["header"]["figures"]["last"]]
    f = [h["header"]["figures"] for h in moving]
    span = (stop - t0) / 1000
    lat = [h["latency"] for h in moving if h["latency"] is not None]
    print(f"{name}: {len(moving)} moving frames in {span:.1f} s ({len(moving) / max(span, 1e-9):.1f} shown/s)")
    print(
        f"  frame ms median {statistics.median([x['ms'] for x in f]):.1f}, p95 {pct([x['ms'] for x in f], 0.95):.1f} "
        f"(target {target}); resolution median {statistics.median([x['width'] for x in f]):.0f}x"
        f"{statistics.median([x['height'] for x in f]):.0f}; PoE {sorted({x['poe'] for x in f})}"
    )
    enc = [h["header"]["encode_ms"] for h in moving]
    size = [h["header"]["bytes"] for h in moving]
    print(
        f"  JPEG encode ms median {statistics.median(enc):.2f}, p95 {pct(enc, 0.95):.2f}; bytes median {statistics.median(size):.0f}; "
        f"dropped {sum(h['header']['dropped'] for h in moving)}"
    )
    if lat:
        print(f"  camera-to-frame latency median {statistics.median(lat):.0f} ms, p95 {pct(lat, 0.95):.0f} ms")
    full = [
        h
        for h in hist
        if final
        and h["at"] > stop
        and h["header"]["figures"]["blocks_missed"] == 0
        and h["header"]["figures"]["stage"] in ("settle", "accumulate", "done")
        and h["header"]["figures"]["width"] == final[-1]["header"]["figures"]["width"]
    ]
    if full:
        f0 = full[0]["header"]["figures"]
        print(
            f"  stop to the first full-size frame missing no block {full[0]['at'] - stop:.0f} ms "
            f"(PoE {f0['poe']}, stage {f0['stage']}, {full[0]['header']['bytes']} bytes)"
        )
    if final:
        last = final[-1]
        h = last["header"]
        print(
            f"  stop to final frame {last['at'] - stop:.0f} ms; final {h['figures']['width']}x{h['figures']['height']} "
            f"{h['format']} {h['bytes']} bytes, encode {h['encode_ms']:.1f} ms, {h['figures']['samples']} samples, "
            f"complete {h['figures']['complete']}"
        )


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", required=True)
    ap.add_argument("--binary", default=str(ROOT / "target" / "release" / "oocfmt"))
    ap.add_argument("--size", default="1024x768", help="the view's canvas, CSS pixels at scale 1")
    ap.add_argument("--seconds", type=float, default=6.0)
    ap.add_argument("--target-ms", type=float, default=66.0)
    ap.add_argument("--view-args", default="", help="more flags for oocfmt view, e.g. '--poe 0 --spp 4'")
    ap.add_argument(
        "--drop-caches", action="store_true", help="empty the page cache first (root, or sudo -n), so cold reads the disk"
    )
    a = ap.parse_args()
    if a.drop_caches:
        drop = "sync && echo 3 > /proc/sys/vm/drop_caches"
        cmd = ["sh", "-c", drop] if os.geteuid() == 0 else ["sudo", "-n", "sh", "-c", drop]
        subprocess.run(cmd, check=True)
        print("page cache dropped")
    w, h = (int(v) for v in a.size.lower().split("x"))
    cmd = [a.binary, "view", a.model, "--port", "0", "--target-ms", str(a.target_ms)] + a.view_args.split()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    url = proc.stdout.readline().strip()
    try:
        with sync_playwright() as p:
            b = p.chromium.launch(executable_path="/usr/bin/chromium", headless=True, args=["--no-sandbox"])
            # The bar and the status line take about 90 pixels.
            page = b.new_page(viewport={"width": w, "height": h + 90}, device_scale_factor=1)
            start = time.monotonic()
            page.goto(url)
            page.wait_for_function(
                "() => { const l = window.oocfmt && window.oocfmt.last; return l && l.figures.last; }", timeout=600_000
            )
            print(f"first still view: {time.monotonic() - start:.2f} s from opening the page")
            phase(page, "cold", a.seconds, a.target_ms)
            phase(page, "warm", a.seconds, a.target_ms)
            b.close()
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=30)


if __name__ == "__main__":
    main()
