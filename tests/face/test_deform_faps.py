"""Each FAP moves its feature point by value x FAPU in its positive direction.

Seed 002 Table 7 sign conventions, in the frame of docs/face-model.md (+x the
face's own left, +y up, +z the gaze), on the procedural test head.
"""

from __future__ import annotations

import numpy as np
import pytest

from realizer.face.deform import deform
from realizer.face.errors import FapValueError
from realizer.face.faps import FAP_TABLE
from realizer.face.testhead import build_test_head

from .helpers import fap_vector

HEAD = build_test_head()
FAPU = HEAD.fapu.per_fap()

TRANSLATIONAL = [
    n for n in range(3, 69) if FAP_TABLE[n].axis is not None and FAP_TABLE[n].feature_point
]


def moved(values: dict[int, float]) -> np.ndarray:
    return deform(HEAD, fap_vector(values)).astype(np.float64) - HEAD.vertices


def angle_between(a: np.ndarray, b: np.ndarray) -> float:
    cos = a @ b / (np.linalg.norm(a) * np.linalg.norm(b))
    return float(np.arccos(np.clip(cos, -1.0, 1.0)))


def test_the_neutral_vector_gives_the_neutral_face():
    out = deform(HEAD, np.zeros(68))
    assert out.dtype == np.float32 and out.shape == HEAD.vertices.shape
    assert np.array_equal(out, HEAD.vertices)


def test_every_fap_from_3_to_68_moves_the_test_head():
    for number in range(3, 69):
        assert np.abs(moved({number: 300.0})).max() > 1e-6, FAP_TABLE[number].name


# both signs where the FAP is bidirectional; negative unidirectional values are
# clamped (tested below)
CASES = [
    (n, v) for n in TRANSLATIONAL for v in (250.0, -250.0) if v > 0 or FAP_TABLE[n].bidirectional
]


@pytest.mark.parametrize(
    ("number", "value"), CASES, ids=[f"{FAP_TABLE[n].name}{v:+g}" for n, v in CASES]
)
def test_a_fap_moves_its_feature_point_by_value_times_fapu(number: int, value: float):
    info = FAP_TABLE[number]
    vertex = HEAD.feature_vertex(info.feature_point)
    offset = moved({number: value})[vertex]
    axis = np.asarray(info.axis)
    expected = value * FAPU[number - 1]
    assert offset @ axis == pytest.approx(expected, rel=1e-4, abs=1e-9)
    # and in the positive direction of Table 7 for a positive value
    assert np.sign(offset @ axis) == np.sign(value)


def test_a_3d_direction_adds_motion_off_the_standard_axis():
    # FAP 54 on the test head also moves the right lip corner back (z -0.3 per x)
    vertex = HEAD.feature_vertex("8.4")
    offset = moved({54: 200.0})[vertex]
    assert -offset[0] == pytest.approx(200.0 * HEAD.fapu.mw, rel=1e-4)
    assert offset[2] == pytest.approx(-0.3 * 200.0 * HEAD.fapu.mw, rel=1e-3)


@pytest.mark.parametrize("number", [3, 14, 41, 42, 47])
def test_negative_values_of_unidirectional_faps_are_clamped_to_zero(number: int):
    assert np.array_equal(deform(HEAD, fap_vector({number: -300.0})), HEAD.vertices)


def test_faps_1_and_2_are_left_to_the_converters():
    assert np.array_equal(deform(HEAD, fap_vector({1: 10.0, 2: 40.0})), HEAD.vertices)


def test_deform_is_pure():
    vector = fap_vector({3: 300.0, 19: 500.0, 48: 800.0, 53: 100.0})
    copy = vector.copy()
    first = deform(HEAD, vector)
    second = deform(HEAD, vector)
    assert np.array_equal(vector, copy)
    assert np.array_equal(first, second) and first is not second
    assert np.array_equal(deform(HEAD, np.zeros(68)), HEAD.vertices)


def test_a_malformed_vector_is_rejected():
    with pytest.raises(FapValueError):
        deform(HEAD, np.zeros(66))


# -- eyes ------------------------------------------------------------------------------


def eye_centre(side: str) -> np.ndarray:
    return HEAD.vertices[HEAD.part(f"{side}_eye")].astype(np.float64).mean(axis=0)


