"""Envelopes, time curves, animations and the mixer (realizer.face.tracks)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from realizer.face.convert.config import FapConfiguration
from realizer.face.convert.emotion import load_default_converter
from realizer.face.convert.errors import ConversionError
from realizer.face.convert.facs import facs_to_faps
from realizer.face.convert.lexemes import lexeme_faps
from realizer.face.tracks import (
    Envelope,
    FapAnimation,
    FapLimits,
    InterruptedAnimation,
    KeyframeAnimation,
    bookmark_curve,
    ease,
    mix,
    sample,
)


def test_a_linear_envelope_attacks_sustains_and_releases() -> None:
    envelope = Envelope(1.0, 2.0, 4.0, 6.0)
    levels = envelope.level([0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 6.0, 6.5])
    assert levels == pytest.approx([0, 0, 0.5, 1, 1, 1, 0.5, 0, 0])


def test_a_hermite_envelope_starts_and_stops_smoothly() -> None:
    envelope = Envelope(0.0, 1.0, 2.0, 3.0, "hermite")
    assert envelope.level([0.25, 0.5, 2.5]) == pytest.approx([0.15625, 0.5, 0.5])
    # zero slope at the ends of the attack
    assert envelope.level(1e-3) < 1e-5 and 1 - envelope.level(1 - 1e-3) < 1e-5


def test_a_triangular_envelope_peaks_at_attack_peak_and_has_no_sustain() -> None:
    envelope = Envelope(0.0, 1.0, 3.0, 4.0, "triangular")
    assert envelope.level([0.5, 1.0, 2.5, 4.0]) == pytest.approx([0.5, 1.0, 0.5, 0.0])


def test_bookmark_curves_follow_seed_002() -> None:
    u = [0.0, 0.25, 0.5, 1.0]
    assert bookmark_curve("linear", u) == pytest.approx([0, 0.25, 0.5, 1])
    assert bookmark_curve("hermite", u) == pytest.approx([0, 0.15625, 0.5, 1])
    assert bookmark_curve("triangular", u) == pytest.approx([0, 0.5, 1, 0])
    assert ease("linear", [-1, 2]) == pytest.approx([0, 1])


def test_envelopes_with_missing_syncs_and_zero_attack() -> None:
    envelope = Envelope.from_syncs({"start": 1.0, "end": 3.0})
    assert envelope.level([1.0, 2.0, 2.999, 3.0]) == pytest.approx([1.0, 1.0, 1.0, 0.0])
    held = Envelope(0.0, 1.0, math.inf, math.inf)
    assert held.level(1e6) == 1.0


def test_envelopes_refuse_sync_times_out_of_order_and_unknown_curves() -> None:
    with pytest.raises(ConversionError):
        Envelope(1.0, 0.5, 2.0, 3.0)
    with pytest.raises(ConversionError):
        Envelope(0.0, 0.5, 2.0, 3.0, "cubic")  # type: ignore[arg-type]


def test_a_fap_animation_weighs_its_faps_by_the_envelope() -> None:
    animation = FapAnimation(lexeme_faps("RAISE_BROWS", 1.0), Envelope(0, 1, 2, 3))
    values, weights = animation.evaluate(0.5)
    assert values[30] == 300.0 and weights[30] == 0.5
    assert weights[2] == 0.0  # FAP 3 is not part of it
    assert animation.faps == (31, 32, 33, 34, 35, 36)


def test_overlapping_lexemes_add_up_per_fap() -> None:
    raise_brows = FapAnimation(lexeme_faps("RAISE_BROWS", 0.5), Envelope(0, 0.2, 2, 2.2))
    oblique = FapAnimation(lexeme_faps("OBLIQUE_BROWS", 0.5), Envelope(1, 1.2, 3, 3.2))
    smile = FapAnimation(lexeme_faps("RAISE_MOUTH_CORNERS", 0.5), Envelope(1, 1.2, 3, 3.2))
    values, mask = mix([raise_brows, oblique, smile], 1.5)
    assert values[30] == pytest.approx(150 + 150)  # FAP 31 from AU 1 twice
    assert values[34] == pytest.approx(150)  # FAP 35 from AU 2 only
    assert values[58] == pytest.approx(125)  # FAP 59 from the smile
    assert mask[30] and mask[58] and not mask[2]
    alone, _ = mix([raise_brows], 1.5)
    assert alone[30] == pytest.approx(150)  # seed 000 7.4 would have kept only one


def test_the_sum_is_clamped_to_each_faps_range() -> None:
    limits = FapLimits.from_ranges({31: (-400, 400)})
    strong = FapAnimation(lexeme_faps("RAISE_BROWS", 1.0), Envelope(0, 0, 5, 5))
    again = FapAnimation(lexeme_faps("OBLIQUE_BROWS", 1.0), Envelope(0, 0, 5, 5))
    values, _ = mix([strong, again], 1.0, limits)
    assert values[30] == 400 and values[32] == pytest.approx(320)


def test_an_emotion_under_a_facs_refinement_as_in_seed_000_figure_7_2() -> None:
    # serenity-like emotion (delighted, joy category) with a wink on the left eye
    emotion = load_default_converter().for_word("delighted").configuration()
    wink = facs_to_faps(["46L"])
    limits = FapLimits.from_ranges({19: (-1080, 1080), 20: (-1080, 1080)})
    base = FapAnimation(emotion, Envelope(0, 0.5, 4, 4.5), priority=0)
    refinement = FapAnimation(wink, Envelope(1, 1.1, 1.3, 1.4), priority=1)
    values, _ = mix([refinement, base], 1.2, limits)
    alone, _ = mix([base], 1.2, limits)
    assert values[18] == pytest.approx(min(1080, alone[18] + 1000))  # left upper lid closes
    assert values[19] == pytest.approx(alone[19])  # right eye keeps the emotion
    untouched = ~wink.mask
    assert np.allclose(values[untouched], alone[untouched])  # the rest is the emotion
    after, _ = mix([refinement, base], 2.0, limits)
    assert np.allclose(after, alone)  # the wink is over


def test_a_replace_animation_cross_fades_the_layers_below_on_its_faps() -> None:
    smile = FapAnimation(lexeme_faps("RAISE_MOUTH_CORNERS", 1.0), Envelope(0, 0.2, 5, 5.2))
    brows = FapAnimation(lexeme_faps("RAISE_BROWS", 1.0), Envelope(0, 0.2, 5, 5.2))
    frown = FapAnimation(
        lexeme_faps("LOWER_MOUTH_CORNERS", 1.0), Envelope(1, 2, 3, 4), priority=2, blend="replace"
    )
    full, _ = mix([smile, brows, frown], 2.5)
    assert full[58] == pytest.approx(-250)  # FAP 59 is the frown's, not smile + frown
    assert full[52] == pytest.approx(200)  # FAP 53 (not in the frown) keeps the smile
    assert full[30] == pytest.approx(300)  # brows untouched
    halfway, _ = mix([smile, brows, frown], 1.5)
    assert halfway[58] == pytest.approx(0.5 * 250 + 0.5 * -250)


def test_priority_not_list_order_decides_what_replaces_what() -> None:
    low = FapAnimation(FapConfiguration.from_mapping({3: 100}), Envelope(0, 0, 2, 2), priority=0)
    high = FapAnimation(
        FapConfiguration.from_mapping({3: 500}), Envelope(0, 0, 2, 2), priority=1, blend="replace"
    )
    assert mix([high, low], 1.0)[0][2] == 500
    assert mix([low, high], 1.0)[0][2] == 500


def test_keyframe_animations_interpolate_between_keyframes() -> None:
    nod = KeyframeAnimation(
        (48,), np.array([0.0, 1.0, 2.0]), np.array([[0.0], [1000.0], [0.0]]), "linear"
    )
    assert nod.sample([0.5, 1.0, 1.75])[:, 0] == pytest.approx([500, 1000, 250])
    values, weights = nod.evaluate(0.5)
    assert values[47] == 500 and weights[47] == 1 and weights.sum() == 1
    assert nod.evaluate(3.0)[1].sum() == 0


def test_sampling_mixes_at_every_time() -> None:
    animation = FapAnimation(FapConfiguration.from_mapping({3: 100}), Envelope(0, 1, 1, 2))
    values, mask = sample([animation], [0.0, 0.5, 1.0, 1.5, 3.0])
    assert values[:, 2] == pytest.approx([0, 50, 100, 50, 0])
    assert mask[:, 2].tolist() == [False, True, True, True, False]


def test_an_interrupted_animation_holds_and_fades_out_instead_of_jumping() -> None:
    base = FapAnimation(FapConfiguration.from_mapping({3: 400}), Envelope(0, 1, 5, 6))
    stopped = InterruptedAnimation(base, at=0.5, release=0.5, curve="linear")
    assert stopped.end == 1.0 and stopped.priority == base.priority
    assert mix([stopped], 0.25)[0][2] == pytest.approx(100)  # as before the interrupt
    assert mix([stopped], 0.5)[0][2] == pytest.approx(200)
    assert mix([stopped], 0.75)[0][2] == pytest.approx(100)  # half faded from 200
    assert not mix([stopped], 1.5)[1].any()


def test_an_interrupted_replace_layer_stays_a_replace_layer() -> None:
    below = FapAnimation(FapConfiguration.from_mapping({3: 100}), Envelope(0, 0, 9, 9))
    top = FapAnimation(
        FapConfiguration.from_mapping({3: 500}), Envelope(0, 0, 9, 9), priority=1, blend="replace"
    )
    stopped = InterruptedAnimation(top, at=1.0, release=1.0, curve="linear")
    assert mix([below, stopped], 1.5)[0][2] == pytest.approx(300)
