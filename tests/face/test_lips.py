"""The lips seen from the front (issue 11): the lips between middle and
corner (FAPs 8..11 inner, 55..58 outer) and the raised corners (12, 13, 59,
60) on the default face.

hm08 samples each lip contour with about five vertices from the middle to
a corner, so the shape of a contour in a front view is a polyline, and
what the eye reads as a curve or as a V is how its turning is shared out
among those vertices. The tests pin that as the change of each contour
vertex's turning angle (degrees, in the x-y plane) between the neutral and
the posed face, at the value ``realizer fap-sheet`` shows (512): the
lip_field tables of 10- and 57- turned one vertex by 53 and 34 degrees
(a V and a triangle), and the artist's smile kept the lip line straight
from the middle to the raised corner (lift linear in x).
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from realizer.face.default import load_default_face
from realizer.face.deform import deform
from realizer.face.model import Face

#: The four lip contours, corner to corner through their feature points.
CONTOURS = {
    "upper inner": ("2.4", "2.6", "2.2", "2.7", "2.5"),
    "lower inner": ("2.4", "2.8", "2.3", "2.9", "2.5"),
    "upper outer": ("8.3", "8.5", "8.1", "8.6", "8.4"),
    "lower outer": ("8.3", "8.7", "8.2", "8.8", "8.4"),
}
#: FAP: the contour it moves.
SIDE_FAPS = {
    8: "upper inner",
    9: "upper inner",
    10: "lower inner",
    11: "lower inner",
    55: "upper outer",
    56: "upper outer",
    57: "lower outer",
    58: "lower outer",
}


@pytest.fixture(scope="module")
def face() -> Face:
    return load_default_face()


def lip_contours(face: Face) -> dict[str, np.ndarray]:
    """Each contour's vertices: the shortest mesh paths between its points."""
    v = np.asarray(face.vertices, dtype=np.float64)
    f = np.asarray(face.faces)
    i = np.concatenate([f[:, 0], f[:, 1], f[:, 2]])
    j = np.concatenate([f[:, 1], f[:, 2], f[:, 0]])
    w = np.linalg.norm(v[i] - v[j], axis=1)
    graph = coo_matrix((np.r_[w, w], (np.r_[i, j], np.r_[j, i])), shape=(len(v), len(v))).tocsr()
    out = {}
    for name, points in CONTOURS.items():
        ids = [face.feature_vertex(p) for p in points]
        loop = [ids[0]]
        for a, b in itertools.pairwise(ids):
            _, pred = dijkstra(graph, indices=a, return_predecessors=True)
            path = [b]
            while path[-1] != a:
                path.append(int(pred[path[-1]]))
            loop += path[::-1][1:]
        out[name] = np.asarray(loop)
    return out


@pytest.fixture(scope="module")
def contours(face: Face) -> dict[str, np.ndarray]:
    return lip_contours(face)


def posed(face: Face, values: dict[int, float]) -> np.ndarray:
    vector = np.zeros(68)
    for fap, value in values.items():
        vector[fap - 1] = value
    return np.asarray(deform(face, vector), dtype=np.float64)


def turning(points: np.ndarray) -> np.ndarray:
    """The turning angle (degrees) at each inner vertex of a polyline, front view."""
    d = np.diff(points[:, :2], axis=0)
    angle = np.arctan2(d[:, 1], d[:, 0])
    t = np.diff(angle)
    result: np.ndarray = np.degrees((t + np.pi) % (2 * np.pi) - np.pi)
    return result


