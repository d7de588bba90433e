"""FAPU from feature points (seed 002 Table 1) and FAP frames."""

from __future__ import annotations

import numpy as np
import pytest

from realizer.face.errors import FaceError, FapValueError
from realizer.face.fapu import ANGLE_UNIT_RAD, Fapu
from realizer.face.frame import FapFrame
from realizer.face.testhead import build_test_head

from .helpers import FAPU_POINTS


def test_fapu_are_key_distances_divided_by_1024():
    fapu = Fapu.from_feature_points(FAPU_POINTS)
    assert fapu.irisd == pytest.approx(0.01 / 1024)
    assert fapu.es == pytest.approx(0.06 / 1024)
    assert fapu.ens == pytest.approx((0.045 - 0.01024) / 1024)
    assert fapu.mns == pytest.approx(0.01024 / 1024)
    assert fapu.mw == pytest.approx(0.01024 / 1024)
    assert fapu.au == ANGLE_UNIT_RAD == 1e-5


def test_the_unit_of_each_fap_follows_table_7():
    fapu = Fapu.from_feature_points(FAPU_POINTS)
    per_fap = fapu.per_fap()
    assert per_fap.shape == (68,)
    assert per_fap[0] == per_fap[1] == 0.0
    assert per_fap[3 - 1] == fapu.mns
    assert per_fap[6 - 1] == fapu.mw
    assert per_fap[19 - 1] == fapu.irisd
    assert per_fap[48 - 1] == fapu.au
    assert per_fap[61 - 1] == fapu.ens


def test_the_test_head_has_plausible_fapu():
    fapu = build_test_head().fapu
    # a human-sized head: eyes 4-8 cm apart, mouth 3-7 cm wide
    assert 0.04 < fapu.es * 1024 < 0.08
    assert 0.03 < fapu.mw * 1024 < 0.07
    assert 0 < fapu.mns * 1024 < fapu.ens * 1024


def test_swapped_left_and_right_is_an_error():
    points = dict(FAPU_POINTS)
    points["3.5"], points["3.6"] = points["3.6"], points["3.5"]
    with pytest.raises(FaceError, match="ES"):
        Fapu.from_feature_points(points)


def test_a_missing_feature_point_is_named():
    points = dict(FAPU_POINTS)
    del points["9.15"]
    with pytest.raises(FaceError, match=r"9\.15"):
        Fapu.from_feature_points(points)


def test_a_frame_holds_values_mask_time_and_number():
    frame = FapFrame.from_mapping({3: 400.0, 31: -200.0}, time=1.5, number=7)
    assert frame.values[2] == 400.0 and frame.mask[2] and not frame.mask[3]
    assert frame.vector[30] == -200.0
    assert (frame.time, frame.number) == (1.5, 7)
    with pytest.raises(ValueError):
        frame.values[0] = 1.0  # read-only


def test_unset_values_do_not_reach_the_vector():
    values = np.zeros(68)
    values[4] = 99.0
    frame = FapFrame(values, np.zeros(68, dtype=bool))
    assert not frame.vector.any()
    assert frame == FapFrame(values, np.zeros(68, dtype=bool))


def test_bad_frames_are_rejected():
    with pytest.raises(FapValueError):
        FapFrame(np.zeros(5), np.zeros(5, dtype=bool))
    with pytest.raises(FapValueError):
        FapFrame.from_mapping({69: 1.0})
