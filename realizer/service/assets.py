"""The face the service shows, and the sessions that animate it.

Every character is a :class:`realizer.session.Session` on one face (the
default face, or ``realizer serve --face PATH``); the service also needs
that face's deformer (for vertex frames) and its colours (for the browser
viewer). All are loaded once, at start-up.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from realizer.service.planner import PlanningRecipe
from realizer.service.server import FaceAssets
from realizer.session import Session


def load_face(path: str | Path | None = None) -> Any:
    """The face in the face parameter file at ``path``, or the default face."""
    if path is None:
        from realizer.face.default import load_default_face

        return load_default_face()
    from realizer.face.paramfile import load_face as load_face_file

    return load_face_file(path)


def srgb_colours(face: Any) -> np.ndarray:
    """(n, 3) uint8 sRGB vertex colours, as the offscreen renderer colours
    the parts (its colours are linear RGB in 0..1)."""
    from realizer.face.render import vertex_colours

    linear = np.clip(np.asarray(vertex_colours(face), dtype=np.float64), 0.0, 1.0)
    srgb = np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * np.power(linear, 1 / 2.4) - 0.055)
    return np.asarray(np.rint(srgb * 255), dtype=np.uint8)


def face_assets(face: Any) -> FaceAssets:
    """The face with the deformer and colours the service streams."""
    from realizer.face.deform import deform

    return FaceAssets(face=face, deform=deform, colours=srgb_colours(face))


class Sessions:
    """``character_id -> Session``, and how a planner process builds the same
    engines (``planning``; realizer.service.planner): a service whose
    session factory has one plans its blocks in planner processes."""

    def __init__(self, make: Callable[[str], Session], planning: PlanningRecipe) -> None:
        self._make = make
        self.planning = planning

    def __call__(self, character_id: str) -> Session:
        return self._make(character_id)


def sessions_from_settings(face: Any, settings: Any) -> Sessions:
    """:func:`session_factory` from a command's settings (``realizer serve``'s
    and ``realizer worker``'s: ``idle``, ``seed``, ``tts``, ``voice`` and
    ``piper_model``), so that both run the same sessions."""
    speech = {
        "tts": settings.tts,
        "voice": settings.voice or "",
        "model": settings.piper_model or "",
    }
    return session_factory(face, idle=settings.idle, seed=settings.seed, speech=speech)


def session_factory(
    face: Any, *, idle: bool = False, seed: int = 0, speech: dict[str, str] | None = None
) -> Sessions:
    """``character_id -> Session(character_id, face)``.

    With ``idle``, each character's face is kept alive between behaviours
    (realizer.face.idle: blinks, saccades, breathing, head motion), seeded by
    ``seed`` and the character's id, so a run is reproducible. ``speech``
    chooses the TTS: ``{"tts": "espeak" | "piper", "voice": ..., "model":
    ...}`` (docs/speech.md); one speech engine serves every character."""
    from realizer.session import Session

    registry_for: Any = None
    if speech:
        from realizer.engines import EngineRegistry
        from realizer.engines.face import FaceEngine
        from realizer.engines.speech import SpeechEngine

        options = {k: v for k, v in speech.items() if k != "tts" and v}
        engine = SpeechEngine.default(speech.get("tts") or "espeak", **options)

        def registry_for() -> Any:
            return EngineRegistry([FaceEngine.default(), engine])

    def make(character_id: str) -> Session:
        motion = None
        if idle:
            import zlib

            from realizer.face.idle import IdleMotion, IdleSettings

            own = zlib.crc32(character_id.encode("utf-8"))
            motion = IdleMotion(IdleSettings(seed=seed * 2**32 + own))
        registry = registry_for() if registry_for is not None else None
        session: Session = Session(character_id, face, idle=motion, registry=registry)
        return session

    # The face and idle motion are not planning's (frames are made here).
    recipe = PlanningRecipe(tuple(sorted(speech.items())) if speech else ())
    return Sessions(make, recipe)