def added_turning(face: Face, loop: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    return turning(vertices[loop]) - turning(np.asarray(face.vertices, dtype=np.float64)[loop])


#: The most a vertex of the FAP's own contour between the corners (within
#: CORNER_SHARE of the corner's x) may turn at 512, degrees ...
MAX_ADDED_TURN = 33.0
CORNER_SHARE = 0.8
#: ... for these displacements: towards the other lip on the outer contour
#: (55+..58+) the lips press on each other and that still kinks (57 degrees).
CURVED = [(f, s) for f in sorted(SIDE_FAPS) for s in (1.0, -1.0) if f < 55 or s < 0]


@pytest.mark.parametrize(
    ("fap", "sign"), [pytest.param(f, s, id=f"{f}{'+' if s > 0 else '-'}") for f, s in CURVED]
)
def test_a_lip_between_middle_and_corner_bends_as_a_curve(
    face: Face, contours: dict[str, np.ndarray], fap: int, sign: float
) -> None:
    """At 512 (the feature point moves 9.2 mm) no vertex of the contour the
    FAP moves, between its corners, turns by more than MAX_ADDED_TURN: the
    turn is shared out along the lip. lip_field's tables turned one vertex
    into a V's point (10-: 53 degrees, 8+: 48, 57-: 34); the corners
    themselves (already a sharp turn at rest) are left out."""
    loop = contours[SIDE_FAPS[fap]]
    added = np.abs(added_turning(face, loop, posed(face, {fap: sign * 512})))
    x = np.abs(np.asarray(face.vertices, dtype=np.float64)[loop[1:-1], 0])
    between = x < CORNER_SHARE * abs(float(face.vertices[loop[0], 0]))
    assert added[between].max() < MAX_ADDED_TURN, f"{added[between].max():.1f} degrees"


@pytest.mark.parametrize(("fap", "corner"), [(12, "2.4"), (13, "2.5"), (59, "8.3"), (60, "8.4")])
def test_a_raised_corner_curves_the_lip_line_up(
    face: Face, contours: dict[str, np.ndarray], fap: int, corner: str
) -> None:
    """A smile's lip line stays level in the middle and curves up towards
    the corner: along the upper lip's inner contour, from the midline to the
    raised corner, the lift grows (never falls by more than 0.1 mm) and at
    half the way it is under a third of the corner's (the artist's smile:
    about half, a straight diagonal)."""
    vertices = posed(face, {fap: 512})
    loop = contours["upper inner"]
    v0 = np.asarray(face.vertices, dtype=np.float64)
    x_corner = face.feature_position(corner)[0]
    side = np.sign(x_corner)
    on_side = loop[(side * v0[loop, 0] >= 0) & (side * v0[loop, 0] <= abs(x_corner))]
    order = on_side[np.argsort(side * v0[on_side, 0])]
    lift = (vertices[order, 1] - v0[order, 1]) * 1000
    assert np.all(np.diff(lift) > -0.1)
    k = face.feature_vertex(corner)
    corner_lift = (vertices[k, 1] - v0[k, 1]) * 1000
    half = np.interp(0.5, side * v0[order, 0] / abs(x_corner), lift)
    assert half < corner_lift / 3, f"{half:.2f} of {corner_lift:.2f} mm"


@pytest.mark.parametrize("fap", [12, 13, 59, 60])
def test_a_corner_raised_to_800_folds_nothing_and_keeps_rising(face: Face, fap: int) -> None:
    """The artist's smile creased the cheek beside the corner from 700 (4 to
    7 triangles folded over at 800); beyond 500-550 the table goes on with a
    smoothed copy of its slope, the corner still rising one MNS per unit."""
    from realizer.face.audit import PRACTICAL_RANGE, count_folds

    assert PRACTICAL_RANGE[fap] == 800
    vertices = posed(face, {fap: 800})
    assert count_folds(face, face.vertices, vertices) == 0
    corner = face.feature_vertex({12: "2.4", 13: "2.5", 59: "8.3", 60: "8.4"}[fap])
    lift = vertices[corner, 1] - float(face.vertices[corner, 1])
    assert lift == pytest.approx(800 * face.fapu.mns, rel=0.01)


#: FAP: its feature point (which side of the mouth it moves).
SIDE_POINTS = {8: "2.6", 9: "2.7", 10: "2.8", 11: "2.9", 55: "8.5", 56: "8.6", 57: "8.7", 58: "8.8"}


@pytest.mark.parametrize("fap", [10, 11, 57, 58])
def test_the_lower_lip_drops_up_to_its_corner(
    face: Face, contours: dict[str, np.ndarray], fap: int
) -> None:
    """Dropping the lower lip beside the middle (10-, 11-, 57-, 58- at 512)
    moves its contour within 3 mm of the corner by at least 2 mm, and the
    upper lip's contours not at all. jawOpen's share sorted the lower lip's
    last 3 mm before each corner onto the upper lip (lip_sides): held
    still there, the lip fell to the corner along one steep straight edge
    (10-) or kinked at the bulge's lower edge (57-)."""
    v0 = np.asarray(face.vertices, dtype=np.float64)
    vertices = posed(face, {fap: -512})
    loop = contours[SIDE_FAPS[fap]]
    side = np.sign(v0[face.feature_vertex(SIDE_POINTS[fap]), 0])
    corner_x = abs(float(v0[loop[0], 0]))
    near = loop[(side * v0[loop, 0] > corner_x - 0.003) & (side * v0[loop, 0] < corner_x - 1e-5)]
    drop = float(np.max(v0[near, 1] - vertices[near, 1])) * 1000
    assert drop > 2.0, f"{drop:.2f} mm"
    for name in ("upper inner", "upper outer"):
        still = contours[name]
        assert np.abs(vertices[still] - v0[still]).max() < 1e-5, name


@pytest.mark.parametrize("fap", [8, 9, 55, 56])
def test_a_dropped_upper_lip_turns_smoothly_into_its_corner(
    face: Face, contours: dict[str, np.ndarray], fap: int
) -> None:
    """Dropping the upper lip beside the middle (8+, 9+, 55+, 56+ at 512),
    no vertex of its contour turns by more than MAX_ADDED_TURN, up to the
    corner's neighbour: the fall fades as cos² to the corner itself
    (LIP_SIDE_CORNER); faded as a quarter cosine to 0.92..0.95 of the way
    the lip turned back to the corner in one vertex (41 degrees at 8+, 50 at
    55+)."""
    loop = contours[SIDE_FAPS[fap]]
    added = np.abs(added_turning(face, loop, posed(face, {fap: 512})))
    assert added.max() < MAX_ADDED_TURN, f"{added.max():.1f} degrees"


#: The most a lower lip contour vertex within 3 mm of its corner may turn as
#: the lower lip drops beside the middle (57-, 58- at 512), degrees.
MAX_CORNER_TURN = {"lower outer": 10.0, "lower inner": 20.0}


@pytest.mark.parametrize("fap", [57, 58])
@pytest.mark.parametrize("name", sorted(MAX_CORNER_TURN))
def test_the_dropped_lower_lip_leaves_its_corners_without_a_facet(
    face: Face, contours: dict[str, np.ndarray], fap: int, name: str
) -> None:
    """Dropping the lower lip beside the middle (57-, 58- at 512), the
    vertices of its outer and inner contours within 3 mm of their corners
    (the corner's neighbour on) turn by less than MAX_CORNER_TURN: the
    outer contour's drop fades to the corner itself (LIP_SIDE_CORNER), the
    inner one's is pinned to a sin² ramp from its corner
    (LIP_SIDE_INNER_RAMP_M). Before, the outer corner's neighbour stayed
    while the next vertex, 0.7 mm on, dropped 1.3 mm (it turned 28
    degrees), and the inner corner's neighbour, 0.7 mm from it, dropped
    3.5 mm (88 degrees): a narrow near-vertical facet at the corner."""
    v0 = np.asarray(face.vertices, dtype=np.float64)
    loop = contours[name]
    side = np.sign(v0[face.feature_vertex(SIDE_POINTS[fap]), 0])
    if side * v0[loop[0], 0] < side * v0[loop[-1], 0]:
        loop = loop[::-1]
    corner_x = abs(float(v0[loop[0], 0]))
    added = np.abs(added_turning(face, loop, posed(face, {fap: -512})))
    # added[k] is the turning at loop[k + 1]
    near = side * v0[loop[1:-1], 0] > corner_x - 0.003
    assert near.sum() >= 2
    assert added[near].max() < MAX_CORNER_TURN[name], f"{added[near].max():.1f} degrees"
