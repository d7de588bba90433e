"""``realizer say``: the real eSpeak NG speaks a text to a WAV and prints its timing."""

from __future__ import annotations

import subprocess
import sys
import wave
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def say(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "realizer", "say", *args],
        cwd=ROOT, capture_output=True, text=True, timeout=60,
    )  # fmt: skip


def test_say_writes_a_wav_and_prints_words_markers_and_phonemes(tmp_path: Path) -> None:
    out = tmp_path / "hello.wav"
    done = say('Hello <sync id="m"/>world.', "-o", str(out))
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0].startswith("voice en (espeak)")
    marker = next(line for line in lines if line.strip().endswith(" m"))
    world = next(line for line in lines if line.strip().endswith("world"))
    assert float(marker.split()[0]) == float(world.split()[0])  # heard at "world"
    assert any(line.split()[2:] == ["h", "0"] for line in lines if len(line.split()) == 4)
    with wave.open(str(out)) as wav:
        assert wav.getframerate() == 22050 and wav.getnframes() > 10000


def test_say_in_german_and_an_unknown_language_warns() -> None:
    german = say("Guten Tag", "--lang", "de")
    assert german.returncode == 0 and german.stdout.startswith("voice de")
    unknown = say("Hello", "--lang", "tlh")
    assert unknown.returncode == 0 and unknown.stdout.startswith("voice en")
    assert "no voice for 'tlh'" in unknown.stderr
