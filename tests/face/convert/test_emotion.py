"""Emotion -> FAP ranges: the worked examples of seeds 000 and 001.

Tolerances are the papers' rounding: seed 001 Table 7 rounds to tens (and
computed terrified with the ratio 6.3/4.9 rounded to 1.3), Table 8 to fives;
seed 000 rounds to units. docs/emotion.md explains each deviation tested here.
"""

from __future__ import annotations

import dataclasses

import pytest

from realizer.face.convert.emotion import (
    ARCHETYPES,
    EmotionConverter,
    FapRange,
    ProfileSet,
    add_ranges,
    angular_weights,
    between_archetypes,
    format_profiles,
    format_vocabulary,
    format_wheels,
    load_default_converter,
    parse_profiles,
    parse_vocabulary,
    parse_wheels,
    same_category,
    weighted_range,
)
from realizer.face.convert.errors import ConversionError, DataFileError

FEAR_8 = {
    3: (400, 560), 5: (-240, -160), 19: (-630, -570), 20: (-630, -570), 21: (-630, -570),
    22: (-630, -570), 31: (260, 340), 32: (260, 340), 33: (160, 240), 34: (160, 240),
    35: (60, 140), 36: (60, 140),
}  # fmt: skip

#: Seed 001 Table 7.
TERRIFIED = {
    3: (520, 730), 5: (-310, -210), 19: (-820, -740), 20: (-820, -740), 21: (-820, -740),
    22: (-820, -740), 31: (340, 440), 32: (340, 440), 33: (210, 310), 34: (210, 310),
    35: (80, 180), 36: (80, 180),
}  # fmt: skip
WORRIED = {
    3: (320, 450), 5: (-190, -130), 19: (-500, -450), 20: (-500, -450), 21: (-500, -450),
    22: (-500, -450), 31: (210, 270), 32: (210, 270), 33: (130, 190), 34: (130, 190),
    35: (50, 110), 36: (50, 110),
}  # fmt: skip

#: Seed 001 Table 8 (F19..F22 printed with reversed bounds there).
GUILTY = {
    3: (160, 230), 5: (-100, -65), 19: (-310, -110), 20: (-315, -120), 21: (-310, -110),
    22: (-315, -120), 31: (61, 167), 32: (57, 160), 33: (65, 100), 34: (65, 100),
    35: (25, 60), 36: (25, 60),
}  # fmt: skip


def ranges(profile: dict[int, FapRange]) -> dict[int, tuple[float, float]]:
    return {fap: (r.low, r.high) for fap, r in profile.items()}


def assert_ranges_close(
    got: dict[int, FapRange], expected: dict[int, tuple[float, float]], tolerance: float
) -> None:
    assert set(got) == set(expected)
    for fap, (low, high) in expected.items():
        assert got[fap].low == pytest.approx(min(low, high), abs=tolerance + 1e-9), f"F{fap} low"
        assert got[fap].high == pytest.approx(max(low, high), abs=tolerance + 1e-9), f"F{fap} high"


def test_the_profile_file_holds_every_profile_of_table_5() -> None:
    profiles = load_default_converter().profiles
    counts = {name: len(profiles.numbers(name)) for name in ARCHETYPES}
    assert counts == {"anger": 5, "sadness": 1, "joy": 4, "disgust": 1, "fear": 10, "surprise": 4}


def test_the_profile_file_matches_seed_000_figure_6_5() -> None:
    profiles = load_default_converter().profiles
    fear9 = profiles.get("fear", 9).as_dict()
    assert (fear9[5].low, fear9[5].high) == (307, 399)  # "the range for FAP 5 starts at 307"
    assert (fear9[36].low, fear9[36].high) == (460, 540)
    surprise1 = profiles.get("surprise", 1).as_dict()
    assert (surprise1[3].low, surprise1[3].high) == (1150, 1252)
    assert (surprise1[54].low, surprise1[54].high) == (-141, -101)


def test_seed_000_fear_profile_of_figure_6_2_is_fear_3() -> None:
    fear3 = ranges(load_default_converter().profiles.get("fear", 3).as_dict())
    assert fear3 == {
        3: (400, 560), 5: (-240, -160), 19: (-630, -570), 20: (-630, -570), 21: (-630, -570),
        22: (-630, -570), 31: (460, 540), 32: (460, 540), 37: (60, 140), 38: (60, 140),
    }  # fmt: skip


