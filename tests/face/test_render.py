"""Offscreen rendering of faces (realizer.face.render).

Tests that need an OpenGL context are marked ``opengl`` and skip, saying why,
where none can be made (no OSMesa/EGL, or pyrender missing).
"""

from __future__ import annotations

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
        assert brightness[row, col] < 0.5 * face_median


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
