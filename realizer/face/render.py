"""Offscreen OpenGL rendering of a (deformed) face to an RGB image.

This is the only module of the realizer that imports pyrender and OpenGL
(heavy dependencies stay at the edges, see docs/architecture.md); it imports
them lazily, on the first render, so that importing :mod:`realizer.face.render` costs nothing.

The renderer draws the face from a fixed frontal camera (or a fixed side
camera) framed on the *neutral* face, so that a deformation shows up as a
change of pixels and two renders of the same face line up pixel for pixel,
which the difference images of Paul 2010, section 4.4.2 (figure 4.20) need.

Platform: PyOpenGL picks its back end from ``PYOPENGL_PLATFORM`` when OpenGL
is first imported. If the variable is unset, we choose ``egl`` where a GPU
render node (``/dev/dri/renderD*``) or an NVIDIA device is present, and
``osmesa`` (Mesa's software rasteriser, the Debian package libosmesa6)
otherwise: OSMesa needs no display and no GPU, and works in containers.
Set ``PYOPENGL_PLATFORM`` yourself to override. pyrender from PyPI pins
PyOpenGL 3.1.0, whose OSMesa binding is broken; scripts/setup.sh installs
pyrender without its pins and a PyOpenGL >= 3.1.7.

One :class:`FaceRenderer` owns one ``pyrender.OffscreenRenderer`` (one GL
context) and reuses it for every image: creating contexts is slow, and
OSMesa leaks when many are made and deleted.
"""

from __future__ import annotations

import glob
import os
import threading
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, Protocol

import numpy as np
import numpy.typing as npt

from realizer.errors import RealizerError

__all__ = [
    "FaceRenderer",
    "Framing",
    "RenderUnavailableError",
    "View",
    "choose_platform",
    "render_face",
    "save_png",
    "vertex_colours",
]

View = Literal["front", "left", "right"]

#: Linear RGB colours of the parts (0..1), chosen to read well in greyscale
#: difference images too.
SKIN_RGB = (0.74, 0.54, 0.44)
LIP_RGB = (0.72, 0.42, 0.40)
SCLERA_RGB = (0.93, 0.92, 0.90)
IRIS_RGB = (0.30, 0.42, 0.55)
PUPIL_RGB = (0.03, 0.03, 0.03)
TEETH_RGB = (0.95, 0.93, 0.85)
TONGUE_RGB = (0.75, 0.35, 0.35)
MOUTH_RGB = (0.32, 0.10, 0.10)
BACKGROUND_RGB = (0.0, 0.0, 0.0)

#: Iris and pupil as angles (radians) from the eyeball's front pole: an iris
#: of 12 mm on a 24 mm eyeball is about 30 degrees, a pupil of 4 mm about 10.
IRIS_ANGLE = 0.52
PUPIL_ANGLE = 0.19

#: Vertical field of view of the camera; narrow, like a portrait lens, so
#: that the face is seen nearly orthographically.
FIELD_OF_VIEW = np.radians(15.0)


class RenderUnavailableError(RealizerError):
    """No OpenGL offscreen context can be made here (no OSMesa or EGL, or
    pyrender is not installed). Install them with ``bash scripts/setup.sh``."""


class RenderableFace(Protocol):
    """What the renderer needs of a face (realizer.face.model.Face has it)."""

    @property
    def vertices(self) -> npt.NDArray[np.floating[Any]]: ...  # (n, 3) neutral, metres

    @property
    def faces(self) -> npt.NDArray[np.integer[Any]]: ...  # (m, 3) triangles

    @property
    def parts(self) -> Mapping[str, Any]: ...  # name -> vertex range or indices


@dataclass(frozen=True, slots=True)
class Framing:
    """The part of space the camera shows: a centre and a height, metres."""

    centre: tuple[float, float, float]
    height: float

    @classmethod
    def of_points(cls, points: npt.NDArray[np.floating[Any]], margin: float = 0.08) -> Framing:
        """Frame the bounding box of ``points`` (k, 3) with a relative margin."""
        lo = points.min(axis=0)
        hi = points.max(axis=0)
        centre = (lo + hi) / 2
        height = float(max(hi[1] - lo[1], hi[0] - lo[0])) * (1 + 2 * margin)
        return cls((float(centre[0]), float(centre[1]), float(centre[2])), height)


