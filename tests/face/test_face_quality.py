"""Measurable properties of a face people recognise (the default face).

Each test pins a fix of the default face as a property of the mesh in a
front (orthographic) view or of its deformation: the lips meet at rest,
FAPs 19 and 20 at 1024 IRISD close the eyes, the lids stay in front of a
thrust eyeball, no single FAP at the value ``realizer fap-sheet`` shows
folds a triangle over, and the brows move the brow region. The evaluation
these follow is section 4.4 of "Realization and high level specification of
facial expressions for embodied agents".
"""

from __future__ import annotations

import numpy as np
import pytest

from realizer.commands.fap_sheet import load_sheet_entries
from realizer.face.default import load_default_face
from realizer.face.deform import deform
from realizer.face.faps import FAP_TABLE
from realizer.face.model import Face

INNER_PARTS = ("upper_teeth", "lower_teeth", "tongue", "mouth_inside")


@pytest.fixture(scope="module")
def face() -> Face:
    return load_default_face()


def front_hits(
    vertices: np.ndarray, faces: np.ndarray, xs: np.ndarray, ys: np.ndarray
) -> np.ndarray:
    """For rays along -z through the grid (x, y): the index of the front-most
    triangle each hits, -1 where none (a front orthographic view)."""
    tri = np.asarray(vertices, dtype=np.float64)[faces]
    lo, hi = tri[:, :, :2].min(axis=1), tri[:, :, :2].max(axis=1)
    near = (lo[:, 0] <= xs.max()) & (hi[:, 0] >= xs.min())
    near &= (lo[:, 1] <= ys.max()) & (hi[:, 1] >= ys.min())
    index = np.flatnonzero(near)
    t = tri[index]
    a = t[:, 0, :2]
    e1, e2 = t[:, 1, :2] - a, t[:, 2, :2] - a
    det = e1[:, 0] * e2[:, 1] - e2[:, 0] * e1[:, 1]
    ok = np.abs(det) > 1e-14
    index, t, a, e1, e2, det = index[ok], t[ok], a[ok], e1[ok], e2[ok], det[ok]
    gx, gy = np.meshgrid(xs, ys)
    points = np.stack([gx.ravel(), gy.ravel()], axis=1)
    d = points[:, None, :] - a[None]
    u = (d[..., 0] * e2[None, :, 1] - e2[None, :, 0] * d[..., 1]) / det
    w = (e1[None, :, 0] * d[..., 1] - d[..., 0] * e1[None, :, 1]) / det
    inside = (u >= 0) & (w >= 0) & (u + w <= 1)
    z = t[None, :, 0, 2] * (1 - u - w) + t[None, :, 1, 2] * u + t[None, :, 2, 2] * w
    z = np.where(inside, z, -np.inf)
    best = np.argmax(z, axis=1)
    hit = np.where(np.isfinite(z[np.arange(len(points)), best]), index[best], -1)
    return hit.reshape(gx.shape)


def triangles_of(face: Face, parts: tuple[str, ...]) -> np.ndarray:
    """Which triangles (bool per triangle) have all corners in ``parts``."""
    member = np.zeros(face.vertex_count, dtype=bool)
    for name in parts:
        member[face.part(name)] = True
    result: np.ndarray = member[face.faces].all(axis=1)
    return result


def fap_vector(**values: float) -> np.ndarray:
    vector = np.zeros(68)
    for key, value in values.items():
        vector[int(key[1:]) - 1] = value
    return vector


def test_the_lips_are_in_contact_at_rest(face: Face) -> None:
    """MPEG-4's neutral face has its lips closed: seen from the front, no ray
    between the lips reaches the teeth or the mouth's inside, along 85 % of
    the mouth's width."""
    corner = face.feature_position("8.3")[0]
    xs = np.linspace(-0.85 * corner, 0.85 * corner, 60)
    meeting = (face.feature_position("2.2")[1] + face.feature_position("2.3")[1]) / 2
    ys = meeting + np.linspace(-0.002, 0.002, 41)
    hits = front_hits(face.vertices, face.faces, xs, ys)
    assert (hits >= 0).all()
    inner = triangles_of(face, INNER_PARTS)[hits]
    assert not inner.any(), f"{inner.any(axis=0).sum()} of {len(xs)} columns see inside"