def test_seed_000_surprise_fap3_example_scales_by_activation() -> None:
    # seed 000 equation 6.1: [569, 1201] * 4.0 / 6.5 = [350, 739]
    result = same_category({3: FapRange(569, 1201)}, 6.5, 4.0)[3]
    assert round(result.low) == 350 and round(result.high) == 739
    converter = load_default_converter()
    at_point = converter.for_point(146.7, 4.0, choices={"surprise": 0}).as_dict()[3]
    assert round(at_point.low) == 350 and round(at_point.high) == 739


def test_terrified_and_worried_follow_seed_001_table_7() -> None:
    converter = load_default_converter()
    terrified = converter.for_word("terrified")
    worried = converter.for_word("worried")
    assert terrified.rule == worried.rule == "same-category"
    assert terrified.sources == worried.sources == ("Fear 8",)
    assert_ranges_close(terrified.as_dict(), TERRIFIED, tolerance=10)
    assert_ranges_close(worried.as_dict(), WORRIED, tolerance=10)


def test_terrified_matches_table_7_exactly_with_the_papers_rounded_ratio() -> None:
    # The paper used 6.3 / 4.9 = 1.2857 rounded to 1.3 and rounded to tens.
    got = same_category({fap: FapRange(*r) for fap, r in FEAR_8.items()}, 1.0, 1.3)
    assert {fap: (round(r.low, -1), round(r.high, -1)) for fap, r in got.items()} == TERRIFIED


def test_afraid_is_the_archetypal_profile_itself() -> None:
    afraid = load_default_converter().for_word("afraid")
    assert afraid.rule == "archetype"
    assert ranges(afraid.as_dict()) == FEAR_8


def printed_sadness_converter() -> EmotionConverter:
    """The converter over Table 5 alone, with Sadness 0's eyelids as printed
    (profiles.txt reads them as the eye's opening f12, negated, so that sad
    droops the lids; the paper's worked example combines them as printed)."""
    converter = load_default_converter(additions=False)
    printed = parse_profiles(
        "Sadness 0\nF19 [-265, -41], F20 [-270, -52], F21 [-265, -41], F22 [-270, -52], "
        "F31 [30, 140], F32 [26, 134]\n"
    ).profiles[0]
    profiles = tuple(printed if p.key == ("sadness", 0) else p for p in converter.profiles.profiles)
    return dataclasses.replace(converter, profiles=ProfileSet(profiles))


def test_guilty_between_afraid_and_sad_follows_seed_001_table_8() -> None:
    guilty = printed_sadness_converter().for_word("guilty")
    assert guilty.rule == "between" and guilty.sources == ("Fear 8", "Sadness 0")
    assert_ranges_close(guilty.as_dict(), GUILTY, tolerance=5)


def test_guilty_from_the_shipped_files_drops_the_lids_that_fear_and_sadness_move_apart() -> None:
    """Fear 8 widens the eyes, Sadness 0 (read as f12) droops the lids:
    opposite signs whose translated ranges do not meet (rule 3), so guilty
    keeps the rest of Table 8 (and the lip corners sadness's additions
    bring, halved by rule 4) but no F19..F22."""
    guilty = load_default_converter(additions=False).for_word("guilty").as_dict()
    assert not set(guilty) & {19, 20, 21, 22}
    table_8 = {fap: r for fap, r in GUILTY.items() if fap not in (19, 20, 21, 22)}
    assert_ranges_close(guilty, table_8, tolerance=5)
    with_additions = load_default_converter().for_word("guilty").as_dict()
    assert with_additions[12].center == pytest.approx(-220 * 4.0 / (2 * 3.9), abs=1)


def test_guilty_fap19_intermediate_numbers_of_equation_12() -> None:
    # t(X_F,19) = 4/4.9 [-630, -570] ~ [-510, -460]; t(X_S,19) = 4/3.9 [-265, -41] ~ [-270, -42]
    fear = FapRange(-630, -570).scaled(4 / 4.9)
    sad = FapRange(-265, -41).scaled(4 / 3.9)
    assert (fear.low, fear.high) == pytest.approx((-510, -460), abs=6)
    assert (sad.low, sad.high) == pytest.approx((-270, -42), abs=2)
    w_fear, w_sad = angular_weights(70.3, 102.3, 108.5)
    # with the paper's rounded centres and lengths, c = -209 and s = 199
    result = weighted_range(-485, 50, -156, 228, w_fear, w_sad)
    assert result.center == pytest.approx(-209, abs=0.5)
    assert result.length == pytest.approx(199, abs=0.5)


