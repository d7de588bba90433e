"""Offscreen OpenGL rendering of a (deformed) face to an RGB image.

The realizer's own small renderer: OpenGL 3.3 core through PyOpenGL, no scene
graph. One :class:`FaceRenderer` owns one context (:mod:`realizer.face.gl`:
OSMesa on the CPU, EGL on a GPU), one multisampled framebuffer and one set
of vertex buffers; each frame rewrites the positions and normals in place
(``glBufferSubData``), draws, resolves the multisampling in OpenGL
(``glBlitFramebuffer``) and reads the pixels into a preallocated array, so a
long video costs no memory per frame.

What the shaders draw, per pixel: skin, lips and the dark mouth cavity
(teeth, tongue and the mouth's inside darken with depth behind the lips);
teeth with crowns on slab meshes (a gap between crowns, each crown's face
and incisal edge rounded by the normal, the thin edge greyer), from
coordinates along the arch and above the edge (:func:`tooth_coordinates`);
eyeballs with a crisp iris and pupil computed from each fragment's direction
from the eyeball's centre (so they turn with the eye and dilate with the
pupil's vertices); eyebrows and an upper lash line from coordinates laid
along the brow and lid feature points of "Face and 2-D mesh animation in
MPEG-4" (Table 6), so they ride on the deformed skin; a key, a fill and a
rim light with a little specular (wet eyes shine more than skin).

The camera is fixed, frontal (or from either side), framed on the *neutral*
face, so a deformation shows up as a change of pixels and two renders of the
same face line up pixel for pixel, as the difference images of
"Realization and high level specification of facial expressions for
embodied agents" (section 4.4.2, figure 4.20) need.

Platform: PyOpenGL picks its back end from ``PYOPENGL_PLATFORM`` when OpenGL
is first imported. If the variable is unset, :func:`choose_platform` picks
``egl`` where a GPU render node (``/dev/dri/renderD*``) or an NVIDIA device is
present and ``osmesa`` (Mesa's software rasteriser, Debian's libosmesa6)
otherwise. OpenGL is imported lazily, on the first renderer, so importing
this module costs nothing (heavy dependencies stay at the edges, see
docs/architecture.md).
"""

from __future__ import annotations

import contextlib
import ctypes
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
    PyOpenGL is not installed). Install them with ``bash scripts/setup.sh``."""


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


def closed_outward(
    vertices: npt.ArrayLike, faces: npt.NDArray[np.integer[Any]], part: npt.NDArray[np.int64]
) -> bool:
    """Whether the triangles on the vertices ``part`` form a closed surface
    (every edge shared by exactly two of them, in opposite directions) that
    faces outwards (positive signed volume), so its back faces never show."""
    v = np.asarray(vertices, dtype=np.float64)
    inside = np.zeros(len(v), dtype=bool)
    inside[part] = True
    tri = np.asarray(faces, dtype=np.int64)
    tri = tri[inside[tri].all(axis=1)]
    if len(tri) < 4:
        return False
    directed = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    forward = directed[:, 0] * len(v) + directed[:, 1]
    backward = directed[:, 1] * len(v) + directed[:, 0]
    if len(np.unique(forward)) != len(forward) or not np.isin(backward, forward).all():
        return False
    a, b, c = v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]]
    return float(np.einsum("ij,ij->", a, np.cross(b, c))) > 0.0


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


#: Multisampling of the OpenGL framebuffer (samples per pixel, resolved in GL).
SAMPLES = 4
#: Eyebrow and lash colour (linear RGB).
BROW_RGB = (0.10, 0.065, 0.045)
#: Materials (the first component of the ``extra`` vertex attribute).
MATERIAL_SKIN, MATERIAL_EYE, MATERIAL_MOUTH, MATERIAL_TEETH = 0.0, 1.0, 2.0, 3.0
#: The neck fades out between these heights (m) above the skin's lowest point.
NECK_FADE_M = (0.008, 0.04)
#: A brow or lash coordinate that means "nowhere near" (millimetres).
FAR_MM = 1000.0

_VERTEX_SHADER = """
#version 330 core
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;
layout(location = 2) in vec3 colour;
layout(location = 3) in vec4 extra;     // material, cavity
layout(location = 4) in vec4 surface;   // eye direction (neutral)
layout(location = 5) in vec4 lines;     // brow s, brow t (mm), lash s, lash t (mm)
uniform mat4 view_projection;
out vec3 v_position;
out vec3 v_normal;
out vec3 v_colour;
out vec4 v_extra;
out vec4 v_surface;
out vec4 v_lines;
void main() {
    v_lines = lines;
    v_position = position;
    v_normal = normal;
    v_colour = colour;
    v_extra = extra;
    v_surface = surface;
    gl_Position = view_projection * vec4(position, 1.0);
}
"""

_FRAGMENT_SHADER = """
#version 330 core
in vec3 v_position;
in vec3 v_normal;
in vec3 v_colour;
in vec4 v_extra;
in vec4 v_surface;
in vec4 v_lines;
uniform vec3 eye_position;
uniform vec3 light_direction[3];   // towards the light: key, fill, rim
uniform vec3 light_colour[3];
uniform vec3 ambient;
uniform float iris_cos;
uniform float pupil_cos;
uniform vec3 iris_rgb;
uniform vec3 sclera_rgb;
uniform vec3 pupil_rgb;
uniform vec3 brow_rgb;
uniform vec2 neck_fade;
uniform vec3 background;            // heights (m) where the neck fades out
out vec4 fragment;

