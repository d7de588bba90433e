"""Speech: timing from a text-to-speech backend, audio, and lip sync.

* :class:`SpeechEngine`, :class:`SpeechLimits`, :class:`AudioClip`,
  :class:`SpeechRealization` -- :mod:`realizer.engines.speech.engine`
* :class:`TtsBackend`, :class:`Synthesis`, :func:`load_backend` --
  :mod:`realizer.engines.speech.tts`; backends in
  :mod:`realizer.engines.speech.espeak` and :mod:`realizer.engines.speech.piper`
* lip sync -- :mod:`realizer.engines.speech.lipsync`
* the syllable estimate (fallback) -- :mod:`realizer.engines.speech.timing`
"""

from __future__ import annotations

from realizer.engines.speech.engine import (
    AudioClip,
    SpeechEngine,
    SpeechLimits,
    SpeechRealization,
)
from realizer.engines.speech.timing import RateSpeechTiming, SpeechPlan, SpeechTiming, syllables
from realizer.engines.speech.tts import Synthesis, TtsBackend, TtsError, load_backend

__all__ = [
    "AudioClip",
    "RateSpeechTiming",
    "SpeechEngine",
    "SpeechLimits",
    "SpeechPlan",
    "SpeechRealization",
    "SpeechTiming",
    "Synthesis",
    "TtsBackend",
    "TtsError",
    "load_backend",
    "syllables",
]
