#!/usr/bin/env bash
# The browser tests of `oocfmt view` (tests/browser): pytest and Playwright driving Debian's
# chromium, headless. Installs what they need when it is missing: chromium (apt, as root), a
# Python venv under target/browser-venv with tests/browser/requirements.txt (Playwright's
# package only: it downloads no browser, the tests launch /usr/bin/chromium), and the release
# binary. Screenshots go to target/browser/.
#
#     bash tools/browser-tests.sh            # OOCFMT=path/to/oocfmt to test another binary
set -euo pipefail
cd "$(dirname "$0")/.."

if ! command -v chromium >/dev/null 2>&1; then
    echo "browser tests: installing chromium"
    sudo=""
    [ "$(id -u)" = 0 ] || sudo="sudo"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq chromium >/dev/null
fi

venv=target/browser-venv
stamp="$venv/.requirements"
if ! cmp -s tests/browser/requirements.txt "$stamp" 2>/dev/null; then
    echo "browser tests: making $venv"
    rm -rf "$venv"
    python3 -m venv "$venv"
    "$venv/bin/pip" install -q --disable-pip-version-check -r tests/browser/requirements.txt
    cp tests/browser/requirements.txt "$stamp"
fi

bin="${OOCFMT:-target/release/oocfmt}"
if [ -z "${OOCFMT:-}" ]; then
    cargo build --release --locked -q -p oocfmt-cli
fi
OOCFMT="$(realpath "$bin")" CHROMIUM="$(command -v chromium)" \
    "$venv/bin/pytest" -q -p no:cacheprovider tests/browser
