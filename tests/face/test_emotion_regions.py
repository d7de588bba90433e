"""Each emotion profile moves the face regions its description names.

"Parameterized Facial Expression Synthesis Based on MPEG-4" (Raouzaiou et
al.) builds its profiles from the face formations of the psychological
descriptions (its Table 2 vocabulary, Table 1's FAP-to-AU mapping): sadness
raises the inner brows, droops the upper lids and (through the additions)
lowers the lip corners; anger lowers the brows, draws them together and
presses the lips; disgust raises the upper lip and wrinkles the nose. Here
each archetype's default profile (the middle of every range, as
``realizer expressions`` shows it) deforms the default face, and a region's
displacement is the mean displacement of the skin vertices within 4 mm of
its feature points, measured on the mesh.
"""

from __future__ import annotations

import numpy as np
import pytest

from realizer.face.convert.emotion import load_default_converter
from realizer.face.default import load_default_face
from realizer.face.deform import deform
from realizer.face.model import Face
from tests.face.test_face_quality import INNER_PARTS, front_hits, triangles_of

#: Regions by their feature points (Tekalp and Ostermann 2000, Table 6) and
#: how far from them (m) their skin is taken: 4 mm, but 1.2 mm round the
#: inner lip midpoints, which lie 2.6 mm apart on the pressed lips.
REGIONS = {
    "inner brows": (("4.1", "4.2"), 0.004),
    "brows": (("4.1", "4.2", "4.3", "4.4", "4.5", "4.6"), 0.004),
    "upper lids": (("3.1", "3.2"), 0.004),
    "upper lid margins": (("3.1", "3.2"), 0.0008),
    "lower lid margins": (("3.3", "3.4"), 0.0008),
    "lip corners": (("2.4", "2.5", "8.3", "8.4"), 0.004),
    "upper lip": (("2.2",), 0.0012),
    "lower lip": (("2.3",), 0.0012),
    "outer upper lip": (("8.1",), 0.004),
    "nose wings": (("9.1", "9.2"), 0.004),
}


@pytest.fixture(scope="module")
def face() -> Face:
    return load_default_face()


def pose(face: Face, word: str, additions: bool = True) -> np.ndarray:
    values = np.zeros(68)
    for fap, fap_range in load_default_converter(additions=additions).for_word(word).ranges:
        values[fap - 1] = fap_range.center
    return np.asarray(deform(face, values), dtype=np.float64)


def region_motion(face: Face, vertices: np.ndarray, region: str) -> np.ndarray:
    """Mean displacement (mm, x y z) of the skin near the region's points,
    x measured towards the face's midline (positive: drawn together)."""
    rest = np.asarray(face.vertices, dtype=np.float64)
    skin = face.part("skin")
    moves = []
    points, reach = REGIONS[region]
    for point in points:
        centre = face.feature_position(point)
        near = skin[np.linalg.norm(rest[skin] - centre, axis=1) < reach]
        d = (vertices[near] - rest[near]).mean(axis=0) * 1000
        d[0] *= -np.sign(centre[0]) if abs(centre[0]) > 1e-4 else 0.0
        moves.append(d)
    result: np.ndarray = np.mean(moves, axis=0)
    return result


def test_sad_raises_the_inner_brows_droops_the_upper_lids_and_lowers_the_lip_corners(
    face: Face,
) -> None:
    sad = pose(face, "sad")
    assert region_motion(face, sad, "inner brows")[1] > 2.0
    assert region_motion(face, sad, "upper lids")[1] < -0.8
    assert region_motion(face, sad, "lip corners")[1] < -2.0
    # the lip corners come from the additions: Table 5's Sadness 0 has none
    assert abs(region_motion(face, pose(face, "sad", additions=False), "lip corners")[1]) < 0.2


