"""Speech: timing from a text-to-speech backend, and lip sync.

* :class:`SpeechEngine` -- :mod:`realizer.engines.speech.engine`
* :class:`SpeechPlan`, :class:`SpeechTiming`, :class:`RateSpeechTiming` --
  :mod:`realizer.engines.speech.timing`
"""

from __future__ import annotations

from realizer.engines.speech.engine import SpeechEngine
from realizer.engines.speech.timing import RateSpeechTiming, SpeechPlan, SpeechTiming, syllables

__all__ = ["RateSpeechTiming", "SpeechEngine", "SpeechPlan", "SpeechTiming", "syllables"]
