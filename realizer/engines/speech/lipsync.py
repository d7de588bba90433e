"""Lip sync: timed phonemes -> MPEG-4 visemes -> mouth FAPs with coarticulation.

Tekalp and Ostermann 2000, section 2.1: a TTS hands phonemes with start
times and durations to a phoneme-to-FAP converter; FAP 1 names the 14
static visemes of Table 3, whose low-level FAP shapes belong to the face
model (:func:`realizer.face.convert.visemes.load_default_visemes`), and the
converter blends neighbouring visemes (coarticulation).

Coarticulation follows the dominance model of Cohen and Massaro (1993):
each phoneme ``n`` has a target ``T_n`` (its viseme's FAPs) and, per group
of FAPs ``g``, a dominance ``D_ng(t) = alpha_ng exp(-theta_ng |t - c_n|)``
that peaks at the phoneme's centre ``c_n``; a FAP's value is the
dominance-weighted mean ``sum_n D_ng(t) T_nf / sum_n D_ng(t)``. Strongly
dominant, narrow functions for p, b, m close the lips even between open
vowels; wide ones for rounded vowels spread lip rounding over neighbouring
consonants; weak ones for h and schwa let them take their neighbours'
shape, so fast speech blends instead of flickering. All of this is data
(``realizer/engines/speech/data/lipsync.toml``).

:func:`lip_animations` samples the result once per speech at
:data:`RATE_HZ`, vectorised over samples, phonemes and FAP groups (in
windows of bounded size; the model's per-viseme targets and per-class
dominance rows are arrays built once), so evaluating a frame is a linear
interpolation at an index found by arithmetic, on the mouth FAPs only: the
cost per frame does not grow with the speech.
"""

from __future__ import annotations

import tomllib
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np
import numpy.typing as npt

from realizer.face.convert.config import FAP_COUNT
from realizer.face.convert.visemes import ShapeTable, load_default_visemes

FloatArray = npt.NDArray[np.float64]

DATA_FILE = Path(__file__).resolve().parent / "data" / "lipsync.toml"

#: Lip track samples per second (linear interpolation between them).
RATE_HZ = 100.0
#: Samples per window of the vectorised evaluation (bounds memory per speech).
_WINDOW = 256
#: Seconds around a window whose phonemes are taken into account (the
#: widest dominance, theta 10/s, is below 1 % of its peak at 0.5 s).
_REACH = 0.6
#: Priority of the articulation in the mixer: above emotions (0) and FAP 1
#: visemes (1), with the face lexemes (2), below explicit FAPs (3).
PRIORITY = 2


@dataclass(frozen=True, slots=True, eq=False)
class _Tables:
    """The model as arrays, built once per model, so a speech's phonemes
    become dominance and target arrays by indexing instead of Python loops."""

    group_names: tuple[str, ...]
    fap_group: npt.NDArray[np.intp]  # (k,) the group (index) of each mouth FAP
    shape_rows: FloatArray  # (visemes, k) the target of each viseme number; 0 neutral
    class_names: tuple[str, ...]
    class_alpha: FloatArray  # (classes, groups)
    class_theta: FloatArray  # (classes, groups)
    replace: npt.NDArray[np.bool_]  # (k,) the FAP is in a "replace" group
    lip_group: int  # the group of FAP 5 raise_b_midlip (closure is judged on it)
    #: symbol -> (viseme numbers, class index, spoken), filled as symbols are met
    memo: dict[str, tuple[tuple[int, ...], int, bool]]


