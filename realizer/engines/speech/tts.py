"""The text-to-speech protocol: text and markers in; audio, phonemes, words, marker times out.

The MPEG-4 TTS interface (Tekalp and Ostermann 2000, section 2.1) has the
synthesiser hand phonemes with their start times and durations, and
bookmarks, to a phoneme/bookmark-to-FAP converter. A :class:`TtsBackend`
does the same for one ``<speech>`` (BML 1.0 ``<text>`` with ``<sync id>``
markers): :meth:`TtsBackend.synthesize` returns a :class:`Synthesis` whose
times are all seconds on the audio's own clock (sample ``n`` is at
``n / sample_rate``).

Backends: :mod:`realizer.engines.speech.espeak` (eSpeak NG through its C
library, the default) and :mod:`realizer.engines.speech.piper` (Piper, run as
a separate program). :func:`load_backend` picks one by name.

A backend is called from any thread (the service plans blocks off its event
loop); each backend serialises its own calls where its library needs it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Protocol
from xml.sax.saxutils import escape, quoteattr

import numpy as np
import numpy.typing as npt

from realizer.bml_parser import SpeechText, TextSync
from realizer.engines.speech.timing import SpeechPlan
from realizer.errors import RealizerError


class TtsError(RealizerError):
    """A synthesiser that is missing, or failed on a text."""


@dataclass(frozen=True, slots=True)
class Phoneme:
    """One phoneme (IPA, as eSpeak NG writes it) from ``start`` to ``end`` seconds.

    The symbol "" is a pause.
    """

    symbol: str
    start: float
    end: float


@dataclass(frozen=True, slots=True)
class Synthesis:
    """What a backend made of one text; every time in seconds of its audio."""

    audio: npt.NDArray[np.int16]  # (n,) mono PCM
    sample_rate: int  # Hz
    phonemes: tuple[Phoneme, ...]
    words: tuple[tuple[str, float, float], ...]  # (word, start, end)
    markers: Mapping[str, float]  # <sync id> -> time it is spoken
    voice: str = ""
    backend: str = ""
    #: wall-clock seconds from the call to the first audio chunk (for the benchmark)
    first_audio: float = field(default=0.0, compare=False)

    @property
    def duration(self) -> float:
        return len(self.audio) / self.sample_rate

    def plan(self) -> SpeechPlan:
        """The scheduler's view: the speech lasts as long as its audio."""
        return SpeechPlan(
            duration=self.duration,
            markers=dict(self.markers),
            words=self.words,
            phonemes=tuple((p.symbol, p.start, p.end) for p in self.phonemes),
        )


class TtsBackend(Protocol):
    """A synthesiser. ``language`` is a BML ``xml:lang`` tag or None for the default voice."""

    @property
    def name(self) -> str: ...

    def has_language(self, language: str) -> bool:
        """True if a voice for this language (BCP 47 tag, any case) is installed."""
        ...

    def synthesize(self, text: SpeechText, language: str | None = None) -> Synthesis:
        """Synthesise the text; raises :class:`TtsError` when it cannot."""
        ...


def ssml(text: SpeechText) -> tuple[str, list[tuple[int, int]]]:
    """The text as SSML with a ``<mark name>`` per ``<sync id>``.

    Returns the document and, for each run of words, its (start, end)
    character offsets in the document, so that a backend's word positions
    can be mapped back to words.
    """
    parts = ["<speak>"]
    offset = len(parts[0])
    spans: list[tuple[int, int]] = []
    for run in text.runs:
        if isinstance(run, TextSync):
            piece = f"<mark name={quoteattr(run.id)}/>"
        else:
            piece = escape(run)
            spans.append((offset, offset + len(piece)))
        parts.append(piece)
        offset += len(piece)
    parts.append("</speak>")
    return "".join(parts), spans


def segments(text: SpeechText) -> list[tuple[str | None, str]]:
    """The text cut at its markers: ``(marker before the words or None, words)``."""
    out: list[tuple[str | None, str]] = [(None, "")]
    for run in text.runs:
        if isinstance(run, TextSync):
            out.append((run.id, ""))
        else:
            marker, words = out[-1]
            out[-1] = (marker, words + run)
    return out


def load_backend(name: str = "espeak", **options: str) -> TtsBackend:
    """The backend called ``name`` ("espeak" or "piper").

    Raises :class:`TtsError` if it is not available.
    """
    if name == "espeak":
        from realizer.engines.speech.espeak import EspeakBackend

        rate = int(options.get("rate") or 175)
        backend: TtsBackend = EspeakBackend.load(voice=options.get("voice") or None, rate=rate)
        return backend
    if name == "piper":
        from realizer.engines.speech.piper import PiperBackend

        model = options.get("model")
        if not model:
            raise TtsError("the piper backend needs a voice model (--piper-model PATH.onnx)")
        return PiperBackend(model)
    raise TtsError(f"unknown TTS backend {name!r} (known: espeak, piper)")
