"""Influence ellipsoids, easing, Bezier smoothing, raised cosine and vertex masks.

Seed 000 §4.3.3-4.3.4, on a row of vertices 1 mm apart along +x from the
feature point (FAP 4, lower_t_midlip: down, 1 unit = 1e-5 m here).
"""

from __future__ import annotations

import numpy as np
import pytest

from realizer.face.deform import deform, ease_exponent, smooth_falloff
from realizer.face.errors import FaceError
from realizer.face.model import (
    CosineDeformer,
    EaseDeformer,
    PointDeformer,
    SmoothDeformer,
)

from .helpers import SPACING_M, UNIT_M, fap_vector, line_face

DOWN = (0.0, -1.0, 0.0)
VALUE = 100.0  # the feature point moves 1 mm down
# the sphere's radius, between vertices so float32 positions cannot blur the edge
SIZE = 0.0095


def drop(face, value: float = VALUE) -> np.ndarray:
    """How far each vertex moved down, in multiples of the feature point's travel."""
    out = deform(face, fap_vector({4: value})).astype(np.float64)
    return (face.vertices[:, 1] - out[:, 1]) / (value * UNIT_M)


def test_linear_falloff_reaches_zero_at_the_sphere():
    face = line_face((EaseDeformer(4, DOWN, SIZE),))
    influence = drop(face)
    expected = np.maximum(0.0, 1.0 - np.arange(60) * SPACING_M / SIZE)
    assert influence == pytest.approx(expected, abs=1e-5)
    assert set(np.flatnonzero(influence)) == set(range(10))  # exactly the inside


def test_scaling_stretches_the_sphere_into_an_ellipsoid():
    face = line_face((EaseDeformer(4, DOWN, SIZE, scale=(2.5, 1.0, 1.0)),))
    influence = drop(face)
    assert influence[10] == pytest.approx(1 - 0.010 / (2.5 * SIZE), abs=1e-5)
    assert set(np.flatnonzero(influence)) == set(range(24))


@pytest.mark.parametrize(
    ("ease", "exponent"),
    [(-100, 0.0), (-50, 0.5), (-20, 0.8), (0, 1.0), (20, 2.0), (50, 3.5), (100, 6.0)],
)
def test_the_easing_exponent_follows_seed_000(ease, exponent):
    assert ease_exponent(ease) == pytest.approx(exponent)


@pytest.mark.parametrize("ease", [-50.0, 50.0])
def test_easing_raises_the_influence_to_its_exponent(ease):
    face = line_face((EaseDeformer(4, DOWN, SIZE, ease=ease),))
    influence = drop(face)
    linear = np.maximum(0.0, 1.0 - np.arange(60) * SPACING_M / SIZE)
    assert influence == pytest.approx(linear ** ease_exponent(ease), abs=1e-5)
    # negative e widens (curve above the line), positive e narrows; the same vertices move
    inner = slice(1, 10)
    if ease < 0:
        assert (influence[inner] > linear[inner]).all()
    else:
        assert (influence[inner] < linear[inner]).all()
    assert set(np.flatnonzero(influence)) == set(range(10))
    assert influence[0] == pytest.approx(1.0, abs=1e-6)


def test_an_ease_outside_minus_100_to_100_is_rejected():
    with pytest.raises(FaceError):
        deform(line_face((EaseDeformer(4, DOWN, SIZE, ease=150.0),)), fap_vector({4: 1.0}))


def test_smoothing_with_zero_center_and_side_is_linear():
    r = np.linspace(0, 1.2, 50)
    assert smooth_falloff(r, 0.0, 0.0) == pytest.approx(np.maximum(0, 1 - r), abs=1e-9)


def test_smoothing_flattens_both_ends_and_enlarges_the_sphere():
    face = line_face((SmoothDeformer(4, DOWN, SIZE, smooth_center=50.0, smooth_side=50.0),))
    influence = drop(face)
    # the sphere grows to 1 + (0.5 + 0.5)/2 = 1.5 times its size: vertices 0..14 move
    assert set(np.flatnonzero(influence > 1e-9)) == set(range(15))
    # symmetric control points: half influence halfway out
    r = np.array([0.75])
    assert smooth_falloff(r, 50.0, 50.0)[0] == pytest.approx(0.5, abs=1e-6)
    # flat at the centre and at the rim: slope near 0 at both ends
    eps = 1e-3
    near = smooth_falloff(np.array([0.0, eps, 1.5 - eps, 1.5]), 50.0, 50.0)
    assert (near[0] - near[1]) / eps < 0.05
    assert (near[2] - near[3]) / eps < 0.05
    assert influence[0] == pytest.approx(1.0, abs=1e-6)


def test_raised_cosine_falloff():
    face = line_face((CosineDeformer(4, DOWN, SIZE),))
    influence = drop(face)
    r = np.arange(60) * SPACING_M / SIZE
    expected = np.where(r < 1, 0.5 * (1 + np.cos(np.pi * np.minimum(r, 1))), 0)
    assert influence == pytest.approx(expected, abs=1e-5)


MASK = (2, 3, 4, 5)


def test_a_used_vertex_mask_lets_only_its_vertices_move():
    face = line_face(
        (EaseDeformer(4, DOWN, SIZE, use_vertex_mask=True),),
        masks={4: MASK},
        points={"2.2": (0.003, 0.0, 0.0)},  # the centre at vertex 3
    )
    influence = drop(face)
    assert set(np.flatnonzero(influence)) == set(MASK)


def test_an_inverted_mask_holds_its_vertices_still():
    face = line_face(
        (EaseDeformer(4, DOWN, SIZE, use_vertex_mask=True, invert_vertex_mask=True),),
        masks={4: MASK},
    )
    influence = drop(face)
    assert set(np.flatnonzero(influence)) == set(range(10)) - set(MASK)


def test_an_unused_mask_changes_nothing():
    face = line_face(
        (EaseDeformer(4, DOWN, SIZE, use_vertex_mask=False, invert_vertex_mask=True),),
        masks={4: MASK},
    )
    assert set(np.flatnonzero(drop(face))) == set(range(10))


def test_a_point_deformer_moves_only_the_feature_point_vertex():
    face = line_face((PointDeformer(4, DOWN),))
    influence = drop(face)
    assert np.flatnonzero(influence).tolist() == [0]
    assert influence[0] == pytest.approx(1.0)


def test_only_the_named_part_moves():
    parts = {"skin": np.arange(0, 5), "tongue": np.arange(5, 60)}
    face = line_face(
        (EaseDeformer(4, DOWN, SIZE, part="tongue", feature_point="2.2"),), parts=parts
    )
    assert set(np.flatnonzero(drop(face))) == set(range(5, 10))


def test_a_direction_against_the_standard_is_rejected():
    face = line_face((EaseDeformer(4, (0.0, 1.0, 0.0), SIZE),))
    with pytest.raises(FaceError, match="down"):
        deform(face, fap_vector({4: 1.0}))


def test_the_lip_masks_of_the_test_head_keep_the_other_lip_still():
    from realizer.face.testhead import build_test_head

    head = build_test_head()
    lips = head.part("lips")
    mouth_y = head.vertices[lips, 1].mean()
    for number, still_side in ((4, -1), (51, -1), (5, +1), (52, +1)):
        out = deform(head, fap_vector({number: 300.0}))
        moved = np.flatnonzero(np.any(out != head.vertices, axis=1))
        assert moved.size > 0
        side = np.sign(head.vertices[moved, 1] - mouth_y)
        assert (side != still_side).all(), number