@dataclass(frozen=True, slots=True)
class LipModel:
    """Phoneme-to-viseme table, dominance parameters and mixing rules (from the data file)."""

    visemes: dict[str, tuple[int, ...]]
    weak_symbols: frozenset[str]
    class_of_viseme: dict[int, str]
    groups: dict[str, tuple[int, ...]]
    alpha: dict[str, dict[str, float]]  # class -> group -> alpha
    theta: dict[str, dict[str, float]]  # class -> group -> theta (1/s)
    replace_groups: frozenset[str]
    release: float
    lead: float
    shapes: ShapeTable
    faps: tuple[int, ...] = field(default=())
    _tables: _Tables | None = field(default=None, repr=False, compare=False)

    def lookup(self, symbol: str) -> tuple[tuple[int, ...], str]:
        """The viseme(s) of an IPA symbol and its dominance class."""
        for key in (symbol, _strip(symbol), symbol[:1]):
            if key in self.visemes:
                visemes = self.visemes[key]
                weak = key in self.weak_symbols or symbol in self.weak_symbols
                return visemes, "weak" if weak else self.class_of_viseme.get(visemes[0], "weak")
        return (0,), "weak"

    @property
    def tables(self) -> _Tables:
        if self._tables is None:
            object.__setattr__(self, "_tables", _tables(self))
        assert self._tables is not None
        return self._tables


def _tables(model: LipModel) -> _Tables:
    faps = model.faps
    group_of = {f: name for name, members in model.groups.items() for f in members}
    # A FAP no group names is a lips FAP (as the data file's comment says).
    group_names = tuple(dict.fromkeys([*model.groups, "lips"]))
    fap_group = np.array([group_names.index(group_of.get(f, "lips")) for f in faps], np.intp)
    numbers = [shape.number for shape in model.shapes.shapes]
    shape_rows = np.zeros((max([0, *numbers]) + 1, len(faps)))
    for shape in model.shapes.shapes:
        values = dict(shape.values)
        shape_rows[shape.number] = [values.get(f, 0.0) for f in faps]
    class_names = tuple(model.alpha)
    # every class gives every group its alpha and theta (a KeyError names a gap)
    class_alpha = np.array([[model.alpha[c][g] for g in group_names] for c in class_names])
    class_theta = np.array([[model.theta[c][g] for g in group_names] for c in class_names])
    replace = np.array([group_names[g] in model.replace_groups for g in fap_group], dtype=bool)
    lip_group = int(fap_group[faps.index(5)]) if 5 in faps else group_names.index("lips")
    return _Tables(group_names, fap_group, shape_rows, class_names, class_alpha, class_theta,
                   replace, lip_group, {})  # fmt: skip


def _strip(symbol: str) -> str:
    return symbol.replace("ˈ", "").replace("ˌ", "").replace("ː", "").replace("ˑ", "")


@lru_cache(maxsize=4)
def load_lip_model(path: Path = DATA_FILE) -> LipModel:
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    visemes: dict[str, tuple[int, ...]] = {}
    for symbol, value in data["visemes"].items():
        visemes[symbol] = tuple(value) if isinstance(value, list) else (int(value),)
    classes = data["classes"]
    class_of_viseme = {
        int(v): name for name, members in classes.items() if name != "weak_symbols"
        for v in members
    }  # fmt: skip
    groups = {name: tuple(int(f) for f in faps) for name, faps in data["groups"].items()}
    alpha = {name: dict(spec["alpha"]) for name, spec in data["dominance"].items()}
    theta = {name: dict(spec["theta"]) for name, spec in data["dominance"].items()}
    shapes = load_default_visemes()
    return LipModel(
        visemes=visemes,
        weak_symbols=frozenset(classes.get("weak_symbols", ())),
        class_of_viseme=class_of_viseme,
        groups=groups,
        alpha=alpha,
        theta=theta,
        replace_groups=frozenset(data["mixing"]["replace"]),
        release=float(data["mixing"]["release"]),
        lead=float(data.get("lead", 0.04)),
        shapes=shapes,
        faps=shapes.faps(),
    )


@dataclass(frozen=True, slots=True)
class _Targets:
    centres: FloatArray  # (n,) seconds
    targets: FloatArray  # (n, k) FAP values of the k mouth FAPs
    alpha: FloatArray  # (n, groups)
    theta: FloatArray  # (n, groups)
    spoken: list[tuple[float, float]]  # intervals of non-pause phonemes
    closes: npt.NDArray[np.bool_]  # (n,) the lips close for it (p, b, m)


