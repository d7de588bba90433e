"""A deterministic speech timing model, replaceable by a real text-to-speech engine.

Without a synthesiser the realizer still needs the time of every word, and so
of every ``<sync>`` marker in a speech's ``<text>``. :class:`RateSpeechTiming`
gives each word a duration from its length at a configurable speaking rate
(syllables per second, estimated from vowel groups) and a pause after
punctuation. A real TTS engine implements the same :class:`SpeechTiming`
protocol and returns marker times from its own phoneme timings (the MPEG-4
TTS interface of Tekalp and Ostermann 2000 returns bookmarks and phonemes the same way).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Protocol

from realizer.bml_parser import SpeechText, TextSync

_WORD_RE = re.compile(r"\S+")
_VOWEL_GROUPS = re.compile(r"[aeiouyàáâäèéêëìíîïòóôöùúûü]+", re.I)


@dataclass(frozen=True, slots=True)
class SpeechPlan:
    """Times in seconds after the speech starts.

    ``markers`` maps each ``<sync id>`` to its time; ``words`` lists
    ``(word, start, end)``; ``phonemes`` (optional, from a real TTS) lists
    ``(phoneme, start, end)`` for lip sync.
    """

    duration: float
    markers: dict[str, float]
    words: tuple[tuple[str, float, float], ...] = ()
    phonemes: tuple[tuple[str, float, float], ...] = field(default=())


class SpeechTiming(Protocol):
    def plan(self, text: SpeechText) -> SpeechPlan: ...


def syllables(word: str) -> int:
    """A rough syllable count: vowel groups, at least one per word."""
    return max(1, len(_VOWEL_GROUPS.findall(word)))


@dataclass(frozen=True, slots=True)
class RateSpeechTiming:
    """Word times from a speaking rate; deterministic for a given text."""

    syllables_per_second: float = 4.5
    comma_pause: float = 0.15  # seconds after , ; :
    stop_pause: float = 0.3  # seconds after . ! ?

    def word_duration(self, word: str) -> float:
        duration = syllables(word) / self.syllables_per_second
        if word[-1] in ",;:":
            duration += self.comma_pause
        elif word[-1] in ".!?":
            duration += self.stop_pause
        return duration

    def plan(self, text: SpeechText) -> SpeechPlan:
        now = 0.0
        markers: dict[str, float] = {}
        words: list[tuple[str, float, float]] = []
        for run in text.runs:
            if isinstance(run, TextSync):
                markers[run.id] = now
                continue
            for match in _WORD_RE.finditer(run):
                word = match.group()
                end = now + self.word_duration(word)
                words.append((word, now, end))
                now = end
        return SpeechPlan(duration=now, markers=markers, words=tuple(words))
