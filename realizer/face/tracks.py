"""FAP tracks: envelopes, time curves, animations and the mixer that combines them.

Every face, head and gaze behaviour becomes an animation over FAPs 3..68
(``docs/interfaces.md``: ``Animation.evaluate(now) -> (values, weights)``).

Envelopes follow a behaviour's scheduled sync points ``start``,
``attackPeak``, ``relax``, ``end``: attack (0 -> 1), sustain (1), release
(1 -> 0). The curve of attack and release is one of the three time curves of
MPEG-4 bookmarks (Tekalp and Ostermann 2000, section 2.3, figure 14):

- ``linear``: the level moves at constant speed;
- ``hermite``: cubic Hermite with zero end slopes, ``3u^2 - 2u^3``, which
  starts and stops smoothly;
- ``triangular``: linear up to the target and straight back down: the level
  rises from ``start`` to a peak at ``attackPeak`` and falls to 0 at ``end``,
  with no sustain (``relax`` is not used).

Combining (the mixer). Paul 2010, section 7.4 lets the last controller that
sets a FAP overwrite it. Here overlapping animations combine per FAP:

1. animations are applied in order of ``priority`` (low first), then start
   time, then the order given;
2. an ``add`` animation adds ``weight * value`` to what is below it, so a
   FACS refinement adds to an emotion, and two lexemes on the same brow add
   up;
3. a ``replace`` animation cross-fades what is below it to its own value by
   its weight, ``(1 - w) * below + w * value``, on its own FAPs only;
4. the sum is clamped to each FAP's range (:class:`FapLimits`), so stacked
   movements never leave what the face can show.

A FAP is set in the result where any animation has a weight above 0.
"""

from __future__ import annotations

import bisect
import operator
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from itertools import pairwise
from typing import Literal

import numpy as np
import numpy.typing as npt

from realizer.face.animation import Animation, DerivedAnimation
from realizer.face.convert.config import FAP_COUNT, FapConfiguration
from realizer.face.convert.errors import ConversionError

CurveKind = Literal["linear", "hermite", "triangular"]
Blend = Literal["add", "replace"]
CURVES: tuple[CurveKind, ...] = ("linear", "hermite", "triangular")
BLENDS: tuple[Blend, ...] = ("add", "replace")

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

#: Durations shorter than this (seconds) are treated as instantaneous.
TIME_EPSILON_S = 1e-9


def check_curve(kind: str) -> CurveKind:
    """Return ``kind`` as a curve name or raise ConversionError."""
    for curve in CURVES:
        if kind == curve:
            return curve
    raise ConversionError(f"unknown curve {kind!r}; use one of {', '.join(CURVES)}")


def ease(kind: CurveKind, u: npt.ArrayLike) -> FloatArray:
    """A transition from 0 to 1 as ``u`` goes from 0 to 1 (clipped), shaped by ``kind``.

    ``triangular`` transitions are linear (the triangle is an envelope shape).
    """
    x = np.clip(np.asarray(u, dtype=np.float64), 0.0, 1.0)
    if kind == "hermite":
        return x * x * (3.0 - 2.0 * x)
    return x


def bookmark_curve(kind: CurveKind, u: npt.ArrayLike) -> FloatArray:
    """The MPEG-4 bookmark time curve over its duration ``u`` in 0..1.

    Tekalp and Ostermann 2000, section 2.3: the fraction of the way from the
    current amplitude to the bookmark's.

    ``linear`` and ``hermite`` reach the target at ``u = 1`` and stay there;
    ``triangular`` reaches it at ``u = 0.5`` and is back at the start at ``u = 1``.
    """
    x = np.clip(np.asarray(u, dtype=np.float64), 0.0, 1.0)
    if kind == "triangular":
        return 1.0 - np.abs(2.0 * x - 1.0)
    return ease(kind, x)


def _ramp(t: FloatArray, t0: float, t1: float) -> FloatArray:
    """0 before ``t0``, 1 after ``t1``, linear between (a step where t1 <= t0)."""
    if t0 == np.inf:  # a phase that never comes (a held behaviour's release)
        return np.zeros_like(t)
    if t1 - t0 <= TIME_EPSILON_S:
        return (t >= t0).astype(np.float64)
    return np.clip((t - t0) / (t1 - t0), 0.0, 1.0)