def _symbol(model: LipModel, tables: _Tables, symbol: str) -> tuple[tuple[int, ...], int, bool]:
    """A symbol's visemes, dominance class (index) and whether it counts as spoken (memoised)."""
    known = tables.memo.get(symbol)
    if known is None:
        visemes, kind = model.lookup(symbol)
        spoken = bool((kind != "pause" or symbol) and (visemes != (0,) or kind == "weak"))
        known = (visemes, tables.class_names.index(kind), spoken)
        if len(tables.memo) < 4096:  # bounded: symbols come from the TTS
            tables.memo[symbol] = known
    return known


def _targets(
    phonemes: Sequence[tuple[str, float, float]], model: LipModel, lead: float
) -> _Targets:
    tables = model.tables
    centres: list[float] = []
    visemes_of: list[int] = []
    classes: list[int] = []
    spoken: list[tuple[float, float]] = []
    bilabial = tables.class_names.index("bilabial") if "bilabial" in tables.class_names else -1
    for symbol, start, end in phonemes:
        start, end = start - lead, end - lead
        visemes, kind, speaks = _symbol(model, tables, symbol)
        if speaks:
            spoken.append((start, end))
        step = (end - start) / len(visemes)
        for index, viseme in enumerate(visemes):
            centres.append(start + step * (index + 0.5))
            visemes_of.append(viseme if 0 <= viseme < tables.shape_rows.shape[0] else 0)
            classes.append(kind)
    kinds = np.asarray(classes, dtype=np.intp)
    return _Targets(
        np.asarray(centres, dtype=np.float64),
        tables.shape_rows[np.asarray(visemes_of, dtype=np.intp)],
        tables.class_alpha[kinds], tables.class_theta[kinds], spoken, kinds == bilabial,
    )  # fmt: skip


def articulate(
    phonemes: Sequence[tuple[str, float, float]],
    times: FloatArray,
    model: LipModel | None = None,
    lead: float | None = None,
) -> FloatArray:
    """Mouth FAP values ``(len(times), len(model.faps))`` at ``times`` (seconds).

    ``phonemes`` are ``(IPA symbol, start, end)`` on the same clock; before
    the first and after the last the mouth returns to neutral (a pause is
    added at both ends).
    """
    model = model or load_lip_model()
    lead = model.lead if lead is None else lead
    return _articulate(_targets(_padded(phonemes), model, lead), times, model)[0]


def _padded(phonemes: Sequence[tuple[str, float, float]]) -> list[tuple[str, float, float]]:
    """The phonemes with a pause before the first and after the last."""
    if not phonemes:
        return []
    first, last = phonemes[0][1], phonemes[-1][2]
    return [("", first - 0.3, first), *phonemes, ("", last, last + 0.3)]


def _articulate(
    data: _Targets, times: FloatArray, model: LipModel
) -> tuple[FloatArray, FloatArray]:
    """Mouth FAP values and the share (0..1) the closing phonemes (p, b, m) have of the lips.

    Per window of samples, the dominances are ``(samples, phonemes, groups)``
    (one exponential per group, not per FAP) and each group's weighted sum
    of targets is one matrix product.
    """
    tables = model.tables
    k = len(model.faps)
    out = np.zeros((times.size, k))
    closure = np.zeros(times.size)
    if data.centres.size == 0:
        return out, closure
    columns = np.arange(k)
    lip = tables.lip_group
    for begin in range(0, times.size, _WINDOW):
        window = times[begin : begin + _WINDOW]
        near = (data.centres >= window[0] - _REACH) & (data.centres <= window[-1] + _REACH)
        if not near.any():
            continue
        distance = np.abs(window[:, None] - data.centres[near][None, :])  # (w, n)
        dominance = data.alpha[near][None] * np.exp(-data.theta[near][None] * distance[:, :, None])
        total = dominance.sum(axis=1)  # (w, groups)
        weighted = np.matmul(dominance.transpose(0, 2, 1), data.targets[near])  # (w, groups, k)
        out[begin : begin + _WINDOW] = (
            weighted[:, tables.fap_group, columns] / total[:, tables.fap_group]
        )
        closing = dominance[:, data.closes[near], lip].sum(axis=1)
        closure[begin : begin + _WINDOW] = closing / total[:, lip]
    return out, closure