def choose_platform() -> str:
    """The PyOpenGL platform to use, setting ``PYOPENGL_PLATFORM`` if unset."""
    chosen = os.environ.get("PYOPENGL_PLATFORM")
    if not chosen:
        gpu = bool(glob.glob("/dev/dri/renderD*")) or os.path.exists("/dev/nvidia0")
        chosen = "egl" if gpu else "osmesa"
        os.environ["PYOPENGL_PLATFORM"] = chosen
    return chosen


def part_indices(part: Any) -> npt.NDArray[np.int64]:
    """Vertex indices of a part given as a ``(start, stop)`` range, a ``range``,
    a slice, or an index array."""
    if isinstance(part, range):
        return np.arange(part.start, part.stop, dtype=np.int64)
    if isinstance(part, slice):
        return np.arange(part.start or 0, part.stop, dtype=np.int64)
    array = np.asarray(part, dtype=np.int64)
    if array.shape == (2,):
        # A (start, stop) pair: ambiguous with a two-vertex index list, but no
        # part of a face has two vertices.
        return np.arange(array[0], array[1], dtype=np.int64)
    return array.reshape(-1)


#: Part groups: a face may name its eyes and teeth one by one.
PART_MEMBERS: dict[str, tuple[str, ...]] = {
    "eyes": ("left_eye", "right_eye", "eye_l", "eye_r"),
    "teeth": ("upper_teeth", "lower_teeth", "teeth_upper", "teeth_lower"),
}


def face_part(face: RenderableFace, name: str) -> npt.NDArray[np.int64] | None:
    """Vertex indices of part ``name`` (or of its members, for "eyes" and
    "teeth"), or None when the face has no such part."""
    if name in face.parts:
        return part_indices(face.parts[name])
    members = [part_indices(face.parts[m]) for m in PART_MEMBERS.get(name, ()) if m in face.parts]
    if members:
        return np.concatenate(members)
    return None


def vertex_colours(
    face: RenderableFace, lip_vertices: npt.NDArray[np.int64] | None = None
) -> npt.NDArray[np.float32]:
    """Per-vertex RGB (n, 3) in 0..1: part colours, and on each eyeball an
    iris and a pupil drawn around its front (+z) pole.

    The eyes part is split into the two eyeballs by the sign of x relative to
    its middle; each ball's centre is the mean of its vertices. Colours are
    computed on the neutral face, so they rotate with the eyeballs.
    """
    vertices = np.asarray(face.vertices, dtype=np.float64)
    colours = np.empty((len(vertices), 3), dtype=np.float32)
    colours[:] = SKIN_RGB
    if lip_vertices is not None:
        colours[lip_vertices] = LIP_RGB
    for name, rgb in (("teeth", TEETH_RGB), ("tongue", TONGUE_RGB), ("mouth_inside", MOUTH_RGB)):
        indices = face_part(face, name)
        if indices is not None:
            colours[indices] = rgb
    eyes = face_part(face, "eyes")
    if eyes is not None and len(eyes):
        x = vertices[eyes, 0]
        middle = (x.min() + x.max()) / 2
        for ball in (eyes[x >= middle], eyes[x < middle]):
            if len(ball) == 0:
                continue
            centre = vertices[ball].mean(axis=0)
            offsets = vertices[ball] - centre
            cos_angle = offsets[:, 2] / np.maximum(np.linalg.norm(offsets, axis=1), 1e-12)
            angle = np.arccos(np.clip(cos_angle, -1.0, 1.0))
            ball_rgb = np.where(
                (angle < PUPIL_ANGLE)[:, None],
                PUPIL_RGB,
                np.where((angle < IRIS_ANGLE)[:, None], IRIS_RGB, SCLERA_RGB),
            )
            colours[ball] = ball_rgb
    return colours


def vertex_normals(
    vertices: npt.NDArray[np.floating[Any]], faces: npt.NDArray[np.integer[Any]]
) -> npt.NDArray[np.float32]:
    """Area-weighted unit vertex normals (n, 3) of a triangle mesh."""
    v = np.asarray(vertices, dtype=np.float64)
    tri = v[faces]
    face_normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    corners = np.asarray(faces).reshape(-1)
    normals = np.stack(
        [
            np.bincount(corners, np.repeat(face_normals[:, k], 3), minlength=len(v))
            for k in range(3)
        ],
        axis=1,
    )
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    unit: npt.NDArray[np.float32] = (normals / np.maximum(length, 1e-20)).astype(np.float32)
    return unit