def test_angry_lowers_and_draws_the_brows_together_and_presses_the_lips(face: Face) -> None:
    angry = pose(face, "angry")
    assert region_motion(face, angry, "brows")[1] < -2.0
    assert region_motion(face, angry, "inner brows")[0] > 1.0
    assert region_motion(face, angry, "upper lip")[1] < -0.5
    assert region_motion(face, angry, "lower lip")[1] > 0.5
    # pressed, not parted: no front ray between the lips reaches inside
    corner = face.feature_position("8.3")[0]
    xs = np.linspace(-0.85 * corner, 0.85 * corner, 40)
    meeting = (face.feature_position("2.2")[1] + face.feature_position("2.3")[1]) / 2
    ys = meeting + np.linspace(-0.002, 0.002, 21)
    hits = front_hits(angry, face.faces, xs, ys)
    assert not triangles_of(face, INNER_PARTS)[hits[hits >= 0]].any()


def test_disgusted_raises_the_upper_lip_and_wrinkles_the_nose(face: Face) -> None:
    disgusted = pose(face, "disgusted")
    assert region_motion(face, disgusted, "upper lip")[1] > 2.0
    assert region_motion(face, disgusted, "outer upper lip")[1] > 2.0
    assert region_motion(face, disgusted, "nose wings")[1] > 1.5
    # the nose wrinkle is the addition's: Table 5's Disgust 0 leaves the nose
    table_5 = pose(face, "disgusted", additions=False)
    assert abs(region_motion(face, table_5, "nose wings")[1]) < 0.5


def nose_root_motion(face: Face, vertices: np.ndarray) -> float:
    """Mean vertical displacement (mm) of the skin within 8 mm of the
    midpoint between the inner brows (4.1, 4.2): the root of the nose."""
    rest = np.asarray(face.vertices, dtype=np.float64)
    skin = face.part("skin")
    middle = (face.feature_position("4.1") + face.feature_position("4.2")) / 2
    near = skin[np.linalg.norm(rest[skin] - middle, axis=1) < 0.008]
    return float((vertices[near, 1] - rest[near, 1]).mean() * 1000)


def test_disgusted_wrinkles_the_nose_root_and_knits_the_brows(face: Face) -> None:
    # at first sight: the additions' nose wrinkle (F63 [130, 230]) pulls the
    # skin between the brows down and the inner brows come down with it
    # (F31/F32); with F63 [70, 130] and Table 5's F33/F34 alone the root moved
    # 0.2 mm and the inner brows 1.7 mm, and disgust did not read
    disgusted = pose(face, "disgusted")
    assert nose_root_motion(face, disgusted) < -3.0
    assert region_motion(face, disgusted, "inner brows")[1] < -4.5
    assert region_motion(face, disgusted, "nose wings")[1] > 4.0
    assert region_motion(face, disgusted, "upper lip")[1] > 4.0
    table_5 = pose(face, "disgusted", additions=False)
    assert abs(nose_root_motion(face, table_5)) < 0.5
    assert region_motion(face, table_5, "inner brows")[1] > -2.5


def test_disgusted_turns_the_lip_corners_down_under_the_raised_upper_lip(face: Face) -> None:
    # AU 15 with AU 9 and 10: the corners go down while the upper lip rises;
    # Table 5's Disgust 0 left them still, a grimace more than disgust
    disgusted = pose(face, "disgusted")
    assert region_motion(face, disgusted, "lip corners")[1] < -1.5
    assert region_motion(face, disgusted, "outer upper lip")[1] > 2.0
    table_5 = pose(face, "disgusted", additions=False)
    assert region_motion(face, table_5, "lip corners")[1] > -0.5


def test_guilty_raises_the_inner_brows_and_lowers_the_lip_corners(face: Face) -> None:
    guilty = pose(face, "guilty")
    assert region_motion(face, guilty, "inner brows")[1] > 2.0
    assert region_motion(face, guilty, "lip corners")[1] < -1.0


