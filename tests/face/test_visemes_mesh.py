"""The FAP 1 visemes on the default face, as properties of the mesh.

Viseme 0 (silence) and viseme 1 (p, b, m) keep the lips in contact like
MPEG-4's neutral face (Tekalp and Ostermann, "Face and 2-D mesh animation in
MPEG-4", Table 3 and section 2.1); FAP 2's sadness and anger keep them
closed too, fear and surprise open them; viseme 14 (U, "book") rounds the
lips: the mouth narrows, the upper lip pushes forward and the opening is a
rounded hole, not a wide slot.
"""

from __future__ import annotations

import numpy as np
import pytest

from realizer.face.convert.visemes import FAP12_MAX, viseme_faps
from realizer.face.default import load_default_face
from realizer.face.deform import deform
from realizer.face.model import Face
from tests.face.test_face_quality import INNER_PARTS, front_hits, triangles_of


@pytest.fixture(scope="module")
def face() -> Face:
    return load_default_face()


def viseme(face: Face, number: int) -> np.ndarray:
    result: np.ndarray = deform(face, viseme_faps(number, 0, FAP12_MAX).values)
    return result


def opening(face: Face, vertices: np.ndarray) -> tuple[np.ndarray, float]:
    """Height (m) of the mouth's opening seen from the front in each of 41
    columns across the neutral mouth's width, and the column spacing (m): a
    column's height is how much of it reaches the teeth or the inside."""
    corner = abs(face.feature_position("8.3")[0])
    xs = np.linspace(-corner, corner, 41)
    meeting = (face.feature_position("2.2")[1] + face.feature_position("2.3")[1]) / 2
    ys = meeting + np.linspace(-0.02, 0.02, 161)
    hits = front_hits(vertices, face.faces, xs, ys)
    inner = triangles_of(face, INNER_PARTS)[np.maximum(hits, 0)] & (hits >= 0)
    return inner.sum(axis=0) * (ys[1] - ys[0]), float(xs[1] - xs[0])


def nearest(face: Face, name: str) -> int:
    return int(np.argmin(np.linalg.norm(face.vertices - face.feature_position(name), axis=1)))


def test_viseme_u_rounds_the_lips(face: Face) -> None:
    """The U of visemes.txt (F4/F5 part the lips' middles, whose tables fall
    off towards the corners, over little jaw; the corners narrow; F17 pushes
    the upper lip): the old U (F3 200) opened a 28 x 6 mm slot, this one a
    25 x 7.5 mm round hole, and costs fewer bits (no F16) in
    tests/face/test_fapcoding.py's DCT-coded talking block."""
    vertices = viseme(face, 14)
    left, right = nearest(face, "8.4"), nearest(face, "8.3")
    width = np.linalg.norm(vertices[left] - vertices[right])
    rest = np.linalg.norm(face.vertices[left] - face.vertices[right])
    assert width < 0.65 * rest, f"mouth width {width * 1000:.1f} of {rest * 1000:.1f} mm"
    upper = nearest(face, "8.1")
    assert vertices[upper, 2] - face.vertices[upper, 2] > 0.002  # the upper lip protrudes
    heights, step = opening(face, vertices)
    open_columns = np.flatnonzero(heights > 0)
    assert len(open_columns) > 0, "U shows an opening"
    open_width = (open_columns[-1] - open_columns[0] + 1) * step
    centre = heights[len(heights) // 2]
    assert centre >= 0.9 * heights.max(), "no notch in the middle of the opening"
    assert open_width < 3.5 * heights.max(), (
        f"a slot {open_width * 1000:.1f} mm wide, {heights.max() * 1000:.1f} mm high"
    )


@pytest.mark.parametrize("number", [0, 1])
def test_silence_and_bilabials_keep_the_lips_in_contact(face: Face, number: int) -> None:
    heights, _ = opening(face, viseme(face, number))
    assert heights.max() == 0.0, f"viseme {number} opens {heights.max() * 1000:.1f} mm"


@pytest.mark.parametrize(("number", "opens"), [(2, False), (3, False), (4, True), (6, True)])
def test_fap2_expressions_part_the_lips_only_where_they_should(
    face: Face, number: int, opens: bool
) -> None:
    """Sadness and anger (pressed lips) keep the mouth closed; fear and
    surprise drop the jaw (Tekalp and Ostermann, Table 4's descriptions)."""
    from realizer.face.convert.visemes import expression_faps

    heights, _ = opening(face, deform(face, expression_faps(number, FAP12_MAX).values))
    if opens:
        assert heights.max() > 0.003, f"expression {number} opens {heights.max() * 1000:.1f} mm"
    else:
        assert heights.max() < 0.0005, f"expression {number} opens {heights.max() * 1000:.1f} mm"
