"""The articulation's per-frame fast path gives what the mixer's rule over ``evaluate`` gives.

A speech's two lip animations find their sample by arithmetic and apply
themselves on their own FAPs (``add_to``, ``replace_in``); mixed with other
face animations, the frame must equal the rule written out over
``evaluate`` (tests/face/test_mix_fast_path.py) followed by the closure
constraint. The phonemes here are written by hand (no TTS needed).
"""

from __future__ import annotations

import random

import numpy as np
import pytest

from realizer.engines.speech.lipsync import LipAnimation, lip_animations, mouth_opening
from realizer.face.tracks import FapLimits, InterruptedAnimation, mix
from tests.face.test_mix_fast_path import random_animation, reference_mix

WORDS = [["p", "iː", "t", "ə"], ["b", "ɔː", "t"], ["m", "aɪ"], ["f", "aɪ", "v"], ["w", "ʌ", "n"]]


def phonemes(chance: random.Random) -> list[tuple[str, float, float]]:
    out: list[tuple[str, float, float]] = []
    t = chance.uniform(0.0, 1.0)
    for _ in range(chance.randint(1, 8)):
        for symbol in chance.choice(WORDS):
            length = chance.uniform(0.04, 0.2)
            out.append((symbol, t, t + length))
            t += length
        if chance.random() < 0.3:
            out.append(("", t, t + 0.3))
            t += 0.3
    return out


def reference(animations: list[object], now: float, limits: FapLimits | None) -> tuple:  # type: ignore[type-arg]
    values, mask = reference_mix(animations, now, None)
    for animation in sorted(animations, key=lambda a: (a.priority, a.start)):  # type: ignore[attr-defined]
        if isinstance(animation, LipAnimation) and animation.start <= now <= animation.end:
            values = animation.constrain(values, now)
    if limits is not None:
        values = np.clip(values, limits.lower, limits.upper)
    return np.where(mask, values, 0.0), mask


@pytest.mark.parametrize("seed", range(30))
def test_the_articulation_mixes_as_the_rule_over_evaluate_says(seed: int) -> None:
    chance = random.Random(seed)
    spoken = phonemes(chance)
    parts: list[object] = list(lip_animations(spoken))
    if chance.random() < 0.3:  # an interrupted speech: evaluated, not the fast path
        at = chance.uniform(spoken[0][1], spoken[-1][2])
        parts = [InterruptedAnimation(p, at) for p in parts]  # type: ignore[arg-type]
    others = [random_animation(chance) for _ in range(chance.randint(0, 4))]
    animations = others + parts
    chance.shuffle(animations)
    limits = FapLimits.from_ranges({fap: (-400.0, 400.0) for fap in range(3, 69)})
    for now in np.linspace(-0.5, spoken[-1][2] + 0.8, 61):
        for lim in (None, limits):
            values, mask = mix(animations, float(now), lim)  # type: ignore[arg-type]
            expected, expected_mask = reference(animations, float(now), lim)
            assert np.array_equal(mask, expected_mask)
            np.testing.assert_allclose(values, expected, rtol=1e-9, atol=1e-9)


def test_a_frame_between_samples_interpolates_them() -> None:
    add, replace = lip_animations([("m", 0.0, 0.1), ("a", 0.1, 0.3), ("p", 0.3, 0.4)])
    for part in (add, replace):
        for now in np.linspace(part.start, part.end, 137):
            values, weights = part.evaluate(float(now))
            index = np.asarray(part.faps) - 1
            for column, fap in enumerate(index):
                assert values[fap] == pytest.approx(
                    np.interp(now, part.times, part.values[:, column]), abs=1e-9
                )
            assert weights[index] == pytest.approx(np.interp(now, part.times, part.level))
            assert not np.delete(weights, index).any()
    # the jaw (added) and the lips (replaced) belong to one part each
    assert 3 in add.faps and 3 not in replace.faps
    assert 5 in replace.faps and 5 not in add.faps
    frame, _ = mix([add, replace], 0.05 - 0.04)  # the m, with the visual lead
    assert mouth_opening(frame) <= 0.0


def test_sample_times_must_be_even() -> None:
    with pytest.raises(ValueError, match="evenly spaced"):
        LipAnimation(np.array([0.0, 0.1, 0.3]), (3,), np.zeros((3, 1)), np.ones(3))
