"""How the displacements of several FAPs on one vertex combine (docs/face-model.md).

Per axis and sign, the contributions are summed and capped at the largest
single FAP amplitude reaching the vertex. Seed 000 §4.3.1 averaged instead,
which gives the w-shaped lip of its Figure 7.1; plain summing bulges.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from realizer.face.deform import deform
from realizer.face.model import EaseDeformer

from .helpers import SPACING_M, UNIT_M, fap_vector, line_face

DOWN = (0.0, -1.0, 0.0)
LEFT = (1.0, 0.0, 0.0)
SIZE = 0.0095
# FAP 4 centred on vertex 0 (2.2), FAP 8 on vertex 6 (2.6), FAP 6 on vertex 0 (2.4)
FACE = line_face(
    (EaseDeformer(4, DOWN, SIZE), EaseDeformer(8, DOWN, SIZE), EaseDeformer(6, LEFT, SIZE)),
    points={"2.6": (0.006, 0.0, 0.0), "2.4": (0.0, 0.0, 0.0)},
)
X = np.arange(60) * SPACING_M


def influence(centre: float) -> np.ndarray:
    return np.maximum(0.0, 1.0 - np.abs(X - centre) / SIZE)


def offsets(values: dict[int, float]) -> np.ndarray:
    """Vertex offsets in units of 1e-5 m (one FAP unit here)."""
    out = deform(FACE, fap_vector(values)).astype(np.float64)
    return (out - FACE.vertices) / UNIT_M


def test_one_fap_alone_moves_each_vertex_by_its_influence():
    down = -offsets({4: 100.0})[:, 1]
    assert down == pytest.approx(100.0 * influence(0.0), abs=1e-3)


def test_a_feature_point_moves_exactly_by_its_own_fap_despite_a_neighbour():
    down = -offsets({4: 100.0, 8: 100.0})[:, 1]
    assert down[0] == pytest.approx(100.0, abs=1e-3)  # a plain sum would give 136.8
    assert down[6] == pytest.approx(100.0, abs=1e-3)
    # and when the neighbour pushes less, the feature point still moves exactly 100
    down = -offsets({4: 100.0, 8: 50.0})[:, 1]
    assert down[0] == pytest.approx(100.0, abs=1e-3)


def test_equal_neighbours_keep_the_lip_flat_between_them():
    down = -offsets({4: 100.0, 8: 100.0})[:, 1]
    # no dip (the w of averaging) and no bulge (summing) between the two points
    assert down[0:7] == pytest.approx(np.full(7, 100.0), abs=1e-3)


def test_below_the_cap_contributions_add():
    down = -offsets({4: 100.0, 8: 100.0})[:, 1]
    expected = 100.0 * (influence(0.0) + influence(0.006))
    assert down[8] == pytest.approx(expected[8], abs=1e-3)  # 94.7 < 100
    assert down[12] == pytest.approx(expected[12], abs=1e-3)  # FAP 8 alone there


def test_faps_along_different_axes_add_independently():
    both = offsets({4: 100.0, 6: 80.0})
    down_alone = offsets({4: 100.0})
    left_alone = offsets({6: 80.0})
    assert both[:, 1] == pytest.approx(down_alone[:, 1], abs=1e-3)
    assert both[:, 0] == pytest.approx(left_alone[:, 0], abs=1e-3)


def test_opposite_pushes_cancel():
    down = -offsets({4: 100.0, 8: -100.0})[:, 1]
    assert down[3] == pytest.approx(0.0, abs=1e-3)
    assert down[0] == pytest.approx(100.0 * (1.0 - influence(0.006)[0]), abs=1e-3)


def test_the_rule_is_continuous_in_every_value():
    base = offsets({4: 100.0})
    nudged = offsets({4: 100.0, 8: 1e-3})
    assert np.abs(nudged - base).max() < 1e-2  # i.e. < 1e-7 m for 1e-3 units


def test_one_fap_is_linear_in_its_value():
    assert offsets({4: 200.0}) == pytest.approx(2 * offsets({4: 100.0}), abs=1e-3)
    assert offsets({4: -100.0}) == pytest.approx(-offsets({4: 100.0}), abs=1e-3)


# Seed 000 Figure 7.1: three upper-lip points raised together, the middle one with
# an influence sphere that is too large. Side points at 10 and 30 mm, the middle
# one at 20 mm; sizes 9.5 mm (sides) and 15.5 mm (middle).
LIP = line_face(
    (
        EaseDeformer(56, DOWN, SIZE),
        EaseDeformer(51, DOWN, 0.0155),
        EaseDeformer(55, DOWN, SIZE),
    ),
    points={"8.6": (0.010, 0.0, 0.0), "8.1": (0.020, 0.0, 0.0), "8.5": (0.030, 0.0, 0.0)},
)
THREE = {56: 100.0, 51: 100.0, 55: 100.0}


def seed_000_average(face, values: dict[int, float]) -> np.ndarray:
    """FaceEditor's rule (seed 000 §4.3.1): average the displacements a vertex gets."""
    singles = np.stack(
        [
            (deform(face, fap_vector({number: value})) - face.vertices).astype(np.float64)
            for number, value in values.items()
        ]
    )
    reached = np.any(singles != 0, axis=2).sum(axis=0)
    total = singles.sum(axis=0)
    return total / np.maximum(reached, 1)[:, None] / UNIT_M