def hold(spoken: Sequence[tuple[float, float]], times: FloatArray, release: float) -> FloatArray:
    """How firmly articulation holds the "replace" FAPs at ``times``: 1 within
    spoken phonemes, easing to 0 at ``release`` seconds from the nearest one."""
    if not spoken or release <= 0:
        return np.zeros(times.size)
    starts = np.array([s for s, _ in spoken])
    ends = np.array([e for _, e in spoken])
    distance = np.full(times.size, np.inf)
    for begin in range(0, times.size, _WINDOW):
        window = times[begin : begin + _WINDOW, None]
        gap = np.maximum(np.maximum(starts[None] - window, window - ends[None]), 0.0)
        distance[begin : begin + _WINDOW] = gap.min(axis=1)
    u = np.clip(distance / release, 0.0, 1.0)
    return 1.0 - u * u * (3.0 - 2.0 * u)


@dataclass(frozen=True, slots=True, eq=False)
class LipAnimation:
    """Sampled mouth FAPs of one speech: ``values`` (k, len(faps)) of ``faps``
    at ``times`` (k,), evenly spaced, each with the weight ``level`` (k,).

    Linear interpolation between samples; ``blend`` is "add" or "replace"
    (two of these make one speech's articulation, docs/speech.md). A frame
    finds its sample by arithmetic (the times are evenly spaced) and touches
    only the animation's own FAPs.
    """

    times: FloatArray
    faps: tuple[int, ...]
    values: FloatArray
    level: FloatArray
    blend: str = "add"
    priority: int = PRIORITY
    behaviour_id: str = ""
    #: (k,) how firmly the lips must be closed (0..1), or None: no constraint
    closure: FloatArray | None = None
    # The per-frame path: bounds and sample rate as floats, FAP indices,
    # each segment's change, levels and closure as Python floats.
    _start: float = field(init=False, repr=False)
    _end: float = field(init=False, repr=False)
    _rate: float = field(init=False, repr=False)
    _last: int = field(init=False, repr=False)
    _index: npt.NDArray[np.intp] = field(init=False, repr=False)
    _steps: FloatArray = field(init=False, repr=False)
    _mask: FloatArray = field(init=False, repr=False)
    _levels: tuple[float, ...] = field(init=False, repr=False)
    _closure: tuple[float, ...] | None = field(init=False, repr=False)

    def __post_init__(self) -> None:
        times = self.times
        if times.ndim != 1 or times.size < 2 or not times[-1] > times[0]:
            raise ValueError("a lip animation needs at least two ascending sample times")
        if self.values.shape != (times.size, len(self.faps)) or self.level.shape != times.shape:
            raise ValueError("lip animation values must be (samples, faps), level (samples,)")
        span = float(times[-1] - times[0])
        if not np.allclose(np.diff(times), span / (times.size - 1), rtol=1e-6, atol=1e-9):
            raise ValueError("lip animation sample times must be evenly spaced")
        index = np.asarray(self.faps, dtype=np.intp) - 1
        mask = np.zeros(FAP_COUNT)
        mask[index] = 1.0
        set_ = object.__setattr__
        set_(self, "_start", float(times[0]))
        set_(self, "_end", float(times[-1]))
        set_(self, "_rate", (times.size - 1) / span)
        set_(self, "_last", times.size - 2)
        set_(self, "_index", index)
        set_(self, "_steps", np.diff(self.values, axis=0))
        set_(self, "_mask", mask)
        set_(self, "_levels", tuple(self.level.tolist()))
        closure = None if self.closure is None else tuple(self.closure.tolist())
        set_(self, "_closure", closure)

    @property
    def start(self) -> float:
        return self._start

    @property
    def end(self) -> float:
        return self._end

    def _at(self, now: float) -> tuple[int, float]:
        """The segment of ``now`` and the fraction (0..1) into it."""
        x = (now - self._start) * self._rate
        segment = min(max(int(x), 0), self._last)
        return segment, min(max(x - segment, 0.0), 1.0)

    def _level(self, segment: int, u: float) -> float:
        levels = self._levels
        return levels[segment] + (levels[segment + 1] - levels[segment]) * u

    def evaluate(self, now: float) -> tuple[FloatArray, FloatArray]:
        values = np.zeros(FAP_COUNT)
        if not self._start <= now <= self._end:
            return values, np.zeros(FAP_COUNT)
        segment, u = self._at(now)
        values[self._index] = self.values[segment] + self._steps[segment] * u
        return values, self._mask * self._level(segment, u)

    def add_to(self, values: FloatArray, mask: npt.NDArray[np.bool_], now: float) -> None:
        """What the mixer does with an ``add`` animation, on its own FAPs only."""
        if not self._start <= now <= self._end:
            return
        segment, u = self._at(now)
        level = self._level(segment, u)
        if level > 0.0:
            values[self._index] += (self.values[segment] + self._steps[segment] * u) * level
            mask[self._index] = True

    def replace_in(self, values: FloatArray, mask: npt.NDArray[np.bool_], now: float) -> None:
        """What the mixer does with a ``replace`` animation, on its own FAPs only."""
        if not self._start <= now <= self._end:
            return
        segment, u = self._at(now)
        level = self._level(segment, u)
        if level > 0.0:
            index = self._index
            target = self.values[segment] + self._steps[segment] * u
            values[index] += (target - values[index]) * level
            mask[index] = True

    def constrain(self, values: FloatArray, now: float) -> FloatArray:
        """Close the lips on p, b, m whatever opened the jaw in the mix.

        Where the closing phonemes dominate, the lower lip is raised (FAPs 5
        and 52) by what keeps the lips apart, so an emotion's or another
        behaviour's open jaw yields to the closure.
        """
        closure = self._closure
        if closure is None or not self._start <= now <= self._end:
            return values
        segment, u = self._at(now)
        share = closure[segment] + (closure[segment + 1] - closure[segment]) * u
        strength = min(max((share - 0.3) / 0.4, 0.0), 1.0)
        gap = float(values[2] - values[3] - values[4])  # mouth_opening, on one frame
        if strength <= 0.0 or gap <= 0.0:
            return values
        values = values.copy()
        values[4] += strength * gap  # FAP 5 raise_b_midlip
        values[51] += strength * gap  # FAP 52 raise_b_midlip_o
        return values


