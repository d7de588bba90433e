"""The mixer's fast paths (``add_to``, ``replace_in``) give what evaluating gives.

``mix`` lets an ``add`` animation add itself on its own FAPs (``add_to``),
and a ``replace`` face animation cross-fade on its own FAPs
(``replace_in``), instead of returning two (68,) vectors; the result must
not change (the random animations below use both blends). The
reference here is the mixer's rule written out over ``evaluate``.
"""

from __future__ import annotations

import random

import numpy as np
import pytest

from realizer.face.convert.config import FAP_COUNT, FapConfiguration
from realizer.face.tracks import (
    Envelope,
    FapAnimation,
    FapLimits,
    InterruptedAnimation,
    KeyframeAnimation,
    mix,
)


def reference_mix(animations: list, now: float, limits: FapLimits | None) -> tuple:  # type: ignore[type-arg]
    values = np.zeros(FAP_COUNT)
    mask = np.zeros(FAP_COUNT, dtype=bool)
    order = sorted(enumerate(animations), key=lambda p: (p[1].priority, p[1].start, p[0]))
    for _, animation in order:
        if not animation.start <= now <= animation.end:
            continue
        target, weights = animation.evaluate(now)
        active = weights > 0.0
        if getattr(animation, "blend", "add") == "replace":
            values = np.where(active, (1.0 - weights) * values + weights * target, values)
        else:
            values = values + np.where(active, weights * target, 0.0)
        mask |= active
    if limits is not None:
        values = np.clip(values, limits.lower, limits.upper)
    return np.where(mask, values, 0.0), mask


def random_animation(chance: random.Random) -> object:
    faps = sorted(chance.sample(range(3, 69), chance.randint(1, 6)))
    start = chance.uniform(0, 2)
    if chance.random() < 0.5:
        vector = np.zeros(FAP_COUNT)
        mask = np.zeros(FAP_COUNT, dtype=bool)
        for fap in faps:
            vector[fap - 1] = chance.uniform(-300, 300)
            mask[fap - 1] = True
        times = sorted(chance.uniform(start, start + 3) for _ in range(3))
        animation: object = FapAnimation(
            FapConfiguration(vector, mask),
            Envelope(start, times[0], times[1], times[2],
                     chance.choice(["linear", "hermite", "triangular"])),
            priority=chance.randint(0, 2),
            blend=chance.choice(["add", "add", "replace"]),
        )  # fmt: skip
    else:
        count = chance.randint(2, 6)
        times = np.array(sorted(chance.uniform(start, start + 3) for _ in range(count)))
        animation = KeyframeAnimation(
            tuple(faps), times, np.array([[chance.uniform(-200, 200) for _ in faps]
                                          for _ in range(count)]),
            curve=chance.choice(["linear", "hermite"]),
            priority=chance.randint(0, 2),
            blend=chance.choice(["add", "add", "replace"]),
        )  # fmt: skip
    if chance.random() < 0.2:
        animation = InterruptedAnimation(animation, at=start + chance.uniform(0, 2))  # type: ignore[arg-type]
    return animation


@pytest.mark.parametrize("seed", range(60))
def test_mix_equals_the_rule_over_evaluate(seed: int) -> None:
    chance = random.Random(seed)
    animations = [random_animation(chance) for _ in range(chance.randint(1, 6))]
    limits = FapLimits.from_ranges({fap: (-150.0, 150.0) for fap in range(3, 69, 2)})
    for now in np.linspace(-0.5, 6.0, 27):
        for lim in (None, limits):
            values, mask = mix(animations, float(now), lim)  # type: ignore[arg-type]
            expected_values, expected_mask = reference_mix(animations, float(now), lim)
            assert np.array_equal(mask, expected_mask)
            np.testing.assert_allclose(values, expected_values, rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("curve", ["linear", "hermite"])
def test_keyframe_evaluate_at_one_time_equals_sample(curve: str) -> None:
    animation = KeyframeAnimation(
        (3, 19, 48), np.array([0.0, 0.4, 0.4, 1.3, 2.0]),
        np.array([[0, 0, 0], [100, -50, 20], [100, -50, 20], [-80, 30, 0], [0, 0, 0.0]]),
        curve=curve,  # type: ignore[arg-type]
    )  # fmt: skip
    for now in np.linspace(0.0, 2.0, 101):
        values, weights = animation.evaluate(float(now))
        np.testing.assert_allclose(values[[2, 18, 47]], animation.sample(float(now))[0],
                                   atol=1e-12)  # fmt: skip
        assert weights[[2, 18, 47]].tolist() == [1.0, 1.0, 1.0] and weights.sum() == 3.0
    outside, weights = animation.evaluate(2.5)
    assert not outside.any() and not weights.any()