def test_averaging_makes_the_w_shaped_lip_of_seed_000_figure_7_1():
    down = -seed_000_average(LIP, THREE)[:, 1]
    # the side points do not reach their FAP's 100 units: the lip sags beside the middle
    assert down[10] < 75.0 and down[30] < 75.0
    assert down[20] == pytest.approx(100.0, abs=1e-3)
    # a dip between a side point and the middle: a w, not a flat lip
    assert down[15] < down[10]


def test_our_rule_raises_all_three_points_fully_and_keeps_the_lip_flat():
    down = -(deform(LIP, fap_vector(THREE)) - LIP.vertices)[:, 1].astype(np.float64) / UNIT_M
    assert down[[10, 20, 30]] == pytest.approx([100.0, 100.0, 100.0], abs=1e-3)
    # between them the lip stays within 2 % of flat (where the spheres barely
    # overlap the sum stays just under the cap), against the 25 %+ sag of averaging
    assert down[10:31].min() > 98.0
    # and never more than the FAPs ask for (a plain sum would bulge to ~190 at 15 mm)
    assert down.max() <= 100.0 + 1e-3


# -- properties over random values -----------------------------------------------------

AMOUNTS = st.floats(-500.0, 500.0, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(a4=AMOUNTS, a8=AMOUNTS, a6=AMOUNTS)
def test_no_vertex_moves_further_than_the_largest_fap_reaching_it(a4, a8, a6):
    moved = offsets({4: a4, 8: a8, 6: a6})
    reach4, reach8 = influence(0.0) > 0, influence(0.006) > 0
    # y: FAPs 4 and 8 push along -y by their value
    largest_y = np.maximum(np.abs(a4) * reach4, np.abs(a8) * reach8)
    assert (np.abs(moved[:, 1]) <= largest_y + 1e-3).all()
    # x: FAP 6 alone, exactly linear
    assert moved[:, 0] == pytest.approx(a6 * influence(0.0), abs=1e-3)
    # negating every value mirrors the result
    assert offsets({4: -a4, 8: -a8, 6: -a6}) == pytest.approx(-moved, abs=1e-3)


@settings(max_examples=40, deadline=None)
@given(value=AMOUNTS)
def test_a_single_fap_is_exact_for_any_value(value):
    assert -offsets({8: value})[:, 1] == pytest.approx(value * influence(0.006), abs=1e-3)
