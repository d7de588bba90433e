"""The FAP and feature point tables transcribed from seed 002 Tables 6 and 7."""

from __future__ import annotations

import numpy as np
import pytest

from realizer.face.errors import FapValueError
from realizer.face.faps import (
    FAP_TABLE,
    as_fap_vector,
    check_fap_vector,
    clamp_unidirectional,
    fap,
)
from realizer.face.features import FEATURE_POINTS


def test_the_table_has_the_68_faps_in_order():
    assert sorted(FAP_TABLE) == list(range(1, 69))
    assert [FAP_TABLE[n].number for n in range(1, 69)] == list(range(1, 69))


def test_rows_carry_every_column_of_table_7():
    jaw = fap(3)
    assert (jaw.name, jaw.unit, jaw.bidirectional) == ("open_jaw", "MNS", False)
    assert jaw.direction == "down"
    assert (jaw.group, jaw.feature_points, jaw.quant_step) == (2, ("2.1",), 4)
    assert (jaw.iframe_min, jaw.iframe_max, jaw.pframe_min, jaw.pframe_max) == (0, 1080, 0, 360)
    head = fap("head_pitch")
    assert (head.number, head.unit, head.quant_step, head.feature_points) == (48, "AU", 170, ())
    assert (head.iframe_min, head.iframe_max) == (-1860, 1860)
    roll = fap(47)
    assert roll.feature_points == ("6.3", "6.4")
    assert roll.direction == "concave upward"
    assert fap(18).description.endswith("(like in sadness)")
    assert fap(51).name == "lower_t_midlip_o"


def test_the_unidirectional_faps_are_those_marked_u():
    assert [n for n, info in FAP_TABLE.items() if info.unidirectional] == [3, 14, 41, 42, 47]


def test_units_per_group_match_the_table():
    assert {fap(n).unit for n in (19, 20, 21, 22, 29, 30)} == {"IRISD"}
    assert {fap(n).unit for n in (23, 24, 25, 26, 47, 48, 49, 50)} == {"AU"}
    assert fap(6).unit == fap(53).unit == fap(15).unit == "MW"
    assert fap(37).unit == fap(39).unit == "ES"


def test_left_is_plus_x_and_right_is_minus_x():
    assert fap("stretch_l_cornerlip").axis == (1.0, 0.0, 0.0)
    assert fap("stretch_r_cornerlip").axis == (-1.0, 0.0, 0.0)
    assert fap("squeeze_l_eyebrow").axis == (-1.0, 0.0, 0.0)  # "right": towards the middle
    assert fap("open_jaw").axis == (0.0, -1.0, 0.0)
    assert fap("thrust_jaw").axis == (0.0, 0.0, 1.0)
    assert fap("yaw_l_eyeball").axis is None


def test_the_feature_point_table_has_84_points_with_constraints():
    assert len(FEATURE_POINTS) == 84
    assert FEATURE_POINTS["2.1"].constraint_x == "7.1.x"
    assert FEATURE_POINTS["5.3"].constraint_y == "> 9.15.y and < 9.12.y"
    assert FEATURE_POINTS["6.3"].constraint_z == "6.2.z"
    assert FEATURE_POINTS["7.1"].description.startswith("top of spine")
    for info in FAP_TABLE.values():
        for point in info.feature_points:
            assert point in FEATURE_POINTS


def test_a_fap_vector_must_have_68_finite_values():
    with pytest.raises(FapValueError):
        as_fap_vector(np.zeros(67))
    with pytest.raises(FapValueError):
        as_fap_vector(np.full(68, np.nan))


def test_negative_unidirectional_values_are_clamped_or_rejected():
    vector = np.zeros(68)
    vector[2] = -100.0  # open_jaw
    vector[3] = -100.0  # lower_t_midlip, bidirectional
    clamped = clamp_unidirectional(vector)
    assert clamped[2] == 0.0 and clamped[3] == -100.0
    with pytest.raises(FapValueError, match="open_jaw"):
        check_fap_vector(vector)


def test_the_package_exports_resolve():
    import realizer.face as face_package
    from realizer.face.faps import FAP_TABLE as TABLE

    assert face_package.FAP_TABLE is TABLE
    assert callable(face_package.rig_for) and callable(face_package.build_test_head)
    assert face_package.Face.__name__ == "Face"
    with pytest.raises(AttributeError):
        face_package.no_such_name  # noqa: B018
