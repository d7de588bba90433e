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

:func:`lip_track` samples the result once per speech at :data:`RATE_HZ`
(vectorised, in windows of bounded size), so evaluating a frame is a linear
interpolation: the cost per frame does not grow with the speech.
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

    def lookup(self, symbol: str) -> tuple[tuple[int, ...], str]:
        """The viseme(s) of an IPA symbol and its dominance class."""
        for key in (symbol, _strip(symbol), symbol[:1]):
            if key in self.visemes:
                visemes = self.visemes[key]
                weak = key in self.weak_symbols or symbol in self.weak_symbols
                return visemes, "weak" if weak else self.class_of_viseme.get(visemes[0], "weak")
        return (0,), "weak"


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
    alpha: FloatArray  # (n, k)
    theta: FloatArray  # (n, k)
    spoken: list[tuple[float, float]]  # intervals of non-pause phonemes
    closes: npt.NDArray[np.bool_]  # (n,) the lips close for it (p, b, m)


def _targets(
    phonemes: Sequence[tuple[str, float, float]], model: LipModel, lead: float
) -> _Targets:
    faps = model.faps
    group_of = {}
    for name, members in model.groups.items():
        for fap in members:
            group_of[fap] = name
    shape_values = {
        shape.number: np.array([dict(shape.values).get(f, 0.0) for f in faps])
        for shape in model.shapes.shapes
    }
    neutral = np.zeros(len(faps))
    centres: list[float] = []
    targets: list[FloatArray] = []
    alphas: list[FloatArray] = []
    thetas: list[FloatArray] = []
    spoken: list[tuple[float, float]] = []
    closes: list[bool] = []
    for symbol, start, end in phonemes:
        start, end = start - lead, end - lead
        visemes, kind = model.lookup(symbol)
        if (kind != "pause" or symbol) and (visemes != (0,) or kind == "weak"):
            spoken.append((start, end))
        a = np.array([model.alpha[kind][group_of.get(f, "lips")] for f in faps])
        t = np.array([model.theta[kind][group_of.get(f, "lips")] for f in faps])
        pieces = len(visemes)
        step = (end - start) / pieces
        for index, viseme in enumerate(visemes):
            centres.append(start + step * (index + 0.5))
            targets.append(shape_values.get(viseme, neutral))
            alphas.append(a)
            thetas.append(t)
            closes.append(kind == "bilabial")
    return _Targets(
        np.array(centres), np.array(targets).reshape(-1, len(faps)),
        np.array(alphas).reshape(-1, len(faps)), np.array(thetas).reshape(-1, len(faps)),
        spoken, np.array(closes, dtype=bool),
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
    return _articulate(phonemes, times, model, lead)[0]


def _articulate(
    phonemes: Sequence[tuple[str, float, float]],
    times: FloatArray,
    model: LipModel | None = None,
    lead: float | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Mouth FAP values and the share (0..1) the closing phonemes (p, b, m) have of the lips."""
    model = model or load_lip_model()
    lead = model.lead if lead is None else lead
    if phonemes:
        first, last = phonemes[0][1], phonemes[-1][2]
        phonemes = [("", first - 0.3, first), *phonemes, ("", last, last + 0.3)]
    data = _targets(phonemes, model, lead)
    out = np.zeros((times.size, len(model.faps)))
    closure = np.zeros(times.size)
    if data.centres.size == 0:
        return out, closure
    lip = model.faps.index(5) if 5 in model.faps else 0  # raise_b_midlip: a lips FAP
    for begin in range(0, times.size, _WINDOW):
        window = times[begin : begin + _WINDOW]
        near = (data.centres >= window[0] - _REACH) & (data.centres <= window[-1] + _REACH)
        if not near.any():
            continue
        distance = np.abs(window[:, None] - data.centres[near][None, :])  # (w, n)
        dominance = data.alpha[near][None] * np.exp(-data.theta[near][None] * distance[:, :, None])
        total = dominance.sum(axis=1)  # (w, k)
        out[begin : begin + _WINDOW] = (dominance * data.targets[near][None]).sum(axis=1) / total
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
    """Sampled mouth FAPs of one speech: ``values`` and ``weights`` (k, 68) at ``times`` (k,).

    Linear interpolation between samples; ``blend`` is "add" or "replace"
    (two of these make one speech's articulation, docs/speech.md).
    """

    times: FloatArray
    values: FloatArray
    weights: FloatArray
    blend: str = "add"
    priority: int = PRIORITY
    behaviour_id: str = ""
    #: (k,) how firmly the lips must be closed (0..1), or None: no constraint
    closure: FloatArray | None = None

    @property
    def start(self) -> float:
        return float(self.times[0])

    def constrain(self, values: FloatArray, now: float) -> FloatArray:
        """Close the lips on p, b, m whatever opened the jaw in the mix.

        Where the closing phonemes dominate, the lower lip is raised (FAPs 5
        and 52) by what keeps the lips apart, so an emotion's or another
        behaviour's open jaw yields to the closure.
        """
        if self.closure is None:
            return values
        share = float(np.interp(now, self.times, self.closure))
        strength = float(np.clip((share - 0.3) / 0.4, 0.0, 1.0))
        gap = float(mouth_opening(values))
        if strength <= 0.0 or gap <= 0.0:
            return values
        values = values.copy()
        values[4] += strength * gap  # FAP 5 raise_b_midlip
        values[51] += strength * gap  # FAP 52 raise_b_midlip_o
        return values

    @property
    def end(self) -> float:
        return float(self.times[-1])

    def evaluate(self, now: float) -> tuple[FloatArray, FloatArray]:
        times = self.times
        if not times[0] <= now <= times[-1]:
            return np.zeros(FAP_COUNT), np.zeros(FAP_COUNT)
        index = min(int(np.searchsorted(times, now, side="right")) - 1, times.size - 2)
        index = max(index, 0)
        span = times[index + 1] - times[index]
        u = (now - times[index]) / span if span > 0 else 0.0
        values = self.values[index] + (self.values[index + 1] - self.values[index]) * u
        weights = self.weights[index] + (self.weights[index + 1] - self.weights[index]) * u
        return values, weights


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
    mouth, closure = _articulate(phonemes, times, model, lead)
    index = np.asarray(model.faps, dtype=np.intp) - 1
    group_of = {f: g for g, members in model.groups.items() for f in members}
    replace = np.array([group_of.get(f, "lips") in model.replace_groups for f in model.faps])
    values = np.zeros((count, FAP_COUNT))
    values[:, index] = mouth
    spoken = _targets(phonemes, model, lead).spoken
    held = hold(spoken, times, model.release)
    add_weights = np.zeros((count, FAP_COUNT))
    add_weights[:, index[~replace]] = 1.0
    add_weights[[0, -1]] = 0.0  # values are neutral there; the weight says so too
    replace_weights = np.zeros((count, FAP_COUNT))
    replace_weights[:, index[replace]] = held[:, None]
    return (
        LipAnimation(times, values, add_weights, "add", PRIORITY, behaviour_id),
        LipAnimation(
            times, values.copy(), replace_weights, "replace", PRIORITY, behaviour_id, closure
        ),
    )


def mouth_opening(values: npt.ArrayLike) -> FloatArray:
    """The inner lips' vertical gap change from neutral (FAPU MNS units) of FAP vectors (..., 68).

    ``open_jaw`` (FAP 3) lowers the lower lip, ``lower_t_midlip`` (FAP 4)
    lowers the upper inner lip and ``raise_b_midlip`` (FAP 5) raises the
    lower one (Tekalp and Ostermann 2000, Table 7): gap = F3 - F4 - F5;
    0 or below means the lips touch.
    """
    v = np.asarray(values, dtype=np.float64)
    return v[..., 2] - v[..., 3] - v[..., 4]