def lip_animations(
    phonemes: Sequence[tuple[str, float, float]],
    *,
    model: LipModel | None = None,
    lead: float | None = None,
    behaviour_id: str = "",
) -> tuple[LipAnimation, LipAnimation]:
    """The articulation of timed phonemes (global seconds) as (add part, replace part)."""
    model = model or load_lip_model()
    lead = model.lead if lead is None else lead
    start = (phonemes[0][1] if phonemes else 0.0) - lead - 0.3
    end = (phonemes[-1][2] if phonemes else 0.0) + 0.3
    count = max(2, int(np.ceil((end - start) * RATE_HZ)) + 1)
    times = np.linspace(start, end, count)
    data = _targets(_padded(phonemes), model, lead)  # the added pauses are not spoken
    mouth, closure = _articulate(data, times, model)
    replace = model.tables.replace
    faps = np.asarray(model.faps)
    held = hold(data.spoken, times, model.release)
    on = np.ones(count)
    on[[0, -1]] = 0.0  # values are neutral there; the weight says so too
    add_faps = tuple(int(f) for f in faps[~replace])
    replace_faps = tuple(int(f) for f in faps[replace])
    return (
        LipAnimation(times, add_faps, mouth[:, ~replace], on, "add", PRIORITY, behaviour_id),
        LipAnimation(times, replace_faps, mouth[:, replace], held, "replace", PRIORITY,
                     behaviour_id, closure),
    )  # fmt: skip


def mouth_opening(values: npt.ArrayLike) -> FloatArray:
    """The inner lips' vertical gap change from neutral (FAPU MNS units) of FAP vectors (..., 68).

    ``open_jaw`` (FAP 3) lowers the lower lip, ``lower_t_midlip`` (FAP 4)
    lowers the upper inner lip and ``raise_b_midlip`` (FAP 5) raises the
    lower one (Tekalp and Ostermann 2000, Table 7): gap = F3 - F4 - F5;
    0 or below means the lips touch.
    """
    v = np.asarray(values, dtype=np.float64)
    return v[..., 2] - v[..., 3] - v[..., 4]
