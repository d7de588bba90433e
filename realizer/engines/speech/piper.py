"""Piper (natural-sounding neural TTS), run as a separate program.

Piper (PyPI ``piper-tts``) is GPL-licensed, so this MIT package never
imports it: every synthesis runs ``python -m piper`` (or the ``piper``
program) in a subprocess with the voice model the user points to
(``--piper-model PATH.onnx``; the model's ``.onnx.json`` config sits beside
it). Get a voice with ``python -m piper.download_voices en_US-lessac-medium``
(docs/speech.md).

Timing. The text is synthesised one marker-to-marker segment at a time, so
each ``<sync>`` marker falls exactly on the boundary between two segments'
audio. Within a segment, the phonemes are those eSpeak NG gives for it
(Piper phonemizes with eSpeak NG, with the voice its config names), their
durations scaled to the length of Piper's audio for that segment: an
estimate of the alignment, exact at the markers and at the ends.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
import wave
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from realizer.bml_parser import SpeechText, parse_bml
from realizer.engines.speech.tts import Phoneme, Synthesis, TtsError, segments

#: Seconds one Piper process may take for one segment.
TIMEOUT_S = 60.0


def piper_command() -> list[str] | None:
    """How to run Piper here, or None when it is not installed."""
    program = shutil.which("piper")
    if program:
        return [program]
    import importlib.util

    if importlib.util.find_spec("piper") is not None:  # finds it without importing it
        return [sys.executable, "-m", "piper"]
    return None


@dataclass(slots=True)
class PiperBackend:
    """Piper with one voice model (``.onnx``, its ``.onnx.json`` beside it)."""

    model: str
    name: str = "piper"

    def __post_init__(self) -> None:
        path = Path(self.model)
        if not path.is_file():
            raise TtsError(f"no Piper voice model at {self.model!r}")
        if piper_command() is None:
            raise TtsError("Piper is not installed (pip install 'realizer[piper]')")

    def config(self) -> dict[str, object]:
        path = Path(self.model + ".json")
        if not path.is_file():
            path = Path(self.model).with_suffix(".json")
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return {}
        return data if isinstance(data, dict) else {}

    def language(self) -> str:
        language = self.config().get("language")
        code = language.get("code", "") if isinstance(language, dict) else ""
        return str(code).replace("_", "-").lower()

    def has_language(self, language: str) -> bool:
        mine = self.language()
        tag = language.strip().lower().replace("_", "-")
        return bool(mine) and (tag == mine or tag.partition("-")[0] == mine.partition("-")[0])

    def _espeak_voice(self) -> str:
        espeak = self.config().get("espeak")
        voice = espeak.get("voice", "") if isinstance(espeak, dict) else ""
        return str(voice) or "en"

    def _run(self, text: str, out: Path) -> tuple[np.ndarray, int]:
        command = piper_command()
        assert command is not None
        try:
            subprocess.run(
                [*command, "-m", self.model, "-f", str(out), "--", text],
                check=True,
                capture_output=True,
                timeout=TIMEOUT_S,
            )
            with wave.open(str(out), "rb") as wav:
                rate = wav.getframerate()
                audio = np.frombuffer(wav.readframes(wav.getnframes()), dtype="<i2")
        except (OSError, subprocess.SubprocessError, wave.Error) as exc:
            raise TtsError(f"Piper failed: {exc}") from None
        return audio.astype(np.int16), rate

    def synthesize(self, text: SpeechText, language: str | None = None) -> Synthesis:
        from realizer.engines.speech.espeak import EspeakBackend

        phonemizer = EspeakBackend.load(voice=self._espeak_voice())
        pieces: list[np.ndarray] = []
        phonemes: list[Phoneme] = []
        words: list[tuple[str, float, float]] = []
        markers: dict[str, float] = {}
        rate = 22050
        now = 0.0
        with tempfile.TemporaryDirectory(prefix="realizer-piper-") as folder:
            for index, (marker, words_text) in enumerate(segments(text)):
                if marker is not None:
                    markers[marker] = now
                if not words_text.strip():
                    continue
                audio, rate = self._run(words_text, Path(folder) / f"{index}.wav")
                length = len(audio) / rate
                guide = phonemizer.synthesize(_plain(words_text))
                scale = length / guide.duration if guide.duration > 0 else 1.0
                phonemes += [Phoneme(p.symbol, now + p.start * scale, now + p.end * scale)
                             for p in guide.phonemes]  # fmt: skip
                words += [(w, now + s * scale, now + e * scale) for w, s, e in guide.words]
                pieces.append(audio)
                now += length
        audio = np.concatenate(pieces) if pieces else np.zeros(0, dtype=np.int16)
        return Synthesis(audio, rate, tuple(phonemes), tuple(words), markers,
                         voice=Path(self.model).stem, backend="piper")  # fmt: skip


def _plain(words: str) -> SpeechText:
    from xml.sax.saxutils import escape

    block = parse_bml(
        '<bml xmlns="http://www.bml-initiative.org/bml/bml-1.0" id="p">'
        f'<speech id="s"><text>{escape(words)}</text></speech></bml>'
    ).block
    speech = block.behaviours[0].speech
    assert speech is not None
    return speech