@pytest.mark.parametrize(
    ("number", "side", "point", "axis", "sign"),
    [
        (23, "left", "3.5", 0, +1),  # yaw "left": the gaze turns to +x
        (24, "right", "3.6", 0, +1),
        (25, "left", "3.5", 1, -1),  # pitch "down": the gaze turns to -y
        (26, "right", "3.6", 1, -1),
    ],
)
def test_eyeballs_turn_by_value_times_au_the_way_table_7_says(number, side, point, axis, sign):
    value = 20000.0  # 0.2 rad
    vertex = HEAD.feature_vertex(point)
    centre = eye_centre(side)
    before = HEAD.vertices[vertex] - centre
    after = deform(HEAD, fap_vector({number: value}))[vertex] - centre
    assert angle_between(before, after) == pytest.approx(value * 1e-5, rel=1e-3)
    assert np.sign(after[axis] - before[axis]) == sign
    # the other eye stays
    other = HEAD.part("right_eye" if side == "left" else "left_eye")
    assert not moved({number: value})[other].any()


@pytest.mark.parametrize(("number", "side"), [(27, "left"), (28, "right")])
def test_eyeball_thrust_moves_the_whole_eye_forward_by_value_times_es(number, side):
    offsets = moved({number: 300.0})[HEAD.part(f"{side}_eye")]
    assert np.allclose(offsets, [0.0, 0.0, 300.0 * HEAD.fapu.es], atol=1e-7)


@pytest.mark.parametrize(("number", "side", "point"), [(29, "left", "3.5"), (30, "right", "3.6")])
def test_pupil_dilation_grows_the_pupil_rim_by_value_times_irisd(number, side, point):
    value = 200.0
    pupil = HEAD.part(f"{side}_pupil")
    centre = HEAD.feature_position(point)
    out = deform(HEAD, fap_vector({number: value})).astype(np.float64)

    def radius(points: np.ndarray) -> np.ndarray:
        rel = points - centre
        return np.linalg.norm(rel[:, :2], axis=1)  # the gaze is +z

    growth = radius(out[pupil]).max() - radius(HEAD.vertices[pupil].astype(np.float64)).max()
    assert growth == pytest.approx(value * HEAD.fapu.irisd, rel=1e-3)
    # the centre of the pupil and the rest of the eye stay
    rest = np.setdiff1d(HEAD.part(f"{side}_eye"), pupil)
    offsets = out - HEAD.vertices
    assert not offsets[rest].any()
    assert np.allclose(offsets[HEAD.feature_vertex(point)], 0.0)


def test_eyes_turn_after_the_pupil_dilates():
    together = deform(HEAD, fap_vector({23: 20000.0, 29: 300.0}))
    pupil = HEAD.part("left_pupil")
    # dilation then rotation preserves the dilated radius around the turned gaze
    centre = eye_centre("left")
    dilated = deform(HEAD, fap_vector({29: 300.0}))
    assert np.allclose(
        np.linalg.norm(together[pupil] - centre, axis=1),
        np.linalg.norm(dilated[pupil] - centre, axis=1),
        atol=1e-7,
    )


# -- jaw -------------------------------------------------------------------------------


def test_open_jaw_lowers_the_lower_teeth_and_tongue_not_the_upper_teeth():
    value = 400.0
    offsets = moved({3: value})
    tip = HEAD.feature_vertex("9.11")
    # the jaw turns about its pivot: the tip of the lower teeth travels value x MNS,
    # mostly downwards
    assert np.linalg.norm(offsets[tip]) == pytest.approx(value * HEAD.fapu.mns, rel=1e-3)
    assert -offsets[tip, 1] > 0.9 * np.linalg.norm(offsets[tip])
    assert (offsets[HEAD.part("tongue"), 1] < 0).all()
    assert not offsets[HEAD.part("upper_teeth")].any()


def test_thrust_and_shift_jaw_translate_the_lower_teeth():
    teeth = HEAD.part("lower_teeth")
    assert np.allclose(moved({14: 300.0})[teeth], [0, 0, 300 * HEAD.fapu.mns], atol=1e-7)
    assert np.allclose(moved({15: 300.0})[teeth], [-300 * HEAD.fapu.mw, 0, 0], atol=1e-7)


# -- tongue ----------------------------------------------------------------------------


def test_tongue_roll_turns_both_borders_up_by_value_times_au():
    value = 10000.0  # 0.1 rad
    offsets = moved({47: value})
    (setting,) = HEAD.params.deformers_for(47)
    pivot = np.asarray(setting.pivot)
    for point in ("6.3", "6.4"):
        vertex = HEAD.feature_vertex(point)
        assert offsets[vertex, 1] > 0
        before = HEAD.vertices[vertex] - pivot
        after = before + offsets[vertex]
        # about the tongue's long axis (+z): compare the xy projections
        assert angle_between(before[:2], after[:2]) == pytest.approx(value * 1e-5, rel=1e-3)
    assert not offsets[HEAD.part("skin")].any()


