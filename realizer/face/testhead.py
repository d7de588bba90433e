"""A small procedural test head, built from primitives, for fast unit tests.

An ellipsoid skull with a nose and ears, a torus for the lips (its outer
rim is the outer lip contour, its inner rim the inner contour), two eyeballs
with pupils, upper and lower teeth (boxes) and a tongue (a flattened
ellipsoid). Every feature point that a FAP moves is a vertex chosen by
construction (e.g. 8.3, the left outer lip corner, is the lip torus vertex at
angle 0 on its outer rim), and every FAP 3..68 has a setting: influence
deformers of all kinds (ease, Bezier smooth, raised cosine) with vertex masks
on the lips, the jaw and the ears; rigid transforms for the jaw, eyes and
head; pupil dilation; tongue roll. About 10,000 vertices; metres; the frame
of docs/face-model.md (+x the face's left, +y up, +z the gaze).
"""

from __future__ import annotations

from functools import cache

import numpy as np

from realizer.face.model import (
    CosineDeformer,
    DeformerSetting,
    DilateDeformer,
    EaseDeformer,
    Face,
    FaceParameters,
    RollDeformer,
    SmoothDeformer,
    TransformDeformer,
)

Vec3 = tuple[float, float, float]

SKULL_RADII = (0.075, 0.105, 0.095)
MOUTH_Y = -0.050
EYE_X, EYE_Y, EYE_RADIUS = 0.032, 0.025, 0.012
JAW_PIVOT: Vec3 = (0.0, -0.030, -0.010)


def _grid_faces(rows: int, cols: int, wrap_cols: bool, offset: int) -> np.ndarray:
    """Triangles of a rows x cols vertex grid (row-major), columns wrapping."""
    col_count = cols if wrap_cols else cols - 1
    r, c = np.meshgrid(np.arange(rows - 1), np.arange(col_count), indexing="ij")
    a = r * cols + c
    b = r * cols + (c + 1) % cols
    d = (r + 1) * cols + c
    e = (r + 1) * cols + (c + 1) % cols
    tris = np.stack([np.stack([a, d, b], -1), np.stack([b, d, e], -1)], axis=2)
    return tris.reshape(-1, 3) + offset


def uv_ellipsoid(
    centre: Vec3, radii: Vec3, rings: int, segments: int
) -> tuple[np.ndarray, np.ndarray]:
    """Ellipsoid with poles on the y axis; segment 0 faces +z, segment k/4 faces +x.

    Vertex 0 is the top pole, vertex 1 the bottom pole, then ``rings`` rings of
    ``segments`` vertices from top to bottom.
    """
    theta = np.linspace(0, np.pi, rings + 2)[1:-1]
    phi = np.arange(segments) * 2 * np.pi / segments
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(t) * np.sin(p), np.cos(t), np.sin(t) * np.cos(p)], -1).reshape(-1, 3)
    unit = np.vstack([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0], ring])
    vertices = unit * np.asarray(radii) + np.asarray(centre)
    body = _grid_faces(rings, segments, True, 2)
    top = np.stack(
        [
            np.zeros(segments, int),
            2 + (np.arange(segments) + 1) % segments,
            2 + np.arange(segments),
        ],
        -1,
    )
    last = 2 + (rings - 1) * segments
    bottom = np.stack(
        [
            np.ones(segments, int),
            last + np.arange(segments),
            last + (np.arange(segments) + 1) % segments,
        ],
        -1,
    )
    return vertices, np.vstack([top, body, bottom])


def lip_torus(
    centre: Vec3, half_width: float, half_height: float, tube: float, around: int, across: int
) -> tuple[np.ndarray, np.ndarray]:
    """Elliptic torus in the xy plane: (u, v) -> rim ellipse u, tube angle v.

    u = 0 is the face's left corner (+x), u = 90 deg the top middle; v = 0 the
    outer contour, v = 90 deg the front, v = 180 deg the inner contour.
    Vertex (u_i, v_j) has index i * across + j.
    """
    u = np.arange(around) * 2 * np.pi / around
    v = np.arange(across) * 2 * np.pi / across
    uu, vv = np.meshgrid(u, v, indexing="ij")
    x = (half_width + tube * np.cos(vv)) * np.cos(uu)
    y = (half_height + tube * np.cos(vv)) * np.sin(uu)
    z = tube * np.sin(vv)
    vertices = np.stack([x, y, z], -1).reshape(-1, 3) + np.asarray(centre)
    faces = _grid_faces(around, across, True, 0)
    # close the seam between the last and the first ring of u
    j = np.arange(across)
    a, b = (around - 1) * across + j, (around - 1) * across + (j + 1) % across
    c, d = j, (j + 1) % across
    seam = np.vstack([np.stack([a, c, b], -1), np.stack([b, c, d], -1)])
    return vertices, np.vstack([faces, seam])


