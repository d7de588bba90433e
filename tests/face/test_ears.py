"""The default face's ears (FAPs 65..68) move whole without creasing the
scalp round them: the thesis's evaluation by eye (section 4.4) saw a crease
or a dent behind the ear where the old sphere's vertex mask ended."""

from __future__ import annotations

import numpy as np
import pytest

from realizer.face.default import load_default_face
from realizer.face.deform import deform


@pytest.mark.parametrize("fap", [65, 66, 67, 68])
@pytest.mark.parametrize("value", [128.0, -128.0])
def test_an_ear_fap_turns_no_skin_triangle_sharply(fap: int, value: float) -> None:
    face = load_default_face()
    rest = np.asarray(face.vertices, dtype=np.float64)
    member = np.zeros(face.vertex_count, dtype=bool)
    member[face.part("skin")] = True
    triangles = np.asarray(face.faces)[member[np.asarray(face.faces)].all(axis=1)]

    def normals(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t = p[triangles]
        n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        area = np.linalg.norm(n, axis=1)
        return n / np.maximum(area, 1e-30)[:, None], area

    values = np.zeros(68)
    values[fap - 1] = value
    before, area = normals(rest)
    after, _ = normals(np.asarray(deform(face, values), dtype=np.float64))
    turn = np.degrees(np.arccos(np.clip(np.sum(before * after, axis=1), -1.0, 1.0)))
    # the masked sphere turned triangles behind the ear by up to 62 degrees
    assert turn[area > 1e-9].max() < 35.0
    # and the ear itself moved its feature point the FAP's value
    point = {65: "10.1", 66: "10.2", 67: "10.3", 68: "10.4"}[fap]
    moved = np.asarray(deform(face, values), dtype=np.float64)[face.feature_vertex(point)]
    assert np.linalg.norm(moved - rest[face.feature_vertex(point)]) > 0.004