@dataclass(frozen=True, slots=True)
class Envelope:
    """The level (0..1) of a behaviour over time, from its sync times (seconds).

    ``start <= attack_peak <= relax <= end`` is required; ``end`` may be
    ``math.inf`` for a behaviour that holds (e.g. ``faceShift``).
    """

    start: float
    attack_peak: float
    relax: float
    end: float
    curve: CurveKind = "linear"

    def __post_init__(self) -> None:
        times = (self.start, self.attack_peak, self.relax, self.end)
        if any(b < a - TIME_EPSILON_S for a, b in pairwise(times)):
            raise ConversionError(
                "envelope sync times must be in order start <= attackPeak <= relax <= end, "
                f"got {times}"
            )
        check_curve(self.curve)

    @classmethod
    def from_syncs(cls, times: Mapping[str, float], curve: CurveKind = "linear") -> Envelope:
        """From sync name -> seconds; a missing attackPeak is the start, a
        missing relax the end (BML 1.0 face behaviours)."""
        start = times["start"]
        end = times.get("end", start)
        attack_peak = times.get("attackPeak", start)
        relax = times.get("relax", end)
        return cls(start, attack_peak, relax, end, curve)

    def level_at(self, now: float) -> float:
        """The envelope at one time ``now`` (seconds); the scalar path of :meth:`level`."""
        if not self.start <= now <= self.end:
            return 0.0
        if self.attack_peak <= now <= self.relax and self.curve != "triangular":
            return 1.0
        return float(self.level(now))

    def level(self, t: npt.ArrayLike) -> FloatArray:
        """The envelope at times ``t`` (seconds; scalar or array)."""
        x = np.asarray(t, dtype=np.float64)
        inside = (x >= self.start) & (x <= self.end)
        if self.curve == "triangular":
            rise = _ramp(x, self.start, self.attack_peak)
            fall = 1.0 - _ramp(x, self.attack_peak, self.end)
            shape = np.where(x <= self.attack_peak, rise, fall)
        else:
            attack = ease(self.curve, _ramp(x, self.start, self.attack_peak))
            release = 1.0 - ease(self.curve, _ramp(x, self.relax, self.end))
            shape = np.minimum(attack, release)
        return np.where(inside, shape, 0.0)


@dataclass(frozen=True, slots=True, eq=False)
class FapAnimation:
    """A fixed FAP configuration shaped by an envelope (face behaviours)."""

    target: FapConfiguration
    envelope: Envelope
    priority: int = 0
    blend: Blend = "add"
    behaviour_id: str = ""
    # add_to's data: the set FAPs' indices and values.
    _index: npt.NDArray[np.intp] = field(init=False, repr=False)
    _values: FloatArray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if self.blend not in BLENDS:
            raise ConversionError(f"unknown blend {self.blend!r}")
        index = np.flatnonzero(self.target.mask)
        object.__setattr__(self, "_index", index)
        object.__setattr__(self, "_values", np.asarray(self.target.values, dtype=float)[index])

    @property
    def start(self) -> float:
        return self.envelope.start

    @property
    def end(self) -> float:
        return self.envelope.end

    @property
    def faps(self) -> tuple[int, ...]:
        return tuple(int(i) + 1 for i in np.flatnonzero(self.target.mask))

    def evaluate(self, now: float) -> tuple[FloatArray, FloatArray]:
        weights = np.where(self.target.mask, self.envelope.level_at(now), 0.0)
        return self.target.values.copy(), weights

    def add_to(self, values: FloatArray, mask: BoolArray, now: float) -> None:
        """What :func:`mix` does with an ``add`` animation, on its own FAPs only."""
        level = self.envelope.level_at(now)
        if level > 0.0:
            values[self._index] += level * self._values
            mask[self._index] = True

    def replace_in(self, values: FloatArray, mask: BoolArray, now: float) -> None:
        """What :func:`mix` does with a ``replace`` animation, on its own FAPs only."""
        level = self.envelope.level_at(now)
        if level > 0.0:
            index = self._index
            values[index] = (1.0 - level) * values[index] + level * self._values
            mask[index] = True


