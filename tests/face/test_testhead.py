"""The procedural test head: feature points known by construction, settings for every FAP."""

from __future__ import annotations

import numpy as np

from realizer.face.faps import FAP_TABLE
from realizer.face.features import FEATURE_POINTS
from realizer.face.testhead import build_test_head

HEAD = build_test_head()


def test_it_has_the_named_parts():
    for part in (
        "skin",
        "left_eye",
        "right_eye",
        "left_pupil",
        "right_pupil",
        "upper_teeth",
        "lower_teeth",
        "tongue",
    ):
        assert HEAD.part(part).size > 0
    assert HEAD.part("eyes").size == HEAD.part("left_eye").size + HEAD.part("right_eye").size


def test_every_fap_driven_feature_point_is_a_vertex():
    for info in FAP_TABLE.values():
        for point in info.feature_points:
            vertex = HEAD.feature_vertex(point)
            assert np.allclose(HEAD.vertices[vertex], HEAD.feature_position(point), atol=1e-9)


def test_the_left_side_is_plus_x():
    for left, right in (
        ("3.5", "3.6"),
        ("8.3", "8.4"),
        ("2.4", "2.5"),
        ("10.1", "10.2"),
        ("4.1", "4.2"),
        ("6.3", "6.4"),
        ("9.1", "9.2"),
    ):
        assert HEAD.feature_position(left)[0] > 0 > HEAD.feature_position(right)[0]


def test_midline_points_share_the_x_of_the_spine():
    for point in ("2.1", "2.2", "2.3", "8.1", "8.2", "9.3", "9.15", "6.1", "6.2", "11.4"):
        assert FEATURE_POINTS[point].constraint_x == "7.1.x"
        assert abs(HEAD.feature_position(point)[0] - HEAD.feature_position("7.1")[0]) < 1e-9


def test_every_fap_from_3_to_68_has_a_setting():
    for number in range(3, 69):
        assert HEAD.params.deformers_for(number), FAP_TABLE[number].name


def test_the_mesh_is_consistent():
    assert HEAD.vertices.dtype == np.float32 and HEAD.faces.dtype == np.int32
    assert HEAD.faces.max() < HEAD.vertex_count
    assert HEAD.triangles is HEAD.faces