def test_joyful_raises_the_lower_lids_and_parts_the_lips_without_shutting_the_eyes(
    face: Face,
) -> None:
    """Joy 1 (the default since joy 2 shut the eyes to slits on this face):
    the lower lids rise (the cheeks push them up), the upper lids do not
    come down, the lips part over the teeth and the lip corners go up (the
    stretch tables, F6/F53 at 200 MW, used to pull them down as far as F12
    raised them: 0.56 mm up in all, now 5.6)."""
    joyful = pose(face, "joyful")
    assert region_motion(face, joyful, "lip corners")[1] > 3.0
    assert region_motion(face, joyful, "lower lid margins")[1] > 1.5
    assert region_motion(face, joyful, "upper lid margins")[1] > 0.0
    assert region_motion(face, joyful, "upper lip")[1] > 1.5
    # the eye stays more than half open (9 mm at rest)
    opening = joyful[face.feature_vertex("3.1"), 1] - joyful[face.feature_vertex("3.3"), 1]
    assert opening > 0.6 * (face.feature_position("3.1")[1] - face.feature_position("3.3")[1])


def test_angry_glares_under_the_lowered_brows(face: Face) -> None:
    """The addition from Anger 1: upper lids raised, lower lids tightened."""
    angry = pose(face, "angry")
    assert region_motion(face, angry, "upper lid margins")[1] > 1.0
    assert region_motion(face, angry, "lower lid margins")[1] > 1.0
    assert region_motion(face, angry, "brows")[1] < -2.0


def test_sad_draws_the_inner_brows_together(face: Face) -> None:
    sad = pose(face, "sad")
    assert region_motion(face, sad, "inner brows")[0] > 0.5
    assert region_motion(face, sad, "inner brows")[1] > 2.0


def expression(face: Face, number: int) -> np.ndarray:
    from realizer.face.convert.visemes import FAP12_MAX, expression_faps

    values = expression_faps(number, FAP12_MAX).values.copy()
    return np.asarray(deform(face, values), dtype=np.float64)


def mouth_opening(face: Face, vertices: np.ndarray) -> float:
    """mm between the inner lip midpoints."""
    return float(
        (vertices[face.feature_vertex("2.2"), 1] - vertices[face.feature_vertex("2.3"), 1]) * 1000
    )


def test_fap2_sadness_lowers_the_lip_corners_and_raises_the_inner_brows(face: Face) -> None:
    sad = expression(face, 2)
    assert region_motion(face, sad, "lip corners")[1] < -2.5
    assert region_motion(face, sad, "inner brows")[1] > 5.0
    assert region_motion(face, sad, "upper lid margins")[1] < -1.0


def test_fap2_anger_lowers_the_brows_without_crushing_them_onto_the_lids(face: Face) -> None:
    """Lowered 3 to 7.5 mm (at 10 mm and more the brow skin folded onto the lid in a
    zig-zag crease), drawn together, with the glare."""
    angry = expression(face, 3)
    down = region_motion(face, angry, "brows")[1]
    assert -7.5 < down < -3.0
    assert region_motion(face, angry, "inner brows")[0] > 2.0
    assert region_motion(face, angry, "upper lid margins")[1] > 1.0


def test_fap2_fear_raises_the_brows_opens_the_eyes_and_the_mouth(face: Face) -> None:
    fear = expression(face, 4)
    assert region_motion(face, fear, "inner brows")[1] > 8.0
    assert region_motion(face, fear, "upper lid margins")[1] > 2.0
    assert mouth_opening(face, fear) > 4.0


def test_fap2_disgust_raises_the_upper_lip_wrinkles_the_nose_and_narrows_the_eyes(
    face: Face,
) -> None:
    disgust = expression(face, 5)
    assert region_motion(face, disgust, "upper lip")[1] > 2.5
    assert region_motion(face, disgust, "nose wings")[1] > 1.5
    assert region_motion(face, disgust, "lower lid margins")[1] > 1.0
    assert region_motion(face, disgust, "brows")[1] < -1.5
    # at first sight: the brows knit over a wrinkled nose root (at F31..F34
    # -60 and F63 110 the root moved 3 mm, the inner brows 4 mm)
    assert nose_root_motion(face, disgust) < -4.0
    assert region_motion(face, disgust, "inner brows")[1] < -6.0
    assert region_motion(face, disgust, "inner brows")[0] > 2.0
    assert region_motion(face, disgust, "nose wings")[1] > 6.5