@dataclass(frozen=True, slots=True, eq=False)
class KeyframeAnimation:
    """FAP values through keyframes (head movements): ``times`` (k,) seconds,
    ascending; ``values`` (k, len(faps)); segments shaped by ``curve``. The
    animation has weight 1 on its FAPs from the first to the last keyframe."""

    faps: tuple[int, ...]
    times: FloatArray
    values: FloatArray
    curve: CurveKind = "hermite"
    priority: int = 0
    blend: Blend = "add"
    behaviour_id: str = ""
    _index: npt.NDArray[np.intp] = field(init=False, repr=False)
    # The scalar path of evaluate (one call per frame): times as floats,
    # each segment's start values and change, the constant weights.
    _times: tuple[float, ...] = field(init=False, repr=False)
    _steps: FloatArray = field(init=False, repr=False)
    _weights: FloatArray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if self.times.ndim != 1 or self.times.size < 2:
            raise ConversionError("a keyframe animation needs at least two keyframe times")
        if self.values.shape != (self.times.size, len(self.faps)):
            raise ConversionError("keyframe values must have shape (keyframes, faps)")
        if np.any(np.diff(self.times) < -TIME_EPSILON_S):
            raise ConversionError("keyframe times must ascend")
        check_curve(self.curve)
        index = np.asarray(self.faps, dtype=np.intp) - 1
        object.__setattr__(self, "_index", index)
        object.__setattr__(self, "_times", tuple(self.times.tolist()))
        object.__setattr__(self, "_steps", np.diff(self.values, axis=0))
        weights = np.zeros(FAP_COUNT)
        weights[index] = 1.0
        weights.setflags(write=False)
        object.__setattr__(self, "_weights", weights)

    @property
    def start(self) -> float:
        return float(self.times[0])

    @property
    def end(self) -> float:
        return float(self.times[-1])

    def sample(self, t: npt.ArrayLike) -> FloatArray:
        """Values at times ``t`` (n,) -> (n, len(faps)); held outside the keyframes."""
        x = np.atleast_1d(np.asarray(t, dtype=np.float64))
        segment = np.clip(np.searchsorted(self.times, x, side="right") - 1, 0, self.times.size - 2)
        t0, t1 = self.times[segment], self.times[segment + 1]
        span = np.maximum(t1 - t0, TIME_EPSILON_S)
        u = ease(self.curve, (x - t0) / span)[:, None]
        v0, v1 = self.values[segment], self.values[segment + 1]
        return v0 + (v1 - v0) * u

    def evaluate(self, now: float) -> tuple[FloatArray, FloatArray]:
        """Values and weights at ``now``: :meth:`sample` for one time, without arrays of times.

        The weights are one shared read-only array (the same at every moment).
        """
        values = np.zeros(FAP_COUNT)
        times = self._times
        if not times[0] <= now <= times[-1]:
            return values, np.zeros(FAP_COUNT)
        last = len(times) - 2
        segment = min(max(bisect.bisect_right(times, now) - 1, 0), last)
        t0 = times[segment]
        u = (now - t0) / max(times[segment + 1] - t0, TIME_EPSILON_S)
        u = min(max(u, 0.0), 1.0)
        if self.curve == "hermite":
            u = u * u * (3.0 - 2.0 * u)
        values[self._index] = self.values[segment] + self._steps[segment] * u
        return values, self._weights

    def add_to(self, values: FloatArray, mask: BoolArray, now: float) -> None:
        """What :func:`mix` does with an ``add`` animation, on its own FAPs only."""
        times = self._times
        if not times[0] <= now <= times[-1]:
            return
        segment = min(max(bisect.bisect_right(times, now) - 1, 0), len(times) - 2)
        t0 = times[segment]
        u = min(max((now - t0) / max(times[segment + 1] - t0, TIME_EPSILON_S), 0.0), 1.0)
        if self.curve == "hermite":
            u = u * u * (3.0 - 2.0 * u)
        values[self._index] += self.values[segment] + self._steps[segment] * u
        mask[self._index] = True


@dataclass(frozen=True, slots=True, eq=False)
class InterruptedAnimation(DerivedAnimation):
    """An animation stopped at ``at`` (seconds): it holds its values from that
    moment and fades its weights to 0 over ``release`` seconds with ``curve``.

    What the session uses when a block is interrupted or REPLACEd, so the face
    eases back instead of jumping (BML 1.0 leaves the manner to the realizer).
    """

    base: Animation
    at: float
    release: float = 0.2
    curve: CurveKind = "hermite"

    @property
    def end(self) -> float:
        return min(self.base.end, self.at + self.release)

    def evaluate(self, now: float) -> tuple[FloatArray, FloatArray]:
        if now <= self.at:
            return self.base.evaluate(now)
        values, weights = self.base.evaluate(self.at)
        if self.release <= TIME_EPSILON_S:
            return values, np.zeros_like(weights)
        fade = 1.0 - float(ease(self.curve, (now - self.at) / self.release))
        return values, weights * fade


