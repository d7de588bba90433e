"""Realizer control of running behaviours: AsapRealizer's BMLA parameter value changes.

A ``<bmla:parametervaluechange target="block:behaviour" paramId>`` moves one
parameter of a running behaviour along a linear trajectory from its
``start`` to its ``end`` (AsapRealizer's BMLA extension;
protocols/bml-extensions.md); after ``end`` the target value holds. Two
parameters can change:

* ``amount`` of an animated behaviour (face, head, gaze): its FAP values are
  scaled by ``value / own amount`` (the behaviour's own ``amount``, 1 when it
  gives none), weights untouched: :class:`ScaledAnimation`;
* ``volume`` of a speech: its audio samples are scaled by the value (1 is as
  synthesised): :func:`scaled_clip`.

Sans-I/O and pure: the session calls these with the times it solved.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from realizer.face.animation import Animation, DerivedAnimation, FloatArray

#: The parameters a parameter value change may move.
CHANGEABLE = ("amount", "volume")


@dataclass(frozen=True, slots=True)
class Ramp:
    """A value from ``initial`` at ``start`` to ``target`` at ``end`` (seconds), held after."""

    start: float
    end: float
    initial: float
    target: float

    def at(self, now: float) -> float:
        if now <= self.start:
            return self.initial
        if now >= self.end or self.end <= self.start:
            return self.target
        share = (now - self.start) / (self.end - self.start)
        return self.initial + share * (self.target - self.initial)


@dataclass(frozen=True, slots=True, eq=False)
class ScaledAnimation(DerivedAnimation):
    """An animation whose FAP values are multiplied by ``ramp`` (over time).

    Before the ramp starts it is the animation itself (factor ``ramp.initial``
    is 1 when the change starts from the behaviour's own amount).
    """

    base: Animation
    ramp: Ramp

    def evaluate(self, now: float) -> tuple[FloatArray, FloatArray]:
        values, weights = self.base.evaluate(now)
        return np.asarray(values, dtype=np.float64) * self.ramp.at(now), weights


def scaled_clip(clip: Any, ramp: Ramp) -> Any:
    """A copy of an audio clip (``start``, ``samples`` int16, ``sample_rate``)
    with each sample scaled by ``ramp`` at its time, clipped to int16."""
    samples = np.asarray(clip.samples, dtype=np.float64)
    times = clip.start + np.arange(len(samples)) / clip.sample_rate
    if ramp.end > ramp.start:
        share = np.clip((times - ramp.start) / (ramp.end - ramp.start), 0.0, 1.0)
    else:
        share = (times >= ramp.start).astype(np.float64)
    gain = ramp.initial + share * (ramp.target - ramp.initial)
    scaled = np.clip(np.rint(samples * gain), -32768, 32767).astype(np.int16)
    return type(clip)(clip.start, scaled, clip.sample_rate, clip.behaviour_id)


@dataclass(frozen=True, slots=True, eq=False)
class Window(DerivedAnimation):
    """An animation shown only from ``from_time`` (seconds): a gaze re-aimed at a
    target that moved takes over from the old one at that moment (a saccade)."""

    base: Animation
    from_time: float

    @property
    def start(self) -> float:
        return max(float(self.base.start), self.from_time)