def grid_box(centre: Vec3, extents: Vec3, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """A box whose faces are (steps x steps) grids; steps even puts a vertex mid-edge."""
    import trimesh

    box = trimesh.creation.box(extents=extents)
    vertices, faces = np.asarray(box.vertices), np.asarray(box.faces)
    while len(vertices) < 6 * steps * steps:
        vertices, faces = trimesh.remesh.subdivide(vertices, faces)  # type: ignore[no-untyped-call]
    return np.asarray(vertices) + np.asarray(centre), np.asarray(faces)


def _skull_z(x: float, y: float, grow: float = 0.0) -> float:
    a, b, c = SKULL_RADII
    return float(c * np.sqrt(max(0.0, 1.0 - (x / a) ** 2 - (y / b) ** 2)) + grow)


class _Builder:
    def __init__(self) -> None:
        self.vertices: list[np.ndarray] = []
        self.faces: list[np.ndarray] = []
        self.parts: dict[str, list[np.ndarray]] = {}
        self.count = 0

    def add(self, parts: tuple[str, ...], mesh: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        vertices, faces = mesh
        indices = np.arange(self.count, self.count + len(vertices))
        self.vertices.append(vertices)
        self.faces.append(faces + self.count)
        for part in parts:
            self.parts.setdefault(part, []).append(indices)
        self.count += len(vertices)
        return indices


@cache
def build_test_head() -> Face:
    """The procedural test head (cached: it is immutable)."""
    b = _Builder()
    _, b_, c_ = SKULL_RADII
    skull = b.add(("skin", "skull"), uv_ellipsoid((0, 0, 0), SKULL_RADII, 79, 120))
    mouth_z = _skull_z(0, MOUTH_Y) + 0.004
    lips = b.add(("skin", "lips"), lip_torus((0, MOUTH_Y, mouth_z), 0.022, 0.010, 0.005, 24, 12))
    nose_c = (0.0, -0.012, _skull_z(0, -0.012) - 0.002)
    nose = b.add(("skin", "nose"), uv_ellipsoid(nose_c, (0.011, 0.018, 0.012), 15, 24))
    ears = {}
    for side, sx in (("left", 1.0), ("right", -1.0)):
        ears[side] = b.add(
            ("skin", f"{side}_ear"),
            uv_ellipsoid((sx * 0.077, 0.0, -0.005), (0.006, 0.025, 0.014), 15, 24),
        )
    eyes = {}
    for side, sx in (("left", 1.0), ("right", -1.0)):
        z = _skull_z(EYE_X, EYE_Y) - 0.006
        eyes[side] = b.add(
            (f"{side}_eye",), uv_ellipsoid((sx * EYE_X, EYE_Y, z), (EYE_RADIUS,) * 3, 15, 24)
        )
    upper_teeth = b.add(
        ("upper_teeth",), grid_box((0, -0.0465, mouth_z - 0.008), (0.030, 0.007, 0.006), 4)
    )
    lower_teeth = b.add(
        ("lower_teeth",), grid_box((0, -0.054, mouth_z - 0.008), (0.030, 0.007, 0.006), 4)
    )
    tongue_c = (0.0, -0.058, mouth_z - 0.030)
    tongue = b.add(("tongue",), uv_ellipsoid(tongue_c, (0.018, 0.006, 0.028), 11, 24))

    vertices = np.vstack(b.vertices)
    faces = np.vstack(b.faces)
    parts = {name: np.concatenate(chunks) for name, chunks in b.parts.items()}
    for side in ("left", "right"):
        eye = eyes[side]
        centre = vertices[eye].mean(axis=0)
        rel = vertices[eye] - centre
        cos_to_gaze = rel[:, 2] / np.linalg.norm(rel, axis=1)
        parts[f"{side}_pupil"] = eye[cos_to_gaze > np.cos(np.radians(25))]

    def nearest(indices: np.ndarray, target: Vec3) -> int:
        d = np.linalg.norm(vertices[indices] - np.asarray(target), axis=1)
        return int(indices[int(np.argmin(d))])

    def on_skull(x: float, y: float) -> int:
        return nearest(skull, (x, y, _skull_z(x, y)))

    def lip(u_deg: float, v_deg: float) -> int:
        return int(lips[0] + round(u_deg / 15) % 24 * 12 + round(v_deg / 30) % 12)

    fp_vertex: dict[str, int] = {
        "2.1": on_skull(0, -0.092),
        "2.10": on_skull(0, -0.080),
        "2.11": on_skull(0.015, -0.086),
        "2.12": on_skull(-0.015, -0.086),
        "2.13": on_skull(0.062, -0.055),
        "2.14": on_skull(-0.062, -0.055),
        "2.2": lip(90, 180),
        "2.3": lip(270, 180),
        "2.4": lip(0, 180),
        "2.5": lip(180, 180),
        "2.6": lip(60, 180),
        "2.7": lip(120, 180),
        "2.8": lip(300, 180),
        "2.9": lip(240, 180),
        "8.1": lip(90, 0),
        "8.2": lip(270, 0),
        "8.3": lip(0, 0),
        "8.4": lip(180, 0),
        "8.5": lip(60, 0),
        "8.6": lip(120, 0),
        "8.7": lip(300, 0),
        "8.8": lip(240, 0),
        "8.9": lip(105, 0),
        "8.10": lip(75, 0),
        "3.1": on_skull(EYE_X, EYE_Y + 0.014),
        "3.2": on_skull(-EYE_X, EYE_Y + 0.014),
        "3.3": on_skull(EYE_X, EYE_Y - 0.014),
        "3.4": on_skull(-EYE_X, EYE_Y - 0.014),
        "3.7": on_skull(EYE_X + 0.015, EYE_Y),
        "3.11": on_skull(EYE_X - 0.015, EYE_Y),
        "3.8": on_skull(-EYE_X + 0.015, EYE_Y),
        "3.12": on_skull(-EYE_X - 0.015, EYE_Y),
        "3.9": on_skull(EYE_X, EYE_Y - 0.018),
        "3.10": on_skull(-EYE_X, EYE_Y - 0.018),
        "3.13": on_skull(EYE_X, EYE_Y + 0.018),
        "3.14": on_skull(-EYE_X, EYE_Y + 0.018),
        "4.1": on_skull(0.016, 0.046),
        "4.2": on_skull(-0.016, 0.046),
        "4.3": on_skull(0.033, 0.052),
        "4.4": on_skull(-0.033, 0.052),
        "4.5": on_skull(0.050, 0.046),
        "4.6": on_skull(-0.050, 0.046),
        "5.1": on_skull(0.048, MOUTH_Y),
        "5.2": on_skull(-0.048, MOUTH_Y),
        "5.3": on_skull(0.040, -0.006),
        "5.4": on_skull(-0.040, -0.006),
        "9.1": nearest(nose, (0.011, nose_c[1], nose_c[2])),
        "9.2": nearest(nose, (-0.011, nose_c[1], nose_c[2])),
        "9.3": nearest(nose, (0.0, nose_c[1], nose_c[2] + 0.012)),
        "9.15": nearest(nose, (0.0, nose_c[1] - 0.018, nose_c[2])),
        "9.4": nearest(nose, (-0.007, nose_c[1] - 0.013, nose_c[2] + 0.005)),
        "9.5": nearest(nose, (0.007, nose_c[1] - 0.013, nose_c[2] + 0.005)),
        "9.12": nearest(nose, (0.0, nose_c[1] + 0.010, nose_c[2] + 0.010)),
        "9.13": nearest(nose, (0.008, nose_c[1] + 0.006, nose_c[2] + 0.006)),
        "9.14": nearest(nose, (-0.008, nose_c[1] + 0.006, nose_c[2] + 0.006)),
        "9.6": on_skull(-0.007, 0.012),
        "9.7": on_skull(0.007, 0.012),
        "9.8": nearest(upper_teeth, (0, -0.043, mouth_z - 0.005)),
        "9.10": nearest(upper_teeth, (0, -0.050, mouth_z - 0.005)),
        "9.11": nearest(lower_teeth, (0, -0.0505, mouth_z - 0.005)),
        "9.9": nearest(lower_teeth, (0, -0.0575, mouth_z - 0.005)),
        "6.1": nearest(tongue, (0, tongue_c[1], tongue_c[2] + 0.028)),
        "6.2": nearest(tongue, (0, tongue_c[1] + 0.006, tongue_c[2])),
        "6.3": nearest(tongue, (0.018, tongue_c[1], tongue_c[2])),
        "6.4": nearest(tongue, (-0.018, tongue_c[1], tongue_c[2])),
        "11.1": on_skull(0, 0.085),
        "11.2": on_skull(-0.030, 0.080),
        "11.3": on_skull(0.030, 0.080),
        "11.4": 0,
        "11.6": nearest(skull, (0, 0.025, -c_)),
    }
    for side, sx, (top, back, bottom, low, high) in (
        ("left", 1.0, ("10.1", "10.3", "10.5", "10.7", "10.9")),
        ("right", -1.0, ("10.2", "10.4", "10.6", "10.8", "10.10")),
    ):
        ear = ears[side]
        fp_vertex[top] = nearest(ear, (sx * 0.077, 0.025, -0.005))
        fp_vertex[back] = nearest(ear, (sx * 0.077, 0.0, -0.019))
        fp_vertex[bottom] = nearest(ear, (sx * 0.077, -0.025, -0.005))
        fp_vertex[low] = nearest(ear, (sx * 0.071, -0.018, -0.005))
        fp_vertex[high] = nearest(ear, (sx * 0.071, 0.018, -0.005))
    for side, point in (("left", "3.5"), ("right", "3.6")):
        eye = eyes[side]
        fp_vertex[point] = int(eye[np.argmax(vertices[eye, 2])])
    feature_points: dict[str, Vec3] = {
        name: tuple(float(c) for c in vertices[index])  # type: ignore[misc]
        for name, index in fp_vertex.items()
    }
    feature_points["7.1"] = (0.0, -0.065, -0.025)
    feature_points["11.5"] = (0.0, b_ + 0.005, 0.0)

    skin = parts["skin"]
    mouth_y = float(vertices[lips, 1].mean())
    upper = skin[vertices[skin, 1] > mouth_y + 1e-6]
    lower = skin[vertices[skin, 1] < mouth_y - 1e-6]
    masks: dict[int, tuple[int, ...]] = {}
    for fap in (4, 8, 9, 17, 51, 55, 56):
        masks[fap] = tuple(int(i) for i in upper)
    for fap in (3, 5, 10, 11, 14, 15, 16, 52, 57, 58):
        masks[fap] = tuple(int(i) for i in lower)
    for fap, side in ((65, "left"), (66, "right"), (67, "left"), (68, "right")):
        masks[fap] = tuple(int(i) for i in ears[side])

    eye_centre = {side: tuple(float(c) for c in vertices[eyes[side]].mean(axis=0)) for side in eyes}
    jaw_radius = float(np.linalg.norm(np.asarray(feature_points["9.11"]) - np.asarray(JAW_PIVOT)))
    deformers = _settings(eye_centre, jaw_radius, tongue_c)
    params = FaceParameters(
        feature_points=feature_points,
        keep_syncs=(19, 20, 21, 22, 31, 32, 33, 34, 35, 36),
        deformers=deformers,
        vertex_masks=masks,
    )
    return Face(vertices=vertices, faces=faces, parts=parts, params=params, name="test-head")


UP: Vec3 = (0.0, 1.0, 0.0)
DOWN: Vec3 = (0.0, -1.0, 0.0)
LEFT: Vec3 = (1.0, 0.0, 0.0)
RIGHT: Vec3 = (-1.0, 0.0, 0.0)
FORWARD: Vec3 = (0.0, 0.0, 1.0)


def _settings(
    eye_centre: dict[str, tuple[float, ...]], jaw_radius: float, tongue_c: Vec3
) -> tuple[DeformerSetting, ...]:
    d: list[DeformerSetting] = []
    jaw_scale: Vec3 = (1.4, 0.6, 1.0)
    # group 2: jaw, inner lips, chin
    d.append(EaseDeformer(3, DOWN, 0.05, jaw_scale, True, False))
    d.append(EaseDeformer(14, FORWARD, 0.05, jaw_scale, True, False))
    d.append(EaseDeformer(15, RIGHT, 0.05, jaw_scale, True, False))
    upper_inner = {4: DOWN, 8: DOWN, 9: DOWN, 17: FORWARD}
    lower_inner = {5: UP, 10: UP, 11: UP, 16: FORWARD}
    for fap, direction in {**upper_inner, **lower_inner}.items():
        d.append(EaseDeformer(fap, direction, 0.012, (1.0, 1.0, 1.0), True, False))
    d.append(EaseDeformer(6, LEFT, 0.012))
    d.append(EaseDeformer(7, RIGHT, 0.012))
    d.append(EaseDeformer(12, UP, 0.012, ease=-20.0))
    d.append(EaseDeformer(13, UP, 0.012, ease=-20.0))
    d.append(SmoothDeformer(18, UP, 0.02, smooth_center=50.0, smooth_side=50.0))
    # group 3: eyelids
    lid_scale: Vec3 = (1.3, 0.5, 1.0)
    d.append(EaseDeformer(19, DOWN, 0.014, lid_scale, ease=-20.0))
    d.append(EaseDeformer(20, DOWN, 0.014, lid_scale, ease=-20.0))
    d.append(EaseDeformer(21, UP, 0.014, lid_scale, ease=20.0))
    d.append(EaseDeformer(22, UP, 0.014, lid_scale, ease=20.0))
    # pupils dilate before the eyes turn
    d.append(DilateDeformer(29, "left_pupil", FORWARD, pivot_fp="3.5"))
    d.append(DilateDeformer(30, "right_pupil", FORWARD, pivot_fp="3.6"))
    # group 4: eyebrows
    for fap in (31, 32, 33, 34, 35, 36):
        d.append(CosineDeformer(fap, UP, 0.014))
    d.append(CosineDeformer(37, RIGHT, 0.016))
    d.append(CosineDeformer(38, LEFT, 0.016))
    # group 5: cheeks
    d.append(SmoothDeformer(39, LEFT, 0.025, smooth_center=50.0, smooth_side=50.0))
    d.append(SmoothDeformer(40, RIGHT, 0.025, smooth_center=50.0, smooth_side=50.0))
    d.append(SmoothDeformer(41, UP, 0.02, smooth_center=25.0, smooth_side=75.0))
    d.append(SmoothDeformer(42, UP, 0.02, smooth_center=25.0, smooth_side=75.0))
    # group 6: tongue (displacements on the tongue only)
    d.append(EaseDeformer(43, RIGHT, 0.025, part="tongue"))
    d.append(EaseDeformer(44, UP, 0.025, part="tongue"))
    d.append(EaseDeformer(45, FORWARD, 0.025, part="tongue"))
    d.append(EaseDeformer(46, UP, 0.03, part="tongue"))
    # group 8: outer lips
    for fap, direction in {51: DOWN, 55: DOWN, 56: DOWN, 52: UP, 57: UP, 58: UP}.items():
        d.append(EaseDeformer(fap, direction, 0.014, (1.0, 1.0, 1.0), True, False))
    d.append(EaseDeformer(53, LEFT, 0.014))
    d.append(EaseDeformer(54, (-1.0, 0.0, -0.3), 0.014))  # the corner also moves back
    d.append(EaseDeformer(59, UP, 0.014, ease=-20.0))
    d.append(EaseDeformer(60, UP, 0.014, ease=-20.0))
    # group 9: nose
    d.append(EaseDeformer(61, LEFT, 0.010))
    d.append(EaseDeformer(62, RIGHT, 0.010))
    d.append(EaseDeformer(63, UP, 0.015))
    d.append(EaseDeformer(64, RIGHT, 0.015))
    # group 10: ears (masked to the ear)
    for fap, direction in ((65, UP), (66, UP), (67, LEFT), (68, RIGHT)):
        d.append(EaseDeformer(fap, direction, 0.05, (1.0, 1.0, 1.0), True, False))
    # rigid parts, in order: tongue roll, eyes, jaw, then the head carries all
    d.append(RollDeformer(47, "tongue", FORWARD, pivot=tongue_c))
    for fap, side in ((23, "left_eye"), (24, "right_eye")):
        centre = eye_centre[side.split("_")[0]]
        d.append(TransformDeformer(fap, (side,), "rotation", UP, pivot=_vec(centre)))
        d.append(TransformDeformer(fap + 2, (side,), "rotation", LEFT, pivot=_vec(centre)))
        d.append(TransformDeformer(fap + 4, (side,), "translation", FORWARD))
    jaw = ("lower_teeth", "tongue")
    d.append(TransformDeformer(3, jaw, "rotation", LEFT, 1.0 / jaw_radius, pivot=JAW_PIVOT))
    d.append(TransformDeformer(14, jaw, "translation", FORWARD))
    d.append(TransformDeformer(15, jaw, "translation", RIGHT))
    d.append(TransformDeformer(50, ("all",), "rotation", (0.0, 0.0, 1.0), pivot_fp="7.1"))
    d.append(TransformDeformer(48, ("all",), "rotation", LEFT, pivot_fp="7.1"))
    d.append(TransformDeformer(49, ("all",), "rotation", UP, pivot_fp="7.1"))
    return tuple(d)


def _vec(values: tuple[float, ...]) -> Vec3:
    return (float(values[0]), float(values[1]), float(values[2]))


def subdivide_face(face: Face, times: int = 1) -> Face:
    """The face with every triangle split in four, ``times`` times (for benchmarks).

    A new mid-edge vertex joins a part or a vertex mask when both ends of its
    edge are in it. The vertices are then ordered part by part (skin, eyes,
    teeth, tongue), so that each rigid part is one contiguous range, which
    the rig moves as a view (as a real face file should store them).
    Feature points are positions and stay valid; settings must not name
    vertex indices (FaceDefMesh), which this reordering would break.
    """
    import trimesh

    vertices = np.asarray(face.vertices, dtype=np.float64)
    faces = np.asarray(face.faces)
    n = len(vertices)
    groups: dict[str, np.ndarray] = {f"part:{k}": v for k, v in face.parts.items()}
    groups.update(
        {f"mask:{k}": np.asarray(v, dtype=np.int64) for k, v in face.params.vertex_masks.items()}
    )
    keys = list(groups)
    for _ in range(times):
        member = np.zeros((len(vertices), len(keys)))
        for column, key in enumerate(keys):
            member[groups[key], column] = 1.0
        vertices, faces, attributes = trimesh.remesh.subdivide(  # type: ignore[no-untyped-call]
            vertices, faces, vertex_attributes={"member": member}
        )
        inside = np.asarray(attributes["member"]) > 0.999
        groups = {key: np.flatnonzero(inside[:, column]) for column, key in enumerate(keys)}
    assert np.allclose(vertices[:n], face.vertices)
    label = np.zeros(len(vertices), dtype=np.int64)
    for rank, part in enumerate(
        ("left_eye", "right_eye", "upper_teeth", "lower_teeth", "tongue"), start=1
    ):
        if f"part:{part}" in groups:
            label[groups[f"part:{part}"]] = rank
    order = np.argsort(label, kind="stable")
    new_index = np.empty_like(order)
    new_index[order] = np.arange(order.size)
    vertices = vertices[order]
    faces = new_index[faces]
    groups = {key: np.sort(new_index[value]) for key, value in groups.items()}
    parts = {k[5:]: v for k, v in groups.items() if k.startswith("part:")}
    masks = {
        int(k[5:]): tuple(int(i) for i in v) for k, v in groups.items() if k.startswith("mask:")
    }
    params = FaceParameters(
        feature_points=face.params.feature_points,
        keep_syncs=face.params.keep_syncs,
        deformers=face.params.deformers,
        vertex_masks=masks,
    )
    return Face(vertices, faces, parts, params, name=f"{face.name}-x{4**times}")