def test_the_printed_weight_formula_contradicts_seed_001s_own_example() -> None:
    # Equations (5)-(6) as printed put (w_I - w_A1)/(w_A2 - w_A1) on A1 (fear);
    # that gives a centre near fear's -485, not the paper's -209.
    w_fear, w_sad = angular_weights(70.3, 102.3, 108.5, "as-printed")
    printed = weighted_range(-485, 50, -156, 228, w_fear, w_sad)
    assert printed.center == pytest.approx(-432, abs=1)


def test_seed_000_fap20_example_with_the_printed_weights_and_its_own_centres() -> None:
    # Seed 000 section 6.2: anger (225 deg, activation 4.2, profile 1) and joy
    # (315 deg, 5.4, profile 3), emotion at 261 deg and activation 3.8.
    anger = FapRange(-335, -205).scaled(3.8 / 4.2)
    joy = FapRange(-426, -302).scaled(3.8 / 5.4)
    assert (round(anger.low), round(anger.high)) == (-303, -185)  # (6.7)
    assert (round(joy.low), round(joy.high)) == (-300, -213)  # (6.8)
    assert joy.center == pytest.approx(-256.5, abs=0.5) and joy.length == pytest.approx(87, abs=0.5)
    w_anger, w_joy = angular_weights(225, 261, 315, "as-printed")
    assert (w_anger, w_joy) == pytest.approx((0.4, 0.6))  # (6.9), (6.10)
    # the thesis' centre -260 and length 150 for anger are not those of its own
    # translated range [-303, -185] (centre -244, length 118) ...
    assert anger.center == pytest.approx(-244.3, abs=0.1)
    assert anger.length == pytest.approx(117.6, abs=0.1)
    # ... but fed its own numbers, the combination step gives its result exactly
    result = weighted_range(-260, 150, -256.5, 87, w_anger, w_joy)
    assert result.length == pytest.approx(112.2) and result.center == pytest.approx(-257.9)
    assert (round(result.low), round(result.high)) == (-314, -202)


def test_seed_000_fap20_example_through_the_converter() -> None:
    converter = load_default_converter()
    choices = {"anger": 1, "joy": 3}
    printed = load_default_converter().__class__(
        converter.profiles, converter.wheels, converter.vocabulary, weighting="as-printed"
    )
    # corrected arithmetic, printed weights: [-301, -202]; interpolation: [-302, -196]
    as_printed = printed.for_point(261, 3.8, wheel="ideal", choices=choices).as_dict()[20]
    assert (round(as_printed.low), round(as_printed.high)) == (-301, -202)
    interpolated = converter.for_point(261, 3.8, wheel="ideal", choices=choices).as_dict()[20]
    assert (round(interpolated.low), round(interpolated.high)) == (-302, -196)


def test_seed_000_fap3_one_sided_example_is_averaged_with_neutral() -> None:
    # FAP 3 only in joy, [195, 205]: (3.8 / (2 * 5.4)) * [195, 205]. The thesis
    # prints [67, 72]; 0.35185 * 195 is 68.6, so its 67 is an arithmetic slip.
    result = between_archetypes({}, 4.2, 225, {3: FapRange(195, 205)}, 5.4, 315, 3.8, 261)[3]
    assert result.low == pytest.approx(68.6, abs=0.05)
    assert round(result.high) == 72


def test_opposite_signs_intersect_and_vanish_when_disjoint() -> None:
    overlapping = between_archetypes(
        {7: FapRange(-100, 50)}, 1.0, 0, {7: FapRange(-20, 200)}, 1.0, 90, 1.0, 45
    )
    assert ranges(overlapping) == {7: (-20, 50)}
    disjoint = between_archetypes(
        {7: FapRange(-100, -50)}, 1.0, 0, {7: FapRange(50, 100)}, 1.0, 90, 1.0, 45
    )
    assert disjoint == {}


