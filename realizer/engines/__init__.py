"""Engines: behaviour -> timing model -> realization, and the registry of them.

This layer sits above the scheduler (docs/architecture.md): the scheduler
knows timing models and the solver; the engines know behaviours.

* :class:`EngineRegistry`, :class:`Engine` -- :mod:`realizer.engines.registry`
* :class:`DefaultEngine` -- :mod:`realizer.engines.default` (behaviours
  nothing draws)
* :class:`~realizer.engines.face.FaceEngine` -- face, head, gaze, emotion
  (imported from its module; it loads the face data)
* :class:`~realizer.engines.speech.SpeechEngine` -- speech timing from a TTS
  and lip sync
"""

from __future__ import annotations

from realizer.engines.default import DefaultEngine
from realizer.engines.registry import Engine, EngineRegistry

__all__ = ["DefaultEngine", "Engine", "EngineRegistry"]