def eye_region(face: Face, side: str) -> tuple[np.ndarray, np.ndarray]:
    outer, inner, top, bottom = (
        ("3.7", "3.11", "3.9", "3.3") if side == "left" else ("3.12", "3.8", "3.10", "3.4")
    )
    x = sorted([face.feature_position(outer)[0], face.feature_position(inner)[0]])
    y_low = face.feature_position(bottom)[1] - 0.002
    y_high = face.feature_position("3.1" if side == "left" else "3.2")[1] + 0.002
    del top
    return np.linspace(x[0], x[1], 50), np.linspace(y_low, y_high, 30)


def visible_eyeball(face: Face, vertices: np.ndarray, side: str) -> int:
    xs, ys = eye_region(face, side)
    hits = front_hits(vertices, face.faces, xs, ys)
    eyeball = triangles_of(face, (f"{side}_eye",))
    return int(np.sum((hits >= 0) & eyeball[np.maximum(hits, 0)]))


def test_the_eyes_are_open_at_rest(face: Face) -> None:
    for side in ("left", "right"):
        assert visible_eyeball(face, face.vertices, side) > 300


@pytest.mark.parametrize("value", [1024.0, 1100.0])
def test_fap_19_and_20_at_1024_irisd_close_the_eyes(face: Face, value: float) -> None:
    """At 1024 IRISD the upper lids have come down one iris diameter, onto
    the lower lids: seen from the front, no part of either eyeball shows."""
    closed = deform(face, fap_vector(f19=value, f20=value))
    for side in ("left", "right"):
        assert visible_eyeball(face, closed, side) == 0, side


def test_a_half_closed_lid_covers_about_half_the_eye(face: Face) -> None:
    half = deform(face, fap_vector(f19=512, f20=512))
    for side in ("left", "right"):
        open_ = visible_eyeball(face, face.vertices, side)
        assert 0.25 * open_ < visible_eyeball(face, half, side) < 0.75 * open_


def lid_in_front(face: Face, vertices: np.ndarray, side: str) -> int:
    """How many eyeball vertices that the skin hides at rest come out in front
    of the skin (a ray from the vertex towards the viewer meets no skin)."""
    ball = face.part(f"{side}_eye")
    skin = triangles_of(face, ("skin",))
    rest = np.asarray(face.vertices, dtype=np.float64)
    count = 0
    for positions in (rest, np.asarray(vertices, dtype=np.float64)):
        covered = []
        for k in ball:
            p = positions[k]
            hit = front_hits(positions, face.faces, np.array([p[0]]), np.array([p[1]]))[0, 0]
            covered.append(hit >= 0 and skin[hit])
        if positions is rest:
            hidden = np.array(covered)
        else:
            count = int(np.sum(hidden & ~np.array(covered)))
    return count


@pytest.mark.parametrize(("fap", "side"), [(27, "left"), (28, "right")])
def test_a_thrust_eyeball_stays_behind_its_lids(face: Face, fap: int, side: str) -> None:
    value = next(e.value for e in load_sheet_entries() if e.fap == fap)
    thrust = deform(face, fap_vector(**{f"f{fap}": value}))
    assert lid_in_front(face, thrust, side) == 0


