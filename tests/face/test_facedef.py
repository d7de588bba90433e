"""FaceDefMesh and FaceDefTransform (seed 002 §2.1.3.4, Table 5)."""

from __future__ import annotations

import numpy as np
import pytest

from realizer.face.deform import deform
from realizer.face.errors import FaceError
from realizer.face.facedef import FaceDefMesh, interval_weights, parse_facedef_mesh_text
from realizer.face.model import TransformDeformer

from .helpers import UNIT_M, fap_vector, line_face

TABLE_5 = """\
#FaceDefMesh
FAP 6 (stretch left corner lip)
IndexedFaceSet: Face
interval borders: -1000, 0, 500, 1000
displacements:
vertex 50 1 0 0, 0.9 0 0, 1.5 0 4
vertex 51 0.8 0 0, 0.7 0 0, 2 0 0
"""


@pytest.fixture(scope="module")
def table() -> FaceDefMesh:
    return parse_facedef_mesh_text(TABLE_5)


def test_the_table_5_text_is_read(table):
    assert table.fap == 6 and table.target == "Face"
    assert table.intervals == (-1000.0, 0.0, 500.0, 1000.0)
    assert table.vertices == (50, 51)
    assert table.displacements[0] == ((1, 0, 0), (0.9, 0, 0), (1.5, 0, 4))


def face_with(*settings):
    return line_face(tuple(settings))  # MW = 1e-5 m


def displacement(face, vertex: int, value: float) -> np.ndarray:
    out = deform(face, fap_vector({6: value})).astype(np.float64)
    return (out[vertex] - face.vertices[vertex]) / UNIT_M


def test_the_seed_002_example_fap_6_at_600_moves_vertex_50_by_600_0_400_fapu(table):
    face = face_with(table)
    assert displacement(face, 50, 600.0) == pytest.approx([600.0, 0.0, 400.0], abs=1e-2)
    # vertex 51: 500 * 0.7 + 100 * 2
    assert displacement(face, 51, 600.0) == pytest.approx([550.0, 0.0, 0.0], abs=1e-2)
    # no other vertex moves
    out = deform(face, fap_vector({6: 600.0}))
    assert set(np.flatnonzero(np.any(out != face.vertices, axis=1))) == {50, 51}


def test_values_beyond_the_last_border_continue_its_slope(table):
    face = face_with(table)
    # 500 * 0.9 + 700 * 1.5 = 1500; z: 700 * 4 = 2800
    assert displacement(face, 50, 1200.0) == pytest.approx([1500.0, 0.0, 2800.0], abs=1e-1)


def test_negative_values_move_back_along_the_first_interval(table):
    # continuous path of Figure 5 (see the module docstring of facedef for the sign)
    face = face_with(table)
    assert displacement(face, 50, -200.0) == pytest.approx([-200.0, 0.0, 0.0], abs=1e-2)
    assert displacement(face, 51, -200.0) == pytest.approx([-160.0, 0.0, 0.0], abs=1e-2)


def test_the_path_is_continuous_at_the_borders(table):
    weights = interval_weights(np.asarray(table.intervals), np.array([499.999, 500.0, 500.001]))
    assert np.abs(np.diff(weights, axis=0)).max() < 0.01


def test_one_interval_is_plain_linear():
    single = FaceDefMesh(6, (-1000.0, 1000.0), (3,), (((2.0, 1.0, 0.0),),))
    face = face_with(single)
    for value in (-300.0, 250.0, 1500.0):
        assert displacement(face, 3, value) == pytest.approx([2 * value, value, 0.0], abs=1e-2)


def test_bad_tables_are_rejected():
    with pytest.raises(FaceError):
        FaceDefMesh(6, (0.0, -1.0), (1,), (((1.0, 0.0, 0.0),),))
    with pytest.raises(FaceError):
        FaceDefMesh(6, (-1.0, 0.0, 1.0), (1,), (((1.0, 0.0, 0.0),),))


def test_the_facedeftransform_example_turns_the_left_eye_about_minus_y():
    # Table 5: FAP 23 rotates LeftEyeX about (0, -1, 0) with angle scale 1
    count = 60
    parts = {"skin": np.arange(0, 50), "left_eye": np.arange(50, count)}
    transform = TransformDeformer(
        23, ("left_eye",), "rotation", (0.0, -1.0, 0.0), 1.0, pivot=(0.05, 0.0, -0.01)
    )
    face = line_face((transform,), parts=parts)
    value = 10000.0  # 0.1 rad
    out = deform(face, fap_vector({23: value})).astype(np.float64)
    pivot = np.array([0.05, 0.0, -0.01])
    gaze_before = np.array([0.0, 0.0, 1.0])
    rel_before = face.vertices[50:].astype(np.float64) - pivot
    rel_after = out[50:] - pivot
    # rotation about -y by 0.1 rad: +z turns towards -x
    angle = -0.1
    rot = np.array(
        [[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]]
    )
    assert rel_after == pytest.approx(rel_before @ rot.T, abs=1e-7)
    assert (rot @ gaze_before)[0] < 0
    assert not (out[:50] - face.vertices[:50]).any()
