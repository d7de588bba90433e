"""Idle motion: what keeps a face alive between and during behaviours.

A deterministic generator of FAP values for one character: blinks at random
intervals (and often on a larger gaze shift), small saccades of both eyes
with the upper lids following the eyes' pitch, breathing, and a slow micro
motion of the head. Everything is a pure function of the seed and the time:
:meth:`IdleMotion.frame` at ``now`` gives the same values whatever times
were asked before, so two runs with the same seed are identical frame for
frame, and tests can pin them. ``offset`` (seconds, default 0) is added to
every time asked: a cluster worker sets it to the Unix time of its clock's
frame 0, so the motion follows the wall clock and every worker shows a
character the same idle pose at the same moment (a takeover carries on).

Figures follow the literature the thesis "Realization and high level
specification of facial expressions for embodied agents" builds on for
expressive agents: a spontaneous blink every 2 to 10 seconds (about 15 a
minute), closing in about 0.1 s and opening in about 0.2 s; saccades of a
few degrees every 0.5 to 3 s, taking a few tens of milliseconds, with a
blink on most gaze shifts of more than about 10 degrees; breathing every 4
to 5 s. The session lets explicit behaviours win per FAP: idle values only
fill the FAPs no animation sets (:class:`realizer.session.Session`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["IDLE_FAPS", "IdleMotion", "IdleSettings"]

#: The FAPs idle motion sets: lids 19, 20; eyeballs 23..26; head 48..50.
IDLE_FAPS = (19, 20, 23, 24, 25, 26, 48, 49, 50)

#: How far (IRISD units) the cornea's top travels per AU of eye pitch on a
#: 12 mm eyeball with a 9 mm IRISD (the default face): 12e-5 / 9 * 1024.
LID_IRISD_PER_AU = 0.0137

#: One degree in the angular FAP unit AU (1e-5 rad).
DEGREE_AU = math.radians(1.0) / 1e-5


@dataclass(frozen=True, slots=True)
class IdleSettings:
    """How a character's idle motion behaves (times in seconds, angles in degrees)."""

    seed: int = 0
    blink_interval: tuple[float, float] = (1.5, 7.0)  # uniform bounds of the log-interval
    blink_close_s: float = 0.09
    blink_hold_s: float = 0.04
    blink_open_s: float = 0.2
    saccade_interval: tuple[float, float] = (0.6, 3.0)
    saccade_degrees: float = 4.0  # the largest offset of the gaze from straight ahead
    saccade_s: float = 0.045
    blink_on_shift_degrees: float = 3.0  # shifts larger than this blink half the time
    lid_follow: float = 0.7  # how much of the eye's pitch the upper lids follow
    breath_s: float = 4.6
    breath_degrees: float = 0.35
    head_degrees: float = 0.8

    def __post_init__(self) -> None:
        lo, hi = self.blink_interval
        if not 0.2 <= lo <= hi <= 60.0:
            raise ValueError("blink_interval must lie in 0.2 .. 60 s, low first")
        lo, hi = self.saccade_interval
        if not 0.1 <= lo <= hi <= 60.0:
            raise ValueError("saccade_interval must lie in 0.1 .. 60 s, low first")
        for name in ("blink_close_s", "blink_open_s", "saccade_s", "breath_s"):
            if not 0.005 <= getattr(self, name) <= 60.0:
                raise ValueError(f"{name} must lie in 0.005 .. 60 s")


#: Events are made in chunks of this many seconds, each from its own random
#: stream (seed, kind, chunk), so any time can be evaluated on its own.
_CHUNK_S = 30.0