# -- head ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("number", "point", "axis", "sign", "plane"),
    [
        (48, "9.3", 1, -1, [1, 2]),  # pitch "down" (about x): the nose tip goes down
        (49, "9.3", 0, +1, [0, 2]),  # yaw "left" (about y): the nose tip goes to +x
        (50, "11.4", 0, -1, [0, 1]),  # roll "right" (about z): the skull top goes to -x
    ],
)
def test_the_head_turns_about_the_top_of_the_spine(number, point, axis, sign, plane):
    value = 10000.0  # 0.1 rad
    pivot = HEAD.feature_position("7.1")
    vertex = HEAD.feature_vertex(point)
    before = HEAD.vertices[vertex] - pivot
    out = deform(HEAD, fap_vector({number: value})).astype(np.float64)
    after = out[vertex] - pivot
    assert angle_between(before[plane], after[plane]) == pytest.approx(value * 1e-5, rel=1e-3)
    assert np.linalg.norm(after) == pytest.approx(np.linalg.norm(before), rel=1e-6)
    assert np.sign(after[axis] - before[axis]) == sign
    # every part turns with the head: the mesh is rigidly rotated
    distances = np.linalg.norm(out - pivot, axis=1)
    assert np.allclose(distances, np.linalg.norm(HEAD.vertices - pivot, axis=1), atol=1e-6)


def test_the_head_carries_the_turned_eyes():
    eyes_only = deform(HEAD, fap_vector({23: 20000.0}))
    both = deform(HEAD, fap_vector({23: 20000.0, 49: 10000.0}))
    head_only = deform(HEAD, fap_vector({49: 10000.0}))
    eye = HEAD.part("left_eye")
    # the eye's shape relative to the head is what the eye FAP alone made
    pivot = HEAD.feature_position("7.1")
    angle = 0.1
    rot = np.array(
        [[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]]
    )
    expected = (eyes_only[eye] - pivot) @ rot.T + pivot
    assert np.allclose(both[eye], expected, atol=1e-6)
    skin = HEAD.part("skin")
    assert np.allclose(both[skin], head_only[skin], atol=1e-7)


def test_the_head_pose_can_be_taken_apart_from_the_vertices():
    from realizer.face.deform import rig_for

    vector = fap_vector({3: 300.0, 23: 5000.0, 48: 4000.0, 49: -3000.0, 50: 1000.0})
    local, pose = rig_for(HEAD).deform_posed(vector)
    assert pose.shape == (4, 4)
    assert np.allclose(pose[:3, :3] @ pose[:3, :3].T, np.eye(3))
    posed = local.astype(np.float64) @ pose[:3, :3].T + pose[:3, 3]
    assert np.allclose(posed, deform(HEAD, vector), atol=1e-6)
    # without head FAPs the pose is the identity and the vertices are the result
    no_head = vector.copy()
    no_head[47:50] = 0.0
    local, pose = rig_for(HEAD).deform_posed(no_head)
    assert np.array_equal(pose, np.eye(4))
    assert np.array_equal(local, deform(HEAD, no_head))


def test_a_head_falloff_bends_the_neck_below_the_pivot():
    from realizer.face.model import Face, FaceParameters, TransformDeformer

    from .helpers import FAPU_POINTS

    count = 60
    vertices = np.zeros((count, 3), dtype=np.float32)
    vertices[:, 0] = 0.01
    vertices[:, 1] = (np.arange(count) - 30) * 0.001  # -30 mm .. +29 mm
    yaw = TransformDeformer(
        49, ("all",), "rotation", (0.0, 1.0, 0.0), pivot=(0.0, 0.0, 0.0), falloff=0.02
    )
    face = Face(
        vertices,
        np.zeros((0, 3), np.int32),
        {"skin": np.arange(count)},
        FaceParameters(dict(FAPU_POINTS), (), (yaw,), {}),
    )
    out = deform(face, fap_vector({49: 10000.0})).astype(np.float64)  # 0.1 rad
    rigid = np.array([0.01 * np.cos(0.1), 0.0, -0.01 * np.sin(0.1)])
    offset = out - face.vertices
    full = rigid - np.array([0.01, 0.0, 0.0])
    y = face.vertices[:, 1]
    assert offset[y >= 0][:, [0, 2]] == pytest.approx(np.tile(full[[0, 2]], (30, 1)), abs=1e-7)
    assert not offset[y <= -0.0205].any()
    halfway = int(np.argmin(np.abs(y + 0.010)))
    assert offset[halfway] == pytest.approx(0.5 * full, abs=1e-7)