@dataclass(frozen=True, slots=True, eq=False)
class FapLimits:
    """Each FAP's range ``[lower, upper]`` (68,) in FAPU-scaled units, for clamping."""

    lower: FloatArray
    upper: FloatArray

    def __post_init__(self) -> None:
        if self.lower.shape != (FAP_COUNT,) or self.upper.shape != (FAP_COUNT,):
            raise ConversionError("FAP limits need (68,) lower and upper arrays")
        if np.any(self.lower > self.upper):
            raise ConversionError("a FAP's lower limit is above its upper limit")

    @classmethod
    def unbounded(cls) -> FapLimits:
        return cls(np.full(FAP_COUNT, -np.inf), np.full(FAP_COUNT, np.inf))

    @classmethod
    def from_ranges(cls, ranges: Mapping[int, tuple[float, float]]) -> FapLimits:
        limits = cls.unbounded()
        for fap, (low, high) in ranges.items():
            limits.lower[fap - 1] = low
            limits.upper[fap - 1] = high
        return cls(limits.lower, limits.upper)

    def clamp(self, values: FloatArray) -> FloatArray:
        # np.minimum/np.maximum: np.clip's Python wrapper costs more than the work.
        return np.minimum(np.maximum(values, self.lower), self.upper)


#: The mixing order's key; the sort is stable, so ties keep the order given.
_MIX_ORDER = operator.attrgetter("priority", "start")


def _order(animations: Iterable[Animation]) -> list[Animation]:
    if isinstance(animations, list) and len(animations) < 2:
        return animations
    return sorted(animations, key=_MIX_ORDER)


def mix(
    animations: Iterable[Animation], now: float, limits: FapLimits | None = None
) -> tuple[FloatArray, BoolArray]:
    """Combine the animations at ``now`` (seconds) by the rule of the module
    docstring; returns ``(values (68,), mask (68,))``."""
    values = np.zeros(FAP_COUNT)
    mask = np.zeros(FAP_COUNT, dtype=bool)
    ordered = _order(animations)
    for animation in ordered:
        if not animation.start <= now <= animation.end:
            continue
        blend = getattr(animation, "blend", "add")
        # The fast path: an animation may apply the same rule itself, on its
        # own FAPs only (add_to for "add", replace_in for "replace").
        apply = getattr(animation, "add_to" if blend == "add" else "replace_in", None)
        if apply is not None:
            apply(values, mask, now)
            continue
        target, weights = animation.evaluate(now)
        active = weights > 0.0
        if blend == "replace":
            values = np.where(active, (1.0 - weights) * values + weights * target, values)
        else:
            # Where a weight is 0 nothing is added (np.where, not a product:
            # an unset target value need not be finite).
            values += np.where(active, weights * target, 0.0)
        mask |= active
    for animation in ordered:
        # An animation may constrain the mixed result (lip closure on p, b,
        # m must hold whatever opened the jaw, docs/speech.md).
        constrain = getattr(animation, "constrain", None)
        if constrain is not None and animation.start <= now <= animation.end:
            values = constrain(values, now)
    if limits is not None:
        values = limits.clamp(values)
    values[~mask] = 0.0
    return values, mask


def sample(
    animations: Sequence[Animation], times: npt.ArrayLike, limits: FapLimits | None = None
) -> tuple[FloatArray, BoolArray]:
    """Mix at each of ``times`` (n,) seconds: ``(values (n, 68), mask (n, 68))``."""
    moments = np.atleast_1d(np.asarray(times, dtype=np.float64))
    values = np.zeros((moments.size, FAP_COUNT))
    mask = np.zeros((moments.size, FAP_COUNT), dtype=bool)
    for row, now in enumerate(moments):  # one mix per frame; each mix is vectorised over FAPs
        values[row], mask[row] = mix(animations, float(now), limits)
    return values, mask