def skin_normals(face: Face, vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    tri = np.asarray(vertices, dtype=np.float64)[face.faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = np.linalg.norm(normal, axis=1)
    return normal / np.maximum(area, 1e-30)[:, None], area


def sheet_poses() -> list[tuple[int, float]]:
    poses = []
    for entry in load_sheet_entries():
        poses.append((entry.fap, entry.value))
        if FAP_TABLE[entry.fap].bidirectional:
            poses.append((entry.fap, -entry.value))
    return poses


def _param(fap: int, value: float) -> object:
    return pytest.param(fap, value, id=f"{fap}{'+' if value > 0 else '-'}")


@pytest.mark.parametrize(("fap", "value"), [_param(f, v) for f, v in sheet_poses()])
def test_no_single_fap_at_its_sheet_value_folds_a_triangle(
    face: Face, fap: int, value: float
) -> None:
    """A fold is a skin triangle whose normal turns by more than 90 degrees
    (it is seen from behind: a crease or a tear)."""
    entry = next(e for e in load_sheet_entries() if e.fap == fap)
    vector = fap_vector(**{f"f{fap}": value})
    if entry.jaw_open:
        vector[2] = entry.jaw_open
    base = deform(face, fap_vector(f3=entry.jaw_open)) if entry.jaw_open else face.vertices
    before, area = skin_normals(face, base)
    after, _ = skin_normals(face, deform(face, vector))
    skin = triangles_of(face, ("skin",)) & (area > 1e-9)
    folded = np.flatnonzero(skin & (np.sum(before * after, axis=1) < 0.0))
    assert len(folded) == 0, f"{len(folded)} triangles fold"


#: Lip midpoint FAPs: feature point, axis (Table 7), which lip, whose points
#: a FAP of the other lip must leave still.
LIP_MIDPOINTS = [
    (4, "2.2", (0, -1, 0), "upper"),
    (8, "2.6", (0, -1, 0), "upper"),
    (9, "2.7", (0, -1, 0), "upper"),
    (17, "2.2", (0, 0, 1), "upper"),
    (51, "8.1", (0, -1, 0), "upper"),
    (55, "8.5", (0, -1, 0), "upper"),
    (56, "8.6", (0, -1, 0), "upper"),
    (5, "2.3", (0, 1, 0), "lower"),
    (10, "2.8", (0, 1, 0), "lower"),
    (11, "2.9", (0, 1, 0), "lower"),
    (16, "2.3", (0, 0, 1), "lower"),
    (52, "8.2", (0, 1, 0), "lower"),
    (57, "8.7", (0, 1, 0), "lower"),
    (58, "8.8", (0, 1, 0), "lower"),
]
LIP_POINTS = {
    "upper": ("2.2", "2.6", "2.7", "8.1", "8.5", "8.6"),
    "lower": ("2.3", "2.8", "2.9", "8.2", "8.7", "8.8"),
}


def moved_mm(face: Face, vertices: np.ndarray, point: str) -> np.ndarray:
    k = face.feature_vertex(point)
    result: np.ndarray = (np.asarray(vertices[k]) - np.asarray(face.vertices[k])) * 1000
    return result


@pytest.mark.parametrize("sign", [1.0, -1.0], ids=["+", "-"])
@pytest.mark.parametrize(("fap", "point", "axis", "lip"), LIP_MIDPOINTS)
def test_a_lip_midpoint_fap_moves_its_point_and_leaves_the_other_lip_and_the_corners(
    face: Face, fap: int, point: str, axis: tuple[int, int, int], lip: str, sign: float
) -> None:
    """The lip midpoint tables (a smooth field on the skin, see
    docs/default-face.md): at 512 MNS the FAP's feature point moves
    512 MNS along the FAP's axis, the other lip's six points stay, and the
    lip corners, where the two lips meet, move less than a tenth as far
    (the corners pinned by the other lip is what folded the spheres)."""
    vertices = deform(face, fap_vector(**{f"f{fap}": sign * 512}))
    expected = sign * 512 * face.fapu.mns * 1000 * np.asarray(axis, dtype=np.float64)
    moved = moved_mm(face, vertices, point)
    if fap in (4, 8, 9) and sign > 0:
        # dropping onto the lower lip, the upper lip also comes forward
        # (0.3 mm per mm down), over the lower lip rather than into it
        assert moved[2] == pytest.approx(0.3 * np.linalg.norm(expected), abs=0.05)
        moved[2] = 0.0
    np.testing.assert_allclose(moved, expected, atol=0.05)
    other = LIP_POINTS["lower" if lip == "upper" else "upper"]
    for name in other:
        assert np.linalg.norm(moved_mm(face, vertices, name)) < 0.01, name
    for corner in ("2.4", "2.5", "8.3", "8.4"):
        assert np.linalg.norm(moved_mm(face, vertices, corner)) < 0.1 * np.linalg.norm(expected)


@pytest.mark.parametrize(
    ("fap", "point", "corners"), [(21, "3.3", ("3.7", "3.11")), (22, "3.4", ("3.8", "3.12"))]
)
def test_the_lower_lid_rises_past_the_squint_with_its_corners_held(
    face: Face, fap: int, point: str, corners: tuple[str, str]
) -> None:
    """At the sheet's 512 IRISD the lower lid's midpoint has risen 512 IRISD
    (beyond the artist's squint, whose whole slope folded the corners over),
    while its corners rise less than a fifth of that."""
    vertices = deform(face, fap_vector(**{f"f{fap}": 512}))
    rise = 512 * face.fapu.irisd * 1000
    assert moved_mm(face, vertices, point)[1] == pytest.approx(rise, abs=0.05)
    for name in corners:
        assert moved_mm(face, vertices, name)[1] < 0.2 * rise, name
