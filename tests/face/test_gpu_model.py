"""The deformation model as data (realizer.face.gpu_model): its numpy
evaluation equals the server's deform() on random FAP vectors."""

from __future__ import annotations

import numpy as np
import pytest

from realizer.face.default import load_default_face
from realizer.face.deform import deform
from realizer.face.gpu_model import gpu_model_for, model_message_fields

TOLERANCE_M = 1e-4  # the 0.1 mm


@pytest.fixture(scope="module")
def face():  # type: ignore[no-untyped-def]
    return load_default_face()


def random_vectors(count: int, seed: int = 7) -> list[np.ndarray]:
    """FAP vectors with every FAP set, about the size expressions use (and beyond)."""
    rng = np.random.default_rng(seed)
    out = [rng.uniform(-400, 400, 68) for _ in range(count)]
    sparse = rng.uniform(-800, 800, 68) * (rng.random(68) < 0.2)
    return [*out, sparse, np.zeros(68)]


def test_the_arrays_evaluate_to_the_vertices_deform_gives(face) -> None:  # type: ignore[no-untyped-def]
    model = gpu_model_for(face)
    for vector in random_vectors(12):
        expected = deform(face, vector)
        got = model.evaluate(vector)
        assert np.abs(got - expected).max() < 1e-6
    # and not trivially: the vectors do move the face by far more than the tolerance
    assert np.abs(deform(face, random_vectors(1)[0]) - face.vertices).max() > 100 * TOLERANCE_M


def test_every_rigid_part_and_table_reaches_the_model(face) -> None:  # type: ignore[no-untyped-def]
    model = gpu_model_for(face)
    kinds = set((model.entries[:, 0] // 3).astype(int).tolist())
    assert kinds == {0, 1}  # influence deformers and FaceDefMesh/dilation tables
    # the two eyes and the head (the jaw and the tongue roll are tables)
    assert model.group_count >= 3
    jaw = np.zeros(68)
    jaw[2] = 500.0  # open_jaw
    moved = np.abs(model.evaluate(jaw) - face.vertices).max(axis=1) > 1e-4
    assert moved.sum() > 100


def test_the_model_message_is_at_most_a_few_megabytes(face) -> None:  # type: ignore[no-untyped-def]
    fields = model_message_fields(gpu_model_for(face))
    size = sum(len(v) for v in fields.values() if isinstance(v, bytes))
    assert 10_000 < size < 4_000_000
    entries = np.frombuffer(fields["entries"], dtype="<f4").reshape(-1, 4)
    assert entries.shape[0] == fields["entryCount"]