class IdleMotion:
    """Idle FAP values of one character; :meth:`frame` gives them at a time."""

    def __init__(self, settings: IdleSettings | None = None, offset: float = 0.0) -> None:
        self.settings = settings or IdleSettings()
        #: added to every time :meth:`frame` is asked for (see the module)
        self.offset = offset
        self._cache: dict[tuple[str, int], np.ndarray] = {}
        self._targets: dict[int, tuple[float, float]] = {}
        self._shift_blinks: dict[int, bool] = {}
        s = self.settings
        rng = np.random.default_rng([s.seed, 7])
        # micro head motion: a sum of slow sines per axis (48, 49, 50)
        self._head_freq = rng.uniform(0.05, 0.35, size=(3, 3))
        self._head_phase = rng.uniform(0.0, 2 * math.pi, size=(3, 3))
        self._head_amp = rng.uniform(0.4, 1.0, size=(3, 3))
        self._head_amp /= self._head_amp.sum(axis=1, keepdims=True)
        self._breath_phase = float(rng.uniform(0.0, 2 * math.pi))

    # -- event schedules ----------------------------------------------------------

    def _times(self, kind: str, chunk: int) -> np.ndarray:
        """Start times of the events of ``kind`` in chunk ``chunk`` (sorted)."""
        key = (kind, chunk)
        cached = self._cache.get(key)
        if cached is not None:
            return cached
        s = self.settings
        lo, hi = s.blink_interval if kind == "blink" else s.saccade_interval
        rng = np.random.default_rng([s.seed, 1 if kind == "blink" else 2, chunk + 2**31])
        t = chunk * _CHUNK_S + float(rng.uniform(0.0, lo))
        times = []
        while t < (chunk + 1) * _CHUNK_S:
            times.append(t)
            t += math.exp(float(rng.uniform(math.log(lo), math.log(hi))))
        result = np.asarray(times)
        if len(self._cache) > 16:  # keep the few chunks around now
            self._cache.clear()
        self._cache[key] = result
        return result

    def _recent(self, kind: str, now: float, count: int) -> np.ndarray:
        """The last ``count`` event times at or before ``now`` (oldest first)."""
        chunk = math.floor(now / _CHUNK_S)
        times = self._times(kind, chunk)
        times = times[times <= now]
        if len(times) < count:
            earlier = self._times(kind, chunk - 1)
            times = np.concatenate([earlier, times])
        return times[-count:]

    def _gaze(self, index: int) -> tuple[float, float]:
        """The gaze target (yaw, pitch) in degrees after saccade ``index``."""
        cached = self._targets.get(index)
        if cached is not None:
            return cached
        s = self.settings
        rng = np.random.default_rng([s.seed, 3, index + 2**40])
        radius = s.saccade_degrees * math.sqrt(float(rng.uniform()))
        angle = float(rng.uniform(0.0, 2 * math.pi))
        target = (radius * math.cos(angle), 0.6 * radius * math.sin(angle))
        if len(self._targets) > 64:
            self._targets.clear()
        self._targets[index] = target
        return target

    def _blinks_on_shift(self, index: int) -> bool:
        """Whether the gaze shift of saccade ``index`` comes with a blink (half do)."""
        cached = self._shift_blinks.get(index)
        if cached is None:
            rng = np.random.default_rng([self.settings.seed, 4, index + 2**40])
            cached = bool(rng.uniform() < 0.5)
            if len(self._shift_blinks) > 64:
                self._shift_blinks.clear()
            self._shift_blinks[index] = cached
        return cached

    def _saccade_index(self, t: float) -> int:
        """A global number for the saccade starting at ``t`` (its 10 ms slot)."""
        return round(t * 100)

    # -- the frame ----------------------------------------------------------------

    def frame(self, now: float) -> tuple[np.ndarray, np.ndarray]:
        """(values (68,), mask (68,)) of the idle FAPs at ``now`` seconds
        (plus :attr:`offset`)."""
        s = self.settings
        now = now + self.offset
        values = np.zeros(68)
        mask = np.zeros(68, dtype=bool)
        for fap in IDLE_FAPS:
            mask[fap - 1] = True
        # gaze: the last two saccades (to ease from the previous target)
        recent = self._recent("saccade", now, 2)
        if len(recent):
            start = float(recent[-1])
            target = self._gaze(self._saccade_index(start))
            before = self._gaze(self._saccade_index(float(recent[0]))) if len(recent) > 1 else (
                0.0, 0.0,
            )  # fmt: skip
            k = min(max((now - start) / s.saccade_s, 0.0), 1.0)
            k = k * k * (3 - 2 * k)
            yaw = before[0] + (target[0] - before[0]) * k
            pitch = before[1] + (target[1] - before[1]) * k
        else:
            yaw = pitch = 0.0
        values[22] = values[23] = yaw * DEGREE_AU  # 23, 24: yaw (+ left)
        values[24] = values[25] = pitch * DEGREE_AU  # 25, 26: pitch (+ down)
        # blinks: spontaneous, and on large gaze shifts
        closing = self._blink(now, recent)
        # the upper lids follow the eyes' pitch (down: lower; up: higher)
        follow = s.lid_follow * LID_IRISD_PER_AU * pitch * DEGREE_AU
        values[18] = values[19] = min(1024.0 * closing + follow * (1.0 - closing), 1100.0)
        # breathing (head pitch) and micro head motion
        t = now
        breath = s.breath_degrees * math.sin(2 * math.pi * t / s.breath_s + self._breath_phase)
        for axis in range(3):
            wobble = float(
                np.sum(
                    self._head_amp[axis]
                    * np.sin(2 * math.pi * self._head_freq[axis] * t + self._head_phase[axis])
                )
            )
            values[47 + axis] = s.head_degrees * wobble * DEGREE_AU
        values[47] += breath * DEGREE_AU
        return values, mask

    def _blink(self, now: float, saccades: np.ndarray) -> float:
        """How closed the lids are (0 open .. 1 shut) at ``now``."""
        s = self.settings
        starts = list(self._recent("blink", now, 1))
        # a gaze shift larger than blink_on_shift_degrees blinks half the time
        if len(saccades) == 2:
            index = self._saccade_index(float(saccades[1]))
            previous = self._gaze(self._saccade_index(float(saccades[0])))
            shift = math.dist(self._gaze(index), previous)
            if shift > s.blink_on_shift_degrees and self._blinks_on_shift(index):
                starts.append(float(saccades[1]))
        total = s.blink_close_s + s.blink_hold_s + s.blink_open_s
        closing = 0.0
        for start in starts:
            age = now - start
            if not 0.0 <= age < total:
                continue
            if age < s.blink_close_s:
                k = age / s.blink_close_s
                amount = k * k
            elif age < s.blink_close_s + s.blink_hold_s:
                amount = 1.0
            else:
                k = (age - s.blink_close_s - s.blink_hold_s) / s.blink_open_s
                amount = (1 - k) ** 2
            closing = max(closing, amount)
        return closing
