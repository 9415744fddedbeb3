"""Fixtures of the browser tests: a small container, an `oocfmt view` server on it, and
headless Debian chromium driven by Playwright (no browser download: executable_path)."""

import os
import pathlib
import re
import signal
import subprocess

import pytest
from playwright.sync_api import sync_playwright

ROOT = pathlib.Path(__file__).resolve().parents[2]
OUT = ROOT / "target" / "browser"
CHROMIUM = os.environ.get("CHROMIUM", "/usr/bin/chromium")


def oocfmt_binary():
    given = os.environ.get("OOCFMT")
    if given:
        return given
    for profile in ("release", "debug"):
        path = ROOT / "target" / profile / "oocfmt"
        if path.exists():
            return str(path)
    raise RuntimeError("no oocfmt binary: build it (cargo build --release -p oocfmt-cli) or set OOCFMT")


@pytest.fixture(scope="session")
def oocfmt():
    return oocfmt_binary()


@pytest.fixture(scope="session")
def model(oocfmt):
    """A 30 000-triangle Mandelbulb, converted once per run."""
    OUT.mkdir(parents=True, exist_ok=True)
    obj, oocf = OUT / "mb.obj", OUT / "mb.oocf"
    subprocess.run([oocfmt, "gen", "mandelbulb", "--tris", "30000", "-o", str(obj), "--quiet"], check=True)
    subprocess.run([oocfmt, "convert", str(obj), "-o", str(oocf), "--quiet"], check=True)
    return oocf


@pytest.fixture(scope="session")
def server(oocfmt, model):
    """`oocfmt view` on the model: its URL (the first line it prints), stopped with Ctrl-C."""
    proc = subprocess.Popen(
        [oocfmt, "view", str(model), "--port", "0", "--spp", "4", "--poe", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    url = proc.stdout.readline().strip()
    assert re.fullmatch(r"http://127\.0\.0\.1:\d+/\?token=[0-9a-f]{32}", url), url
    yield url
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=20) == 0, proc.stderr.read()


@pytest.fixture(scope="session")
def cad_model(oocfmt):
    """A 20 000-triangle CAD assembly with parts, converted once per run."""
    OUT.mkdir(parents=True, exist_ok=True)
    obj, oocf = OUT / "cad.obj", OUT / "cad.oocf"
    subprocess.run([oocfmt, "gen", "cad", "--tris", "20000", "--parts", "40", "-o", str(obj), "--quiet"], check=True)
    subprocess.run([oocfmt, "convert", str(obj), "-o", str(oocf), "--quiet"], check=True)
    return oocf


@pytest.fixture(scope="session")
def cad_server(oocfmt, cad_model):
    """`oocfmt view` on the CAD model, as `server` is on the Mandelbulb."""
    proc = subprocess.Popen(
        [oocfmt, "view", str(cad_model), "--port", "0", "--spp", "2", "--poe", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    url = proc.stdout.readline().strip()
    assert re.fullmatch(r"http://127\.0\.0\.1:\d+/\?token=[0-9a-f]{32}", url), url
    yield url
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=20) == 0, proc.stderr.read()


@pytest.fixture(scope="session")
def browser():
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=["--no-sandbox"])
        yield b
        b.close()


@pytest.fixture()
def page(browser):
    context = browser.new_context(viewport={"width": 640, "height": 480}, device_scale_factor=1, accept_downloads=True)
    pg = context.new_page()
    errors = []
    pg.on("pageerror", lambda e: errors.append(str(e)))
    yield pg
    context.close()
    assert not errors, f"the page threw: {errors}"


@pytest.fixture()
def touch_page(browser):
    """A page in a context with a touch screen, as a tablet's: touch events go through CDP
    (`Input.dispatchTouchEvent`)."""
    context = browser.new_context(viewport={"width": 640, "height": 480}, device_scale_factor=1, has_touch=True)
    pg = context.new_page()
    errors = []
    pg.on("pageerror", lambda e: errors.append(str(e)))
    yield pg
    context.close()
    assert not errors, f"the page threw: {errors}"
