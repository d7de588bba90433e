"""A scene to gaze at: named targets with positions, shared by a server's characters.

BML 1.0 names gaze, gazeShift, pointing and headDirectionShift targets by
id and leaves the world to the realizer. The scene holds them:

* ``camera``: where the viewer's camera is, straight in front of the first
  character at eye height;
* ``user``: a person in front of the camera, a little below it;
* every character's eyes, under the character's id: characters stand side
  by side along x, each facing the camera (+z), so that they can look at
  each other;
* targets a client adds or moves while blocks run (``Scene.place``).

Positions are metres in one world frame: x to the characters' left as the
camera sees it (the viewer's right), y up, z from the characters towards
the camera; the first character's eyes are at the origin. A direction from
a character's eyes to a target is ``(yaw, pitch)`` degrees: yaw positive to
the character's left, pitch positive up (the signs of the face engine's
gaze, :mod:`realizer.engines.face`).

Sans-I/O and bounded: at most :attr:`SceneLimits.targets` targets, names
of at most :attr:`SceneLimits.name_length` characters, finite coordinates
within :attr:`SceneLimits.extent` metres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from realizer.errors import RealizerError


class SceneError(RealizerError):
    """A target the scene cannot take (a bad name or position, too many)."""

    warning_type = "NO_SUCH_TARGET"


@dataclass(frozen=True, slots=True)
class SceneLimits:
    targets: int = 256
    name_length: int = 64
    #: metres from the origin a coordinate may lie
    extent: float = 1000.0
    #: metres between neighbouring characters' eyes
    spacing: float = 0.7


#: The fixed targets: name -> position (metres).
DEFAULT_TARGETS: dict[str, tuple[float, float, float]] = {
    "camera": (0.0, 0.0, 1.2),
    "user": (0.0, -0.15, 1.5),
}


@dataclass(slots=True)
class Scene:
    """Named targets and the characters' eyes; see the module docstring."""

    limits: SceneLimits = field(default_factory=SceneLimits)
    targets: dict[str, tuple[float, float, float]] = field(
        default_factory=lambda: dict(DEFAULT_TARGETS)
    )
    characters: list[str] = field(default_factory=list)
    #: bumped on every change, so that users can tell a moved target
    version: int = 0

    def add_character(self, character_id: str) -> tuple[float, float, float]:
        """Place a character's eyes (next free place along x); returns them."""
        if character_id not in self.characters:
            self.characters.append(character_id)
            index = self.characters.index(character_id)
            # 0, +1, -1, +2, -2, ...: the first in the middle, the rest around it
            side = (index + 1) // 2 * (1 if index % 2 else -1)
            self._set(character_id, (side * self.limits.spacing, 0.0, 0.0))
        return self.targets[character_id]

    def place(self, name: str, position: tuple[float, float, float]) -> None:
        """Add or move a target. Raises :class:`SceneError` for a bad name or
        position, or when the scene holds :attr:`SceneLimits.targets`."""
        if not name or len(name) > self.limits.name_length or not name.isprintable():
            raise SceneError(f"target name {name[:80]!r} is empty, too long or not printable")
        if name in self.characters:
            raise SceneError(f"{name!r} names a character's eyes, which the scene places")
        if len(position) != 3 or not all(
            isinstance(v, int | float) and math.isfinite(v) and abs(v) <= self.limits.extent
            for v in position
        ):
            raise SceneError(
                f"target {name!r}: a position is three finite numbers within "
                f"{self.limits.extent:g} m"
            )
        if name not in self.targets and len(self.targets) >= self.limits.targets:
            raise SceneError(f"the scene holds {self.limits.targets} targets already")
        self._set(name, (float(position[0]), float(position[1]), float(position[2])))

    def _set(self, name: str, position: tuple[float, float, float]) -> None:
        self.targets[name] = position
        self.version += 1

    def direction(self, character_id: str, target: str) -> tuple[float, float] | None:
        """(yaw, pitch) degrees from the character's eyes to ``target``, or None
        when the scene has no such target (or the target is the character)."""
        position = self.targets.get(target)
        if position is None or target == character_id:
            return None
        eyes = self.targets.get(character_id) or self.add_character(character_id)
        dx, dy, dz = (p - e for p, e in zip(position, eyes, strict=True))
        horizontal = math.hypot(dx, dz)
        if horizontal < 1e-9 and abs(dy) < 1e-9:
            return None
        return math.degrees(math.atan2(dx, dz)), math.degrees(math.atan2(dy, horizontal))

    def snapshot(self) -> dict[str, object]:
        """The scene as JSON-able data (the viewer protocol's ``scene`` message)."""
        return {
            "version": self.version,
            "characters": list(self.characters),
            "targets": {name: list(position) for name, position in self.targets.items()},
        }
