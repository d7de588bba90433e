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


def test_guilty_raises_the_inner_brows_and_lowers_the_lip_corners(face: Face) -> None:
    guilty = pose(face, "guilty")
    assert region_motion(face, guilty, "inner brows")[1] > 2.0
    assert region_motion(face, guilty, "lip corners")[1] < -1.0