void main() {
    vec3 n = normalize(v_normal);
    if (!gl_FrontFacing) n = -n;
    vec3 view = normalize(eye_position - v_position);
    float material = v_extra.x;
    vec3 albedo = v_colour;
    float shine = 0.06;
    float power = 24.0;
    if (material > 0.5 && material < 1.5) {
        // Eyeball: iris and pupil from the neutral direction from the centre.
        vec3 d = normalize(v_surface.xyz);
        float c = d.z;
        float fw = max(fwidth(c), 1e-5);
        float iris = smoothstep(iris_cos - fw, iris_cos + fw, c);
        float pupil = smoothstep(pupil_cos - fw, pupil_cos + fw, c);
        float across = clamp((c - iris_cos) / max(pupil_cos - iris_cos, 1e-4), 0.0, 1.0);
        float angle = atan(d.y, d.x);
        float fibres = 0.85 + 0.15 * sin(angle * 41.0) * sin(angle * 17.0 + 1.3);
        vec3 iris_here = iris_rgb * mix(0.55, 1.25, smoothstep(0.0, 0.35, across)) * fibres;
        iris_here = mix(iris_here, iris_rgb * 1.6, 0.35 * smoothstep(0.6, 1.0, across));
        albedo = mix(sclera_rgb, iris_here, iris);
        albedo = mix(albedo, pupil_rgb, pupil);
        shine = 0.9;
        power = 90.0;
    } else if (material < 0.5) {
        // Skin: eyebrows and the upper lash line darken it.
        float s = v_lines.x;
        float t = v_lines.y;
        float half_width = mix(3.2, 1.3, clamp(s, 0.0, 1.0));
        float along = smoothstep(-0.1, 0.08, s) * (1.0 - smoothstep(0.9, 1.06, s));
        float w = max(fwidth(t), 0.08);
        float core = 1.0 - smoothstep(half_width - 2.0 * w, half_width + w, abs(t));
        // denser low and towards the inner end, as brow hair grows
        float density = mix(1.0, 0.72, clamp(s, 0.0, 1.0))
                      * mix(1.0, 0.8, clamp(t / 3.0, 0.0, 1.0));
        float brow = clamp(core * along * density, 0.0, 1.0);
        albedo = mix(albedo, brow_rgb, 0.9 * brow);
        float ls = v_lines.z;
        float lt = v_lines.w;
        float lw = max(fwidth(lt), 0.06);
        float thick = mix(0.25, 0.9, smoothstep(0.0, 0.7, ls));
        float liner = smoothstep(-0.35 - lw, -0.35 + lw, lt)
                    * (1.0 - smoothstep(thick - lw, thick + lw, lt))
                    * smoothstep(0.0, 0.12, ls) * (1.0 - smoothstep(0.9, 1.0, ls));
        albedo = mix(albedo, brow_rgb * 0.6, 0.9 * liner);
    } else if (material > 2.5) {
        // Teeth: crowns along the arch (v_extra.z: teeth from the midline),
        // a dark gap between them, widest at the incisal edge; each crown's
        // face and its edge rounded by tilting the normal; the thin edge
        // greyer and the neck by the gum warmer (v_extra.w: mm above the
        // edge, + upper row, - lower row).
        float u = v_extra.z;
        float up = v_extra.w >= 0.0 ? 1.0 : -1.0;
        float h = abs(v_extra.w);
        float f = fract(u);
        float fu = max(fwidth(u), 1e-4);
        float from_gap = min(f, 1.0 - f);
        float gap_width = 0.035 + 0.09 * (1.0 - smoothstep(0.0, 2.5, h));
        float gap = 1.0 - smoothstep(gap_width - fu, gap_width + fu, from_gap);
        vec3 side = normalize(cross(vec3(0.0, 1.0, 0.0), n) + vec3(1e-6, 0.0, 0.0));
        side *= v_position.x >= 0.0 ? 1.0 : -1.0;
        float round_face = (f - 0.5) * 1.3;
        float round_edge = 1.0 - smoothstep(0.0, 1.5, h);
        n = normalize(n + side * round_face - vec3(0.0, up, 0.0) * 1.2 * round_edge);
        vec3 edge_rgb = vec3(0.70, 0.74, 0.78);
        vec3 neck_rgb = vec3(0.93, 0.86, 0.70);
        albedo = mix(albedo, edge_rgb, 0.6 * (1.0 - smoothstep(0.3, 2.0, h)));
        albedo = mix(albedo, neck_rgb, 0.5 * smoothstep(5.0, 9.0, h));
        albedo *= 1.0 - 0.75 * gap;
        shine = 0.35;
        power = 50.0;
    }
    float cavity = v_extra.y;
    vec3 light = ambient;
    vec3 glint = vec3(0.0);
    for (int i = 0; i < 3; ++i) {
        vec3 l = normalize(light_direction[i]);
        float diffuse = max(dot(n, l), 0.0);
        if (i == 2) {
            // rim: light from behind grazing the silhouette
            float edge = pow(1.0 - max(dot(n, view), 0.0), 3.0);
            light += light_colour[i] * edge * (0.4 + 0.6 * diffuse);
            continue;
        }
        light += light_colour[i] * diffuse;
        vec3 h = normalize(l + view);
        glint += light_colour[i] * shine * pow(max(dot(n, h), 0.0), power) * step(0.0, dot(n, l));
    }
    // The neck fades into the background above hm08's ragged cut.
    float neck = smoothstep(neck_fade.x, neck_fade.y, v_position.y);
    vec3 rgb = mix(background, (albedo * light + glint) * cavity, neck);
    fragment = vec4(pow(clamp(rgb, 0.0, 1.0), vec3(1.0 / 2.2)), 1.0);
}
"""


def _look_at(
    eye: npt.NDArray[np.float64], target: npt.NDArray[np.float64]
) -> npt.NDArray[np.float64]:
    """A camera pose (4, 4) at ``eye`` looking at ``target`` with +y up
    (OpenGL cameras look along their -z): camera-to-world."""
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


_FORWARD: dict[str, tuple[float, float, float]] = {
    "front": (0.0, 0.0, 1.0),
    "left": (1.0, 0.0, 0.0),
    "right": (-1.0, 0.0, 0.0),
}


def _polyline_coordinates(
    points: npt.NDArray[np.float64], line: npt.NDArray[np.float64]
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """For 2D ``points`` (k, 2) and a 2D polyline (j, 2): the fraction of the
    line's length at the nearest point on it (may run below 0 and above 1 past
    the ends) and the signed vertical offset from it (metres, + above)."""
    best_d = np.full(len(points), np.inf)
    best_s = np.zeros(len(points))
    best_t = np.zeros(len(points))
    lengths = np.linalg.norm(np.diff(line, axis=0), axis=1)
    total = float(lengths.sum())
    start = 0.0
    for k in range(len(line) - 1):
        a, b = line[k], line[k + 1]
        ab = b - a
        u = ((points - a) @ ab) / float(ab @ ab)
        lo = -np.inf if k == 0 else 0.0
        hi = np.inf if k == len(line) - 2 else 1.0
        u = np.clip(u, lo, hi)
        nearest = a + u[:, None] * ab
        offset = points - nearest
        d = np.linalg.norm(offset, axis=1)
        better = d < best_d
        normal = np.array([-ab[1], ab[0]]) / np.linalg.norm(ab)
        if normal[1] < 0:
            normal = -normal
        best_d = np.where(better, d, best_d)
        best_s = np.where(better, (start + u * lengths[k]) / total, best_s)
        best_t = np.where(better, offset @ normal, best_t)
        start += float(lengths[k])
    return best_s, best_t


def _smooth_curve(
    a: npt.NDArray[np.float64], b: npt.NDArray[np.float64], c: npt.NDArray[np.float64]
) -> npt.NDArray[np.float64]:
    """A polyline of 17 points on the parabola-like curve through ``a``,
    ``b`` (its middle) and ``c`` (a quadratic Bezier with its control point
    placed so that the curve passes through ``b``), so brows and lash lines
    have no kink at the middle feature point."""
    control = 2.0 * b - 0.5 * (a + c)
    t = np.linspace(0.0, 1.0, 17)[:, None]
    curve: npt.NDArray[np.float64] = (1 - t) ** 2 * a + 2 * t * (1 - t) * control + t**2 * c
    return curve


#: Widths (mm) along the arch of the teeth from the midline back (central
#: and lateral incisor, canine, two premolars, first molar), upper and lower,
#: typical adult crowns.
TOOTH_WIDTHS_MM = {
    "upper": (8.5, 6.5, 7.5, 7.0, 6.5, 10.0, 9.0),
    "lower": (5.0, 5.5, 7.0, 7.0, 7.0, 11.0, 10.0),
}


def tooth_coordinates(
    face: RenderableFace, v: npt.NDArray[np.float64], extra: npt.NDArray[np.float32]
) -> None:
    """Write the teeth's shape coordinates into ``extra`` (columns 2, 3) in place.

    The teeth meshes are slabs along the arch; the shader gives them teeth:
    ``extra[:, 2]`` is the position along the arch in teeth (tooth k spans
    k .. k + 1 from the midline, by :data:`TOOTH_WIDTHS_MM` measured along a
    parabola fitted to the arch in the x-z plane), ``extra[:, 3]`` the height
    above the incisal edge in mm, positive on the upper teeth (edge below),
    negative on the lower (edge above). From them the fragment shader darkens
    the gaps between teeth, rounds each crown's face and its incisal edge (by
    tilting the normal) and tints the thin edge greyer, per pixel."""
    for row, names in (
        ("upper", ("upper_teeth", "teeth_upper")),
        ("lower", ("lower_teeth", "teeth_lower")),
    ):
        found = [part_indices(face.parts[m]) for m in names if m in face.parts]
        if not found or not len(found[0]):
            continue
        idx = found[0]
        x, y, z = v[idx, 0], v[idx, 1], v[idx, 2]
        if np.ptp(x) < 1e-4:
            continue
        a, _, _ = np.polyfit(x, z, 2)
        grid = np.linspace(0.0, float(np.abs(x).max()), 256)
        slope = 2 * a * grid  # the arch taken symmetric about the midline
        step = np.sqrt(1.0 + slope**2)
        arc = np.concatenate([[0.0], np.cumsum((step[1:] + step[:-1]) / 2 * np.diff(grid))])
        along_mm = np.interp(np.abs(x), grid, arc) * 1000.0
        edges = np.concatenate([[0.0], np.cumsum(TOOTH_WIDTHS_MM[row])])
        tooth = np.interp(along_mm, edges, np.arange(len(edges)))
        # the incisal edge: the lowest (upper row) or highest (lower row)
        # point within 2 mm along the arch
        bins = np.floor(along_mm / 2.0).astype(np.int64)
        if row == "upper":
            edge = np.full(bins.max() + 1, np.inf)
            np.minimum.at(edge, bins, y)
            height = (y - edge[bins]) * 1000.0
        else:
            edge = np.full(bins.max() + 1, -np.inf)
            np.maximum.at(edge, bins, y)
            height = -(edge[bins] - y) * 1000.0
        extra[idx, 2] = tooth.astype(np.float32)
        extra[idx, 3] = np.where(height == 0.0, 1e-3 if row == "upper" else -1e-3, height)


def surface_attributes(
    face: RenderableFace,
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32], npt.NDArray[np.float32]]:
    """The static per-vertex attributes of the shaders, from the neutral face:

    ``extra`` (n, 4): material, cavity shade (1 = lit, darker deep in the mouth);
    ``surface`` (n, 4): the eyeballs' neutral directions from their centres;
    ``lines`` (n, 4): brow s, brow t, lash s, lash t: the position along the
    eyebrow's centre line (0 inner .. 1 outer) and the signed distance from it
    (mm, + up), and the same for the upper lid's margin. Values ride on the
    vertices, so brows and lashes follow the deformed skin; the shader draws
    them per pixel from the interpolated coordinates."""
    v = np.asarray(face.vertices, dtype=np.float64)
    n = len(v)
    extra = np.zeros((n, 4), dtype=np.float32)
    extra[:, 1] = 1.0
    surface = np.zeros((n, 4), dtype=np.float32)
    lines = np.tile(np.array([-1.0, FAR_MM, -1.0, FAR_MM], dtype=np.float32), (n, 1))
    balls = [part_indices(face.parts[m]) for m in PART_MEMBERS["eyes"] if m in face.parts]
    if not balls and "eyes" in face.parts:
        eyes = part_indices(face.parts["eyes"])
        middle = (v[eyes, 0].min() + v[eyes, 0].max()) / 2
        balls = [eyes[v[eyes, 0] >= middle], eyes[v[eyes, 0] < middle]]
    for ball in balls:
        if len(ball):
            extra[ball, 0] = MATERIAL_EYE
            offsets = v[ball] - v[ball].mean(axis=0)
            surface[ball, :3] = offsets / np.linalg.norm(offsets, axis=1, keepdims=True)
    # The mouth's inside is in the lips' shadow: darker the deeper it lies
    # behind the lips' inner contour (a fixed cavity term; the lips hide it
    # when the mouth is closed). The tongue and the mouth's skin are darker
    # than the teeth, which catch light at the front.
    inner = [face_part(face, p) for p in ("teeth", "tongue", "mouth_inside")]
    inner_all = [p for p in inner if p is not None and len(p)]
    if inner_all:
        every = np.concatenate(inner_all)
        z_lips = float(v[every, 2].max())
        feature_at = getattr(face, "feature_position", None)
        if feature_at is not None:
            # no inner lip midpoint: the front of the inside
            with contextlib.suppress(Exception):
                z_lips = float(feature_at("2.3")[2])
        for indices, brightest, material in (
            (inner[0], 0.8, MATERIAL_TEETH),
            (inner[1], 0.5, MATERIAL_MOUTH),
            (inner[2], 0.4, MATERIAL_MOUTH),
        ):
            if indices is None or not len(indices):
                continue
            depth = np.clip((z_lips - v[indices, 2]) / 0.03, 0.0, 1.0)
            extra[indices, 0] = material
            extra[indices, 1] = (brightest * (1.0 - 0.85 * depth**0.6)).astype(np.float32)
        tooth_coordinates(face, v, extra)
    feature = getattr(face, "feature_position", None)
    skin = face_part(face, "skin")
    if feature is None or skin is None:
        return extra, surface, lines
    try:
        fp = {k: np.asarray(feature(k), dtype=np.float64) for k in
              ("4.1", "4.2", "4.3", "4.4", "4.5", "4.6", "3.1", "3.2", "3.7", "3.8",
               "3.11", "3.12")}  # fmt: skip
    except Exception:  # a face without these feature points: no brows, no lashes
        return extra, surface, lines
    lift = np.array([0.0, 0.002])
    for inner_, middle_, outer_, lid_top, lid_corners, left in (
        ("4.1", "4.3", "4.5", "3.1", ("3.11", "3.7"), True),
        ("4.2", "4.4", "4.6", "3.2", ("3.8", "3.12"), False),
    ):
        side = skin[(v[skin, 0] >= 0.0) == left]
        # Only the front of the head carries brows and lashes; elsewhere the
        # position along the line is 9 (past the end: nothing drawn), the offset is real,
        # so no band appears where the two regions meet.
        behind = v[side, 2] < fp[outer_][2] - 0.03
        # The brow's centre line runs just below its upper edge (4.3 is the
        # arch's uppermost point).
        brow = _smooth_curve(
            fp[inner_][:2] - lift * 0.2, fp[middle_][:2] - lift * 1.2, fp[outer_][:2] - lift * 0.8
        )
        s, t = _polyline_coordinates(v[side, :2], brow)
        lines[side, 0] = np.where(behind, 9.0, s)
        lines[side, 1] = np.clip(t * 1000.0, -20.0, 20.0)
        # The upper lash line: along the upper lid margin between the corners,
        # on the front of the lid (not inside the eye socket's pocket).
        lid = _smooth_curve(fp[lid_corners[0]][:2], fp[lid_top][:2], fp[lid_corners[1]][:2])
        s, t = _polyline_coordinates(v[side, :2], lid)
        socket = v[side, 2] < fp[lid_top][2] - 0.006
        lines[side, 2] = np.where(behind | socket, 9.0, s)
        lines[side, 3] = np.clip(t * 1000.0, -20.0, 20.0)
    return extra, surface, lines


class FaceRenderer:
    """Renders one face, neutral or deformed, at a fixed size and camera.

    Create one per face and size and call :meth:`render` as often as needed:
    the GL context, shaders, buffers and framebuffers are made once and each
    frame only rewrites the vertex buffer. Not thread-safe (one GL context);
    a lock serialises calls. Call :meth:`close` (or use it as a context
    manager) to free the context.

    ``samples``: multisampling per pixel (1 = none), resolved in OpenGL.
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
        samples: int = SAMPLES,
    ) -> None:
        if not (1 <= width <= 8192 and 1 <= height <= 8192):
            raise ValueError(f"image size must be 1..8192 pixels, not {width}x{height}")
        self.face = face
        self.width = width
        self.height = height
        self.framing = framing or Framing.of_points(np.asarray(face.vertices))
        n = len(face.vertices)
        # The skin and the eyes are closed surfaces seen from outside: their
        # back faces are culled (half the rasterising). The mouth's inside,
        # teeth and tongue are drawn from both sides; they go last; but a
        # tongue that is a closed surface facing out (the default face's)
        # is culled like the skin.
        triangles = np.asarray(face.faces, dtype=np.uint32)
        two_sided = np.zeros(n, dtype=bool)
        for name in ("teeth", "tongue", "mouth_inside"):
            indices = face_part(face, name)
            if indices is not None:
                if name == "tongue" and closed_outward(face.vertices, triangles, indices):
                    continue
                two_sided[indices] = True
        both = two_sided[triangles].any(axis=1)
        self._faces = np.ascontiguousarray(np.concatenate([triangles[~both], triangles[both]]))
        self._culled_count = int((~both).sum()) * 3
        if colours is None:
            attributes = getattr(face, "attributes", None) or {}
            colours = attributes.get("colours")
            if colours is not None and np.asarray(colours).dtype == np.uint8:
                colours = np.asarray(colours, dtype=np.float32) / 255.0
        self._colours = np.ascontiguousarray(
            vertex_colours(face) if colours is None else colours, dtype=np.float32
        )
        if self._colours.shape != (n, 3):
            raise ValueError(f"colours must have shape {(n, 3)}, got {self._colours.shape}")
        extra, surface, lines = surface_attributes(face)
        # Normals: the sum of the (area-weighted) normals of a vertex's
        # triangles, as one sparse product per frame.
        import scipy.sparse as sp

        corners = self._faces.reshape(-1).astype(np.int64)
        self._corner_sum = sp.csr_matrix(
            (
                np.ones(len(corners), dtype=np.float32),
                (corners, np.repeat(np.arange(len(self._faces)), 3)),
            ),
            shape=(n, len(self._faces)),
        )
        self._dynamic = np.zeros((n, 6), dtype=np.float32)  # position, normal
        self._image = np.empty((height, width, 3), dtype=np.uint8)
        self._lock = threading.Lock()
        self._closed = False
        self._view: View | None = None
        platform = choose_platform()
        try:
            from OpenGL import GL

            from realizer.face.gl import make_context
        except Exception as error:  # ImportError, or OpenGL failing to find its library
            raise RenderUnavailableError(f"cannot import PyOpenGL: {error}") from error
        self._gl = GL
        try:
            self._context = make_context(platform)
            self._context.make_current()
            self._setup(samples, np.concatenate([extra, surface, lines], axis=1))
        except RenderUnavailableError:
            raise
        except Exception as error:  # each GL back end raises its own types
            raise RenderUnavailableError(
                f"cannot create an offscreen OpenGL 3.3 context "
                f"(PYOPENGL_PLATFORM={platform}): {error}"
            ) from error

    # -- set-up --------------------------------------------------------------------

    def _compile(self) -> int:
        GL = self._gl
        program = GL.glCreateProgram()
        for kind, source in (
            (GL.GL_VERTEX_SHADER, _VERTEX_SHADER),
            (GL.GL_FRAGMENT_SHADER, _FRAGMENT_SHADER),
        ):
            shader = GL.glCreateShader(kind)
            GL.glShaderSource(shader, source)
            GL.glCompileShader(shader)
            if not GL.glGetShaderiv(shader, GL.GL_COMPILE_STATUS):
                log = GL.glGetShaderInfoLog(shader)
                raise RenderUnavailableError(f"shader does not compile: {log!r}")
            GL.glAttachShader(program, shader)
            GL.glDeleteShader(shader)
        GL.glLinkProgram(program)
        if not GL.glGetProgramiv(program, GL.GL_LINK_STATUS):
            raise RenderUnavailableError(
                f"shaders do not link: {GL.glGetProgramInfoLog(program)!r}"
            )
        return int(program)

    def _setup(self, samples: int, attributes: npt.NDArray[np.float32]) -> None:
        GL = self._gl
        self._program = self._compile()
        self._uniforms = {
            name: GL.glGetUniformLocation(self._program, name)
            for name in (
                "view_projection", "eye_position", "light_direction", "light_colour",
                "ambient", "iris_cos", "pupil_cos", "iris_rgb", "sclera_rgb", "pupil_rgb",
                "brow_rgb", "neck_fade", "background",
            )
        }  # fmt: skip
        self._vao = GL.glGenVertexArrays(1)
        GL.glBindVertexArray(self._vao)
        self._dynamic_buffer, static_buffer, index_buffer = GL.glGenBuffers(3)
        self._buffers = [self._dynamic_buffer, static_buffer, index_buffer]
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, self._dynamic_buffer)
        GL.glBufferData(GL.GL_ARRAY_BUFFER, self._dynamic.nbytes, None, GL.GL_DYNAMIC_DRAW)
        for location, offset in ((0, 0), (1, 12)):
            GL.glEnableVertexAttribArray(location)
            GL.glVertexAttribPointer(location, 3, GL.GL_FLOAT, False, 24, ctypes.c_void_p(offset))
        static = np.ascontiguousarray(np.concatenate([self._colours, attributes], axis=1))
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, static_buffer)
        GL.glBufferData(GL.GL_ARRAY_BUFFER, static.nbytes, static, GL.GL_STATIC_DRAW)
        stride = static.shape[1] * 4
        for location, size, offset in ((2, 3, 0), (3, 4, 12), (4, 4, 28), (5, 4, 44)):
            GL.glEnableVertexAttribArray(location)
            GL.glVertexAttribPointer(
                location, size, GL.GL_FLOAT, False, stride, ctypes.c_void_p(offset)
            )
        GL.glBindBuffer(GL.GL_ELEMENT_ARRAY_BUFFER, index_buffer)
        GL.glBufferData(
            GL.GL_ELEMENT_ARRAY_BUFFER, self._faces.nbytes, self._faces, GL.GL_STATIC_DRAW
        )
        GL.glBindVertexArray(0)
        # Framebuffers: a multisampled one to draw in, a plain one to read.
        max_samples = int(GL.glGetIntegerv(GL.GL_MAX_SAMPLES))
        self.samples = max(1, min(samples, max_samples))
        self._framebuffers = list(GL.glGenFramebuffers(2))
        self._renderbuffers = list(GL.glGenRenderbuffers(3))
        draw, read = self._framebuffers
        colour, depth, resolved = self._renderbuffers
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, draw)
        GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, colour)
        self._storage(GL.GL_RGBA8)
        GL.glFramebufferRenderbuffer(
            GL.GL_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0, GL.GL_RENDERBUFFER, colour
        )
        GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, depth)
        self._storage(GL.GL_DEPTH_COMPONENT24)
        GL.glFramebufferRenderbuffer(
            GL.GL_FRAMEBUFFER, GL.GL_DEPTH_ATTACHMENT, GL.GL_RENDERBUFFER, depth
        )
        if GL.glCheckFramebufferStatus(GL.GL_FRAMEBUFFER) != GL.GL_FRAMEBUFFER_COMPLETE:
            raise RenderUnavailableError("the multisampled framebuffer is incomplete")
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, read)
        GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, resolved)
        GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, GL.GL_RGBA8, self.width, self.height)
        GL.glFramebufferRenderbuffer(
            GL.GL_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0, GL.GL_RENDERBUFFER, resolved
        )
        if GL.glCheckFramebufferStatus(GL.GL_FRAMEBUFFER) != GL.GL_FRAMEBUFFER_COMPLETE:
            raise RenderUnavailableError("the resolve framebuffer is incomplete")
        GL.glUseProgram(self._program)
        u = self._uniforms
        GL.glUniform1f(u["iris_cos"], float(np.cos(IRIS_ANGLE)))
        GL.glUniform1f(u["pupil_cos"], float(np.cos(PUPIL_ANGLE)))
        GL.glUniform3f(u["iris_rgb"], *IRIS_RGB)
        GL.glUniform3f(u["sclera_rgb"], *SCLERA_RGB)
        GL.glUniform3f(u["pupil_rgb"], *PUPIL_RGB)
        GL.glUniform3f(u["brow_rgb"], *BROW_RGB)
        GL.glUniform3f(u["background"], *BACKGROUND_RGB)
        skin = face_part(self.face, "skin")
        lowest = float(
            np.asarray(self.face.vertices)[skin if skin is not None else slice(None), 1].min()
        )
        GL.glUniform2f(u["neck_fade"], lowest + NECK_FADE_M[0], lowest + NECK_FADE_M[1])
        GL.glUniform3f(u["ambient"], 0.16, 0.16, 0.18)
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glCullFace(GL.GL_BACK)
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        GL.glViewport(0, 0, self.width, self.height)

    def _storage(self, kind: int) -> None:
        """Storage for the bound renderbuffer: multisampled unless one sample
        (Mesa rounds a multisampled count of 1 up to 4)."""
        GL = self._gl
        if self.samples > 1:
            GL.glRenderbufferStorageMultisample(
                GL.GL_RENDERBUFFER, self.samples, kind, self.width, self.height
            )
        else:
            GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, kind, self.width, self.height)

    def _set_view(self, view: View) -> None:
        if view == self._view:
            return
        if view not in _FORWARD:
            raise ValueError(f"view must be one of {sorted(_FORWARD)}, not {view!r}")
        GL = self._gl
        target = np.array(self.framing.centre, dtype=np.float64)
        distance = self.framing.height / 2 / np.tan(FIELD_OF_VIEW / 2)
        direction = np.array(_FORWARD[view])
        eye = target + distance * direction
        world_to_camera = np.linalg.inv(_look_at(eye, target))
        near, far = distance / 10, distance * 10
        f = 1.0 / np.tan(FIELD_OF_VIEW / 2)
        projection = np.array(
            [
                [f * self.height / self.width, 0, 0, 0],
                [0, f, 0, 0],
                [0, 0, (far + near) / (near - far), 2 * far * near / (near - far)],
                [0, 0, -1, 0],
            ]
        )
        matrix = (projection @ world_to_camera).astype(np.float32)
        u = self._uniforms
        GL.glUniformMatrix4fv(u["view_projection"], 1, True, matrix)
        GL.glUniform3f(u["eye_position"], *(float(c) for c in eye))
        # Key light from above, front and the viewer's left; a cooler fill from
        # the right and below; a rim light from behind and above.
        up = np.array([0.0, 1.0, 0.0])
        side = np.cross(up, direction)
        key = direction + 0.8 * up - 0.7 * side
        fill = direction - 0.15 * up + 0.9 * side
        rim = -0.6 * direction + 0.8 * up + 0.5 * side
        directions = np.stack([key, fill, rim]).astype(np.float32)
        colours = np.array([[1.05, 1.0, 0.95], [0.30, 0.33, 0.38], [0.55, 0.55, 0.6]], np.float32)
        GL.glUniform3fv(u["light_direction"], 3, directions)
        GL.glUniform3fv(u["light_colour"], 3, colours)
        self._view = view

    # -- use -----------------------------------------------------------------------

    def __enter__(self) -> FaceRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Free the GL objects and the context (idempotent)."""
        with self._lock:
            if self._closed or not hasattr(self, "_context"):
                self._closed = True
                return
            self._closed = True
            GL = self._gl
            try:
                self._context.make_current()
                GL.glDeleteFramebuffers(len(self._framebuffers), self._framebuffers)
                GL.glDeleteRenderbuffers(len(self._renderbuffers), self._renderbuffers)
                GL.glDeleteBuffers(len(self._buffers), self._buffers)
                GL.glDeleteVertexArrays(1, [self._vao])
                GL.glDeleteProgram(self._program)
            except Exception:  # a half-made renderer: free the context anyway
                pass
            self._context.release()

    def project(
        self, points: npt.NDArray[np.floating[Any]], *, view: View = "front"
    ) -> npt.NDArray[np.float64]:
        """Pixel coordinates (k, 2) as (column, row) of 3D points (k, 3),
        metres, in the images :meth:`render` makes with ``view``."""
        pts = np.atleast_2d(np.asarray(points, dtype=np.float64))
        target = np.array(self.framing.centre)
        distance = self.framing.height / 2 / np.tan(FIELD_OF_VIEW / 2)
        pose = _look_at(target + distance * np.array(_FORWARD[view]), target)
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

        Returns an RGB image (height, width, 3) uint8, a new array each call.
        """
        positions = np.asarray(self.face.vertices if vertices is None else vertices)
        if positions.shape != self._colours.shape:
            raise ValueError(
                f"vertices must have shape {self._colours.shape}, got {positions.shape}"
            )
        with self._lock:
            if self._closed:
                raise RenderUnavailableError("this FaceRenderer has been closed")
            dynamic = self._dynamic
            dynamic[:, :3] = positions
            p = dynamic[:, :3]
            tri = self._faces
            a = p[tri[:, 0]]
            face_normals = np.cross(p[tri[:, 1]] - a, p[tri[:, 2]] - a)
            normals = self._corner_sum @ face_normals
            length = np.sqrt(np.einsum("ij,ij->i", normals, normals))[:, None]
            np.divide(normals, np.maximum(length, 1e-20), out=dynamic[:, 3:])
            GL = self._gl
            self._context.make_current()
            GL.glUseProgram(self._program)
            self._set_view(view)
            GL.glBindBuffer(GL.GL_ARRAY_BUFFER, self._dynamic_buffer)
            GL.glBufferSubData(GL.GL_ARRAY_BUFFER, 0, dynamic.nbytes, dynamic)
            draw, read = self._framebuffers
            GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, draw)
            GL.glViewport(0, 0, self.width, self.height)
            GL.glClearColor(*BACKGROUND_RGB, 1.0)
            GL.glClear(GL.GL_COLOR_BUFFER_BIT | GL.GL_DEPTH_BUFFER_BIT)
            GL.glBindVertexArray(self._vao)
            GL.glEnable(GL.GL_CULL_FACE)
            GL.glDrawElements(GL.GL_TRIANGLES, self._culled_count, GL.GL_UNSIGNED_INT, None)
            GL.glDisable(GL.GL_CULL_FACE)
            rest = self._faces.size - self._culled_count
            if rest:
                GL.glDrawElements(
                    GL.GL_TRIANGLES,
                    rest,
                    GL.GL_UNSIGNED_INT,
                    ctypes.c_void_p(self._culled_count * 4),
                )
            GL.glBindVertexArray(0)
            GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, draw)
            GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, read)
            GL.glBlitFramebuffer(
                0, 0, self.width, self.height, 0, 0, self.width, self.height,
                GL.GL_COLOR_BUFFER_BIT, GL.GL_NEAREST,
            )  # fmt: skip
            GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, read)
            GL.glReadPixels(
                0, 0, self.width, self.height, GL.GL_RGB, GL.GL_UNSIGNED_BYTE, self._image
            )
            return self._image[::-1].copy()


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
