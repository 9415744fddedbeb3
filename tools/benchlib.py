"""What the benchmark scripts in tools/ share: where the release binary is, running it, and a
line naming the machine the figures come from."""

import os
import platform
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.path.join(ROOT, "target", "release", "oocfmt")


def require_binary():
    if not os.path.exists(BIN):
        sys.exit(f"{BIN} missing: run `cargo build --release -p oocfmt-cli` first")


def run(args):
    """Runs `oocfmt ARGS`, exits with its output when it fails, returns its stdout."""
    r = subprocess.run([BIN] + args, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"oocfmt {' '.join(args)} failed ({r.returncode}):\n{r.stdout}{r.stderr}")
    return r.stdout


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
