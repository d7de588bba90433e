"""The msgpack layouts of the viewer endpoint (protocols/viewer.md)."""

from __future__ import annotations

import numpy as np
import pytest

from realizer.service import codec
from realizer.service.errors import BadMessage
from realizer.service.messages import ViewOptions


def test_fap_payload_lists_only_the_set_faps_with_their_numbers() -> None:
    values = np.zeros(68)
    mask = np.zeros(68, dtype=bool)
    values[[11, 12, 50]] = [120.0, -35.5, 7.0]
    mask[[11, 12]] = True
    payload = codec.fap_payload(values, mask)
    assert codec.decode_faps(payload) == {12: 120.0, 13: -35.5}


def test_int16_deltas_decode_to_within_half_a_step_and_skip_unmoved_vertices() -> None:
    rng = np.random.default_rng(1)
    neutral = rng.uniform(-0.1, 0.1, (500, 3)).astype(np.float32)
    moved = neutral.astype(np.float64).copy()
    moved[10:20] += rng.uniform(-0.01, 0.01, (10, 3))
    mesh = codec.mesh_message("a", neutral, np.zeros((1, 3), np.int32), None, 60)
    options = ViewOptions(fap=False, vertices="int16")
    delta = codec.delta_payload(moved, neutral.astype(np.float64))
    frame = codec.frame_message("a", 3, 0.05, options, delta=delta)
    decoded = codec.decode_vertices(codec.unpack(codec.pack(frame)), codec.unpack(codec.pack(mesh)))
    assert len(delta["ids"]) == 10 * 4  # ten uint32 indices
    assert np.max(np.abs(decoded - moved)) <= codec.DELTA_STEP / 2 + 1e-7


def test_a_neutral_frame_has_no_deltas_and_decodes_to_the_neutral_pose() -> None:
    neutral = np.eye(3, dtype=np.float32)
    delta = codec.delta_payload(neutral, neutral.astype(np.float64))
    mesh = codec.mesh_message("a", neutral, np.array([[0, 1, 2]]), None, 60)
    frame = codec.frame_message("a", 0, 0.0, ViewOptions(vertices="int16"), delta=delta)
    assert delta["ids"] == b""
    assert np.array_equal(codec.decode_vertices(frame, mesh), neutral)


def test_mesh_message_carries_topology_neutral_pose_and_counts() -> None:
    neutral = np.arange(12, dtype=np.float32).reshape(4, 3)
    faces = np.array([[0, 1, 2], [1, 2, 3]])
    mesh = codec.unpack(codec.pack(codec.mesh_message("bob", neutral, faces, None, 30)))
    assert (mesh["type"], mesh["character"], mesh["vertexCount"], mesh["faceCount"]) == (
        "mesh",
        "bob",
        4,
        2,
    )
    assert np.array_equal(np.frombuffer(mesh["faces"], "<u4").reshape(-1, 3), faces)
    assert np.array_equal(np.frombuffer(mesh["neutral"], "<f4").reshape(-1, 3), neutral)


def test_frame_message_contains_only_what_the_viewer_asked_for() -> None:
    fap = codec.fap_payload(np.ones(68), np.ones(68, dtype=bool))
    only_faps = codec.frame_message("a", 1, 0.1, ViewOptions(fap=True), fap=fap, vertices=b"x")
    only_vertices = codec.frame_message(
        "a", 1, 0.1, ViewOptions(fap=False, vertices="float32"), fap=fap, vertices=b"x"
    )
    assert "fap" in only_faps and "vertices" not in only_faps
    assert "fap" not in only_vertices and only_vertices["vertices"] == b"x"


def test_unpack_refuses_bytes_that_are_not_a_message() -> None:
    with pytest.raises(BadMessage):
        codec.unpack(b"\xc1")
    with pytest.raises(BadMessage):
        codec.unpack(codec.pack({"no": "type"}))