def test_interpolation_is_continuous_at_the_archetypes() -> None:
    for converter, faps in (
        (load_default_converter(), (31,)),  # in both fear 8 and sadness 0, same sign
        (printed_sadness_converter(), (19, 31)),
    ):
        near_fear = converter.for_point(70.3 + 1e-4, 4.9).as_dict()
        fear = converter.for_point(70.3, 4.9).as_dict()
        for fap in faps:
            assert near_fear[fap].center == pytest.approx(fear[fap].center, abs=0.01)


def test_additions_add_faps_and_never_change_a_range_of_table_5() -> None:
    table_5 = load_default_converter(additions=False).profiles
    shipped = load_default_converter().profiles
    added = 0
    for profile in table_5.profiles:
        merged = shipped.get(profile.archetype, profile.number).as_dict()
        assert {f: merged[f] for f in profile.as_dict()} == profile.as_dict()
        added += len(merged) - len(profile.as_dict())
    assert added > 0
    assert shipped.get("sadness", 0).as_dict()[12].high < 0  # lip corners down
    assert shipped.get("anger", 0).as_dict()[5].low > 0  # lower lip up: pressed lips
    assert shipped.get("disgust", 0).as_dict()[63].low > 0  # nose wrinkle


def test_an_addition_may_not_repeat_a_faps_range_or_name_no_profile() -> None:
    profiles = parse_profiles("Sadness 0\nF31 [30, 140]\n")
    with pytest.raises(ConversionError, match="repeats F31"):
        add_ranges(profiles, parse_profiles("Sadness 0\nF31 [0, 10]\n"))
    with pytest.raises(ConversionError, match="no profile"):
        add_ranges(profiles, parse_profiles("Anger 7\nF5 [0, 10]\n"))


def test_wheel_points_wrap_around_zero() -> None:
    converter = load_default_converter()
    # between joy (323.4) and fear (70.3) on the measured wheel
    a = converter.for_point(10, 4.0)
    b = converter.for_point(370, 4.0)
    assert a.sources == ("Joy 1", "Fear 8") and a.as_dict() == b.as_dict()


def test_profiles_can_be_chosen_by_their_table_5_number() -> None:
    converter = load_default_converter()
    chosen = converter.for_word("afraid", choices={"fear": 3})
    assert chosen.sources == ("Fear 3",) and 37 in chosen.as_dict()
    with pytest.raises(ConversionError, match="fear 12"):
        converter.for_word("afraid", choices={"fear": 12})
    with pytest.raises(ConversionError):
        converter.for_word("afraid", choices={"boredom": 1})


def test_words_without_activation_need_one_and_unknown_words_are_refused() -> None:
    converter = load_default_converter()
    with pytest.raises(ConversionError, match="activation"):
        converter.for_word("accepting")
    assert converter.for_word("accepting", activation=3.0).rule == "between"
    assert converter.for_word("anger").sources == ("Anger 0",)  # ideal wheel archetype
    with pytest.raises(ConversionError, match="boredom"):
        converter.for_word("boredom")
    with pytest.raises(ConversionError):
        converter.for_point(90, 0.0)


def test_the_midpoints_are_the_fap_values_to_animate() -> None:
    values = load_default_converter().for_word("afraid").configuration().as_dict()
    assert values[3] == 480 and values[19] == -600 and len(values) == 12


def test_every_emotion_data_file_round_trips() -> None:
    converter = load_default_converter()
    assert parse_profiles(format_profiles(converter.profiles)) == converter.profiles
    assert parse_wheels(format_wheels(converter.wheels)) == converter.wheels
    assert parse_vocabulary(format_vocabulary(converter.vocabulary)) == converter.vocabulary


def test_profile_lines_accept_a_bare_zero_and_report_errors_with_lines() -> None:
    parsed = parse_profiles("Fear 5\nF37 0, F38 [0, 0]\n").get("fear", 5).as_dict()
    assert ranges(parsed) == {37: (0, 0), 38: (0, 0)}
    with pytest.raises(DataFileError) as caught:
        parse_profiles("Fear 1\nF3 [400, 560], G5 [1, 2]\n", source="p.txt")
    assert caught.value.line == 2
    with pytest.raises(DataFileError):
        parse_profiles("Fear\nF3 [400, 560]\n")
