"""Small faces for exact checks: a row of vertices along +x from a feature point."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from realizer.face.model import DeformerSetting, Face, FaceParameters

#: MNS = MW = 1e-5 m per unit on the line face (MNS0 = MW0 = 0.01024 m).
UNIT_M = 1e-5
SPACING_M = 0.001

# the FAPU feature points, away from the line (which runs along y = 0, z = 0)
FAPU_POINTS = {
    "3.1": (0.03, 0.05, 0.0),
    "3.2": (-0.03, 0.05, 0.0),
    "3.3": (0.03, 0.04, 0.0),
    "3.4": (-0.03, 0.04, 0.0),
    "3.5": (0.03, 0.045, 0.0),
    "3.6": (-0.03, 0.045, 0.0),
    "9.15": (0.0, 0.01024, 0.0),
    "2.2": (0.0, 0.0, 0.0),
    "8.3": (0.00512, -0.005, 0.0),
    "8.4": (-0.00512, -0.005, 0.0),
}


def line_face(
    deformers: tuple[DeformerSetting, ...],
    *,
    count: int = 60,
    points: Mapping[str, tuple[float, float, float]] | None = None,
    masks: Mapping[int, tuple[int, ...]] | None = None,
    parts: Mapping[str, np.ndarray] | None = None,
) -> Face:
    """Vertices i * 1 mm along +x (vertex 0 at feature point 2.2, the origin)."""
    vertices = np.zeros((count, 3), dtype=np.float32)
    vertices[:, 0] = np.arange(count) * SPACING_M
    all_points = dict(FAPU_POINTS)
    all_points.update(points or {})
    params = FaceParameters(all_points, (), deformers, dict(masks or {}))
    return Face(
        vertices,
        np.zeros((0, 3), dtype=np.int32),
        dict(parts or {"skin": np.arange(count)}),
        params,
        name="line",
    )


def fap_vector(values: Mapping[int, float]) -> np.ndarray:
    vector = np.zeros(68)
    for number, value in values.items():
        vector[number - 1] = value
    return vector