def _look_at(
    eye: npt.NDArray[np.float64], target: npt.NDArray[np.float64]
) -> npt.NDArray[np.float64]:
    """A camera pose (4, 4) at ``eye`` looking at ``target`` with +y up
    (OpenGL cameras look along their -z)."""
    back = eye - target
    back /= np.linalg.norm(back)
    right = np.cross([0.0, 1.0, 0.0], back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    pose = np.eye(4)
    pose[:3, 0] = right
    pose[:3, 1] = up
    pose[:3, 2] = back
    pose[:3, 3] = eye
    return pose


class FaceRenderer:
    """Renders one face, neutral or deformed, at a fixed size and camera.

    Create one per face and size and call :meth:`render` as often as needed:
    the GL context, scene, camera and lights are made once. Not thread-safe
    (one GL context); a lock serialises calls. Call :meth:`close` (or use it
    as a context manager) to free the context.

    Raises :class:`RenderUnavailableError` when no OpenGL context can be made.
    """

    def __init__(
        self,
        face: RenderableFace,
        width: int = 512,
        height: int = 512,
        *,
        framing: Framing | None = None,
        colours: npt.NDArray[np.floating[Any]] | None = None,
        supersample: int = 2,
    ) -> None:
        self.face = face
        self.width = width
        self.height = height
        self.supersample = supersample
        self.framing = framing or Framing.of_points(np.asarray(face.vertices))
        self._faces = np.ascontiguousarray(face.faces, dtype=np.uint32)
        if colours is None:
            # A face may carry its own colours (realizer.face.model.Face.attributes).
            attributes = getattr(face, "attributes", None) or {}
            colours = attributes.get("colours")
            if colours is not None and np.asarray(colours).dtype == np.uint8:
                colours = np.asarray(colours, dtype=np.float32) / 255.0
        self._colours = np.ascontiguousarray(
            vertex_colours(face) if colours is None else colours, dtype=np.float32
        )
        self._lock = threading.Lock()
        choose_platform()
        try:
            import pyrender
        except Exception as error:  # ImportError, or OpenGL failing to find its library
            raise RenderUnavailableError(f"cannot import pyrender/OpenGL: {error}") from error
        self._pyrender = pyrender
        try:
            self._renderer = pyrender.OffscreenRenderer(width * supersample, height * supersample)
        except Exception as error:  # each GL back end raises its own types
            raise RenderUnavailableError(
                f"cannot create an offscreen OpenGL context "
                f"(PYOPENGL_PLATFORM={os.environ.get('PYOPENGL_PLATFORM')}): {error}"
            ) from error
        self._material = pyrender.MetallicRoughnessMaterial(
            baseColorFactor=(1.0, 1.0, 1.0, 1.0),
            metallicFactor=0.0,
            roughnessFactor=0.65,
            doubleSided=True,
        )
        self._scene = pyrender.Scene(
            bg_color=(*BACKGROUND_RGB, 1.0), ambient_light=(0.28, 0.28, 0.28)
        )
        self._mesh_node: Any = None
        self._camera_node: Any = None
        self._light_nodes: list[Any] = []
        self._view: View | None = None

    def __enter__(self) -> FaceRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        renderer = getattr(self, "_renderer", None)
        if renderer is not None:
            renderer.delete()
            self._renderer = None

    def _set_view(self, view: View) -> None:
        if view == self._view:
            return
        pyrender = self._pyrender
        for node in [self._camera_node, *self._light_nodes]:
            if node is not None:
                self._scene.remove_node(node)
        target = np.array(self.framing.centre, dtype=np.float64)
        distance = self.framing.height / 2 / np.tan(FIELD_OF_VIEW / 2)
        forward = {"front": (0.0, 0.0, 1.0), "left": (1.0, 0.0, 0.0), "right": (-1.0, 0.0, 0.0)}
        direction = np.array(forward[view])
        camera = pyrender.PerspectiveCamera(
            yfov=float(FIELD_OF_VIEW),
            aspectRatio=self.width / self.height,
            znear=distance / 10,
            zfar=distance * 10,
        )
        eye = target + distance * direction
        self._camera_node = self._scene.add(camera, pose=_look_at(eye, target))
        # Key light from above, front and the viewer's left; a weaker fill
        # from the right; the ambient term keeps shadows from going black.
        up = np.array([0.0, 1.0, 0.0])
        side = np.cross(up, direction)
        lights = [
            (2.6, direction + 0.7 * up - 0.6 * side),
            (1.2, direction - 0.2 * up + 0.8 * side),
        ]
        self._light_nodes = [
            self._scene.add(
                pyrender.DirectionalLight(color=(1.0, 1.0, 1.0), intensity=intensity),
                pose=_look_at(target + towards, target),
            )
            for intensity, towards in lights
        ]
        self._view = view

    def project(
        self, points: npt.NDArray[np.floating[Any]], *, view: View = "front"
    ) -> npt.NDArray[np.float64]:
        """Pixel coordinates (k, 2) as (column, row) of 3D points (k, 3),
        metres, in the images :meth:`render` makes with ``view``."""
        pts = np.atleast_2d(np.asarray(points, dtype=np.float64))
        target = np.array(self.framing.centre)
        distance = self.framing.height / 2 / np.tan(FIELD_OF_VIEW / 2)
        forward = {"front": (0.0, 0.0, 1.0), "left": (1.0, 0.0, 0.0), "right": (-1.0, 0.0, 0.0)}
        pose = _look_at(target + distance * np.array(forward[view]), target)
        local = (pts - pose[:3, 3]) @ pose[:3, :3]  # camera coordinates, looking along -z
        focal = (self.height / 2) / np.tan(FIELD_OF_VIEW / 2)
        column = self.width / 2 + focal * local[:, 0] / -local[:, 2]
        row = self.height / 2 - focal * local[:, 1] / -local[:, 2]
        return np.stack([column, row], axis=1)

    def render(
        self,
        vertices: npt.NDArray[np.floating[Any]] | None = None,
        *,
        view: View = "front",
    ) -> npt.NDArray[np.uint8]:
        """Render the face with ``vertices`` (n, 3) metres (default: neutral).

        Returns an RGB image (height, width, 3) uint8.
        """
        if self._renderer is None:
            raise RenderUnavailableError("this FaceRenderer has been closed")
        positions = np.ascontiguousarray(
            self.face.vertices if vertices is None else vertices, dtype=np.float32
        )
        if positions.shape != self._colours.shape:
            raise ValueError(
                f"vertices must have shape {self._colours.shape}, got {positions.shape}"
            )
        pyrender = self._pyrender
        with self._lock:
            self._set_view(view)
            primitive = pyrender.Primitive(
                positions=positions,
                normals=vertex_normals(positions, self._faces),
                color_0=self._colours,
                indices=self._faces,
                material=self._material,
                mode=pyrender.constants.GLTF.TRIANGLES,
            )
            if self._mesh_node is not None:
                self._scene.remove_node(self._mesh_node)
            self._mesh_node = self._scene.add(pyrender.Mesh([primitive]))
            colour, _ = self._renderer.render(self._scene)
        image = np.asarray(colour[..., :3], dtype=np.uint8)
        if self.supersample > 1:
            s = self.supersample
            image = (
                image.reshape(self.height, s, self.width, s, 3)
                .mean(axis=(1, 3))
                .round()
                .astype(np.uint8)
            )
        return image


_shared: dict[tuple[int, int, int], FaceRenderer] = {}


def render_face(
    face: RenderableFace,
    vertices: npt.NDArray[np.floating[Any]] | None = None,
    *,
    size: tuple[int, int] = (512, 512),
    view: View = "front",
) -> npt.NDArray[np.uint8]:
    """Render ``face`` (deformed to ``vertices`` if given) to an RGB image of
    ``size`` (width, height), reusing one renderer per face and size."""
    key = (id(face), size[0], size[1])
    renderer = _shared.get(key)
    if renderer is None or renderer.face is not face:
        renderer = FaceRenderer(face, size[0], size[1])
        _shared[key] = renderer
    return renderer.render(vertices, view=view)


def save_png(image: npt.NDArray[np.uint8], path: str | Path) -> None:
    """Write an RGB (h, w, 3) or grey (h, w) uint8 image as PNG."""
    from PIL import Image

    Image.fromarray(image).save(path, format="PNG", optimize=True)
