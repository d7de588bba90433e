"""How the displacements of several FAPs on one vertex combine (docs/face-model.md).

Per axis and sign, the contributions are summed and capped at the largest
single FAP amplitude reaching the vertex. Seed 000 §4.3.1 averaged instead,
which gives the w-shaped lip of its Figure 7.1; plain summing bulges.
"""

from __future__ import annotations

import numpy as np
import pytest

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
