"""``realizer render`` with speech: the MP4 has the speech as AAC in sync; PNGs get a WAV."""

from __future__ import annotations

import shutil
import subprocess
import sys
import wave
from pathlib import Path

import numpy as np
import pytest

from tests.face.test_render_commands import opengl_or_skip

ROOT = Path(__file__).resolve().parents[2]
BML_NS = "http://www.bml-initiative.org/bml/bml-1.0"
#: The speech starts 0.5 s into the video.
BLOCK = (
    f'<bml xmlns="{BML_NS}" id="b"><speech id="s" start="0.5">'
    "<text>Peter bought my five vans.</text></speech></bml>"
)

pytestmark = pytest.mark.slow


def render(tmp_path: Path, output: Path) -> str:
    opengl_or_skip()
    source = tmp_path / "speech.xml"
    source.write_text(BLOCK)
    done = subprocess.run(
        [sys.executable, "-m", "realizer", "render", str(source), "-o", str(output),
         "--size", "64x64", "--fps", "20", "--quiet", "--no-idle"],
        cwd=ROOT, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    return done.stdout


def predicted_speech(feedback: str) -> tuple[float, float]:
    import re

    match = re.search(r'<speech id="b:s" start="([0-9.]+)" end="([0-9.]+)"', feedback)
    assert match, feedback
    return float(match.group(1)), float(match.group(2))


def sounding(samples: np.ndarray, rate: int) -> tuple[float, float]:
    """First and last 10 ms window with speech energy, seconds."""
    window = rate // 100
    frames = samples[: len(samples) // window * window].astype(np.float64).reshape(-1, window)
    loud = np.flatnonzero(np.sqrt((frames**2).mean(axis=1)) > 300)
    return loud[0] * window / rate, (loud[-1] + 1) * window / rate


@pytest.mark.skipif(shutil.which("ffmpeg") is None, reason="ffmpeg is not installed")
def test_a_rendered_mp4_has_the_speech_starting_and_ending_at_the_predicted_times(
    tmp_path: Path,
) -> None:
    output = tmp_path / "talk.mp4"
    start, end = predicted_speech(render(tmp_path, output))
    probe = subprocess.run(
        ["ffprobe", "-v", "error", "-show_entries", "stream=codec_type,codec_name",
         "-of", "csv=p=0", str(output)],
        capture_output=True, text=True, check=True,
    ).stdout  # fmt: skip
    assert "aac,audio" in probe and "h264,video" in probe
    raw = subprocess.run(
        ["ffmpeg", "-v", "error", "-i", str(output), "-f", "s16le", "-ac", "1", "-ar", "22050",
         "-"],
        capture_output=True, check=True,
    ).stdout  # fmt: skip
    samples = np.frombuffer(raw, dtype="<i2")
    first, last = sounding(samples, 22050)
    # sound begins when the speech starts (eSpeak NG opens with a few ms of
    # silence) and ends before its end (its trailing pause is silent)
    assert start <= first + 0.01 and first - start < 0.06
    assert last <= end + 0.01 and end - last < 0.45
    assert not np.abs(samples[: int(start * 22050) - 200].astype(int)).max() > 300


def test_a_png_folder_gets_a_wav_beside_it(tmp_path: Path) -> None:
    output = tmp_path / "frames"
    start, _ = predicted_speech(render(tmp_path, output))
    wav_path = tmp_path / "frames.wav"
    assert wav_path.is_file() and any(output.glob("*.png"))
    with wave.open(str(wav_path)) as wav:
        rate = wav.getframerate()
        samples = np.frombuffer(wav.readframes(wav.getnframes()), dtype="<i2")
        assert wav.getnchannels() == 1
    first, _ = sounding(samples, rate)
    assert abs(first - start) < 0.06
    frames = len(list(output.glob("*.png")))
    assert abs(len(samples) / rate - frames / 20) < 1e-3
