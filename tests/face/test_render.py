"""Offscreen rendering of faces (realizer.face.render).

Tests that need an OpenGL context are marked ``opengl`` and skip, saying why,
where none can be made (no OSMesa/EGL, or PyOpenGL missing).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from realizer.face import render
from realizer.face.render import FaceRenderer, Framing, RenderUnavailableError

DATA = Path(render.__file__).parent / "data" / "default_face" / "default_face.npz"


@dataclass(frozen=True)
class MeshFace:
    """The shipped default mesh with no rig: enough for the renderer."""

    vertices: np.ndarray
    faces: np.ndarray
    parts: dict[str, Any] = field(default_factory=dict)


@pytest.fixture(scope="module")
def mesh_face() -> MeshFace:
    data = np.load(DATA)
    parts = {key[5:]: data[key] for key in data.files if key.startswith("part:")}
    return MeshFace(data["vertices"], data["faces"], parts)


@pytest.fixture(scope="module")
def renderer(mesh_face: MeshFace) -> Any:
    try:
        r = FaceRenderer(mesh_face, 160, 160)
    except RenderUnavailableError as error:
        pytest.skip(f"no OpenGL offscreen context here: {error}")
    yield r
    r.close()


def test_vertex_normals_of_a_flat_square_point_along_z() -> None:
    vertices = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=np.float32)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    normals = render.vertex_normals(vertices, faces)
    np.testing.assert_allclose(normals, np.tile([0, 0, 1], (4, 1)), atol=1e-6)


def test_colours_draw_a_dark_pupil_at_the_front_of_each_eye(mesh_face: MeshFace) -> None:
    colours = render.vertex_colours(mesh_face)
    eyes = render.face_part(mesh_face, "eyes")
    assert eyes is not None
    v = mesh_face.vertices[eyes]
    for side in (v[:, 0] > 0, v[:, 0] < 0):
        front = eyes[side][np.argmax(v[side, 2])]
        back = eyes[side][np.argmin(v[side, 2])]
        assert colours[front].sum() < 0.3  # pupil
        assert colours[back].sum() > 2.5  # sclera
    mouth = render.part_indices(mesh_face.parts["mouth_inside"])
    skin = np.setdiff1d(render.part_indices(mesh_face.parts["skin"]), mouth)
    np.testing.assert_allclose(colours[skin], np.tile(render.SKIN_RGB, (len(skin), 1)), atol=1e-6)
    np.testing.assert_allclose(
        colours[mouth], np.tile(render.MOUTH_RGB, (len(mouth), 1)), atol=1e-6
    )


def test_choose_platform_keeps_a_platform_the_user_set(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PYOPENGL_PLATFORM", "egl")
    assert render.choose_platform() == "egl"


def test_choose_platform_picks_osmesa_without_a_gpu(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("PYOPENGL_PLATFORM", raising=False)
    monkeypatch.setattr(render.glob, "glob", lambda pattern: [])
    monkeypatch.setattr(render.os.path, "exists", lambda path: False)
    assert render.choose_platform() == "osmesa"


@pytest.mark.opengl
def test_a_render_is_an_rgb_image_of_the_requested_size(renderer: Any) -> None:
    image = renderer.render()
    assert image.shape == (160, 160, 3)
    assert image.dtype == np.uint8


@pytest.mark.opengl
def test_the_face_is_centred_on_a_black_background(renderer: Any) -> None:
    image = renderer.render().astype(int)
    covered = image.sum(axis=2) > 0
    assert 0.25 < covered.mean() < 0.8
    assert not covered[0].any() and not covered[:, 0].any() and not covered[:, -1].any()
    _, cols = np.nonzero(covered)
    assert abs(cols.mean() - 80) < 4  # the head is symmetric about x = 0
    # left and right halves mirror each other
    mirrored = np.abs(covered.astype(int) - covered[:, ::-1].astype(int)).mean()
    assert mirrored < 0.02


@pytest.mark.opengl
def test_projected_pupils_land_on_dark_pixels(renderer: Any, mesh_face: MeshFace) -> None:
    image = renderer.render().astype(int)
    eyes = render.face_part(mesh_face, "eyes")
    assert eyes is not None
    v = mesh_face.vertices[eyes]
    brightness = image.sum(axis=2)
    face_median = np.median(brightness[brightness > 0])
    for side in (v[:, 0] > 0, v[:, 0] < 0):
        pupil = v[side][np.argmax(v[side, 2])]
        col, row = np.round(renderer.project(pupil[None])[0]).astype(int)
        # the darkest pixel within one pixel (a glint may sit on the pupil)
        assert brightness[row - 1 : row + 2, col - 1 : col + 2].min() < 0.5 * face_median


@pytest.mark.opengl
def test_renders_of_the_same_vertices_are_identical(renderer: Any) -> None:
    np.testing.assert_array_equal(renderer.render(), renderer.render())


@pytest.mark.opengl
def test_moving_the_chin_changes_only_pixels_below_the_nose(
    renderer: Any, mesh_face: MeshFace
) -> None:
    neutral = renderer.render().astype(int)
    moved = mesh_face.vertices.copy()
    chin = (moved[:, 1] < 0.635) & (moved[:, 2] > 0.12)
    moved[chin, 1] -= 0.01
    changed = np.abs(renderer.render(moved).astype(int) - neutral).sum(axis=2) > 30
    assert changed.any()
    rows = np.nonzero(changed)[0]
    nose_row = renderer.project(np.array([[0.0, 0.69, 0.168]]))[0, 1]
    assert rows.min() > nose_row


@pytest.mark.opengl
def test_a_side_view_shows_the_profile(renderer: Any) -> None:
    front = renderer.render(view="front")
    side = renderer.render(view="left")
    assert not np.array_equal(front, side)
    renderer.render(view="front")  # switching back works


@pytest.mark.opengl
def test_wrong_vertex_count_is_refused(renderer: Any) -> None:
    with pytest.raises(ValueError, match="shape"):
        renderer.render(np.zeros((3, 3), dtype=np.float32))


def test_framing_of_points_covers_them_with_a_margin() -> None:
    framing = Framing.of_points(np.array([[0, 0, 0], [1, 2, 3]], dtype=float), margin=0.1)
    assert framing.centre == (0.5, 1.0, 1.5)
    assert framing.height == pytest.approx(2.4)


@pytest.fixture(scope="module")
def default_renderer() -> Any:
    from realizer.face.default import load_default_face

    try:
        r = FaceRenderer(load_default_face(), 320, 320)
    except RenderUnavailableError as error:
        pytest.skip(f"no OpenGL offscreen context here: {error}")
    yield r
    r.close()


@pytest.mark.opengl
def test_multisampling_smooths_the_silhouette(mesh_face: MeshFace) -> None:
    try:
        plain = FaceRenderer(mesh_face, 160, 160, samples=1)
        smooth = FaceRenderer(mesh_face, 160, 160, samples=4)
    except RenderUnavailableError as error:
        pytest.skip(f"no OpenGL offscreen context here: {error}")
    with plain, smooth:
        hard = plain.render().astype(int).sum(axis=2)
        soft = smooth.render().astype(int).sum(axis=2)
    assert smooth.samples > 1

    # Along the head's outline against the black background, anti-aliased
    # pixels are only partly covered, so the outermost lit pixel of each row
    # is dimmer than without multisampling.
    def outermost(image: np.ndarray) -> float:
        values = []
        for line in image[40:120]:
            lit = np.nonzero(line > 0)[0]
            if len(lit):
                values += [line[lit[0]], line[lit[-1]]]
        return float(np.mean(values))

    assert outermost(soft) < 0.8 * outermost(hard)


@pytest.mark.opengl
def test_the_default_face_has_dark_eyebrows(default_renderer: Any) -> None:
    from realizer.face.default import load_default_face

    face = load_default_face()
    image = default_renderer.render().astype(int).sum(axis=2)
    for name in ("4.3", "4.4"):
        arch = face.feature_position(name)
        below_arch = arch - np.array([0, 0.0025, 0])
        col, row = np.round(default_renderer.project(below_arch[None])[0]).astype(int)
        forehead_point = arch + np.array([0, 0.012, 0])
        above = np.round(default_renderer.project(forehead_point[None])[0]).astype(int)
        brow = image[row - 1 : row + 2, col - 2 : col + 3].mean()
        forehead = image[above[1] - 1 : above[1] + 2, above[0] - 2 : above[0] + 3].mean()
        assert brow < 0.7 * forehead, name


@pytest.mark.opengl
def test_the_mouth_cavity_is_dark(default_renderer: Any) -> None:
    from realizer.face.default import load_default_face
    from realizer.face.deform import deform

    face = load_default_face()
    values = np.zeros(68)
    values[2] = 600  # open_jaw
    image = default_renderer.render(deform(face, values)).astype(int).sum(axis=2)
    lips = (face.feature_position("2.2") + face.feature_position("2.3")) / 2
    col, row = np.round(default_renderer.project(lips[None])[0]).astype(int)
    cheek = np.round(default_renderer.project(face.feature_position("5.1")[None])[0]).astype(int)
    opening = image[row : row + 8, col - 3 : col + 4]
    assert opening.min() < 0.5 * image[cheek[1], cheek[0]]


@pytest.mark.opengl
def test_a_closed_renderer_refuses_to_render(mesh_face: MeshFace) -> None:
    try:
        r = FaceRenderer(mesh_face, 16, 16)
    except RenderUnavailableError as error:
        pytest.skip(f"no OpenGL offscreen context here: {error}")
    r.close()
    r.close()  # idempotent
    with pytest.raises(RenderUnavailableError, match="closed"):
        r.render()


def _resident_bytes() -> int:
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


@pytest.mark.opengl
@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/statm").exists(), reason="needs /proc to read memory")
def test_rendering_2000_frames_keeps_memory_flat() -> None:
    """Offscreen video must not grow per frame (the buffers are rewritten in
    place): 2,000 deformed frames add less than 50 MB of resident memory."""
    from realizer.face.default import load_default_face
    from realizer.face.deform import deform

    face = load_default_face()
    try:
        r = FaceRenderer(face, 64, 48)
    except RenderUnavailableError as error:
        pytest.skip(f"no OpenGL offscreen context here: {error}")
    values = np.zeros(68)
    with r:
        for i in range(50):  # warm up: shader variants, allocator pools
            values[2] = 10 * (i % 40)
            r.render(deform(face, values))
        before = _resident_bytes()
        for i in range(2000):
            values[2] = 10 * (i % 40)
            values[18] = 25 * (i % 41)
            r.render(deform(face, values))
        grown = _resident_bytes() - before
    assert grown < 50 * 2**20, f"resident memory grew by {grown / 2**20:.1f} MiB"
