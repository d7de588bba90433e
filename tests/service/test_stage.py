"""The sans-I/O core: routing, named limits, block states, frames.

Driven with a test double of the session (doubles.py), so the stage's own
rules are checked without sockets and without the scheduler's timings.
"""

from __future__ import annotations

import numpy as np
import pytest

from realizer.service import codec
from realizer.service.limits import ServiceLimits
from realizer.service.messages import ViewOptions
from realizer.service.stage import BlockEvent, FrameEncoder, Stage, WireFeedback
from tests.service.doubles import FakeFace, FakeSession, fake_deform, smile_bml


def make_stage(**limits: int) -> tuple[Stage, dict[str, FakeSession]]:
    made: dict[str, FakeSession] = {}

    def factory(character_id: str) -> FakeSession:
        made[character_id] = FakeSession(character_id)
        return made[character_id]

    return Stage(factory, ServiceLimits(**limits)), made


def states(messages: tuple[object, ...]) -> list[str]:
    return [m.state for m in messages if isinstance(m, BlockEvent)]


def test_a_block_goes_to_the_character_it_names_made_on_first_use() -> None:
    stage, made = make_stage()
    result = stage.submit_bml(smile_bml("b1", character="Alice"), 0.5)
    assert result.accepted and result.character == "Alice"
    assert list(made) == ["Alice"] and made["Alice"].calls == [("receive_bml", 0.5)]
    assert states(result.messages) == ["accepted"]


def test_the_request_character_overrides_the_block_and_the_default_comes_last() -> None:
    stage, made = make_stage()
    stage.submit_bml(smile_bml("b1", character="Alice"), 0.0, character="Bob")
    stage.submit_bml(smile_bml("b2"), 0.0, fallback="Carol")
    stage.submit_bml(smile_bml("b3"), 0.0)
    assert sorted(made) == ["Bob", "Carol", "default"]


def test_malformed_bml_is_answered_with_a_warning_and_reaches_no_session() -> None:
    stage, made = make_stage()
    result = stage.submit_bml('<bml id="broken"><faceLexeme', 0.0)
    warning = result.messages[0]
    assert not result.accepted and made == {}
    assert isinstance(warning, WireFeedback) and warning.kind == "warning"
    assert 'id="broken"' in warning.xml and 'type="PARSING_FAILURE"' in warning.xml
    assert states(result.messages) == ["rejected"]


def test_a_block_over_the_behaviour_limit_is_refused_with_a_warning() -> None:
    stage, made = make_stage(behaviours_per_block=3)
    assert stage.submit_bml(smile_bml("ok", behaviours=3), 0.0).accepted
    refused = stage.submit_bml(smile_bml("big", behaviours=4), 0.0)
    assert not refused.accepted and "more than 3 behaviours" in refused.messages[0].xml  # type: ignore[union-attr]
    assert [c for c, _ in made["default"].calls] == ["receive_bml"]


def test_queued_blocks_are_limited_per_character_until_blocks_end() -> None:
    stage, _ = make_stage(queued_blocks=2)
    assert stage.submit_bml(smile_bml("a"), 0.0).accepted
    assert stage.submit_bml(smile_bml("b"), 0.0).accepted
    third = stage.submit_bml(smile_bml("c"), 0.0)
    assert not third.accepted and "2 queued blocks" in third.messages[0].xml  # type: ignore[union-attr]
    assert stage.submit_bml(smile_bml("x", character="Other"), 0.0).accepted
    ended = [m for t in stage.tick(1.5) for m in t.messages if isinstance(m, BlockEvent)]
    assert sorted(e.block_id for e in ended) == ["a", "b", "x"]
    assert {e.state for e in ended} == {"done"}
    assert stage.submit_bml(smile_bml("c"), 1.6).accepted


def test_the_character_limit_refuses_new_characters_only() -> None:
    stage, made = make_stage(characters=1)
    assert stage.submit_bml(smile_bml("a", character="One"), 0.0).accepted
    refused = stage.submit_bml(smile_bml("b", character="Two"), 0.0)
    assert not refused.accepted and "limit of 1 characters" in refused.messages[0].xml  # type: ignore[union-attr]
    assert stage.submit_bml(smile_bml("c", character="One"), 0.0).accepted
    assert list(made) == ["One"]


def test_an_invalid_character_id_is_refused() -> None:
    stage, made = make_stage()
    refused = stage.submit_bml(smile_bml("a"), 0.0, character="no spaces/slashes")
    assert not refused.accepted and made == {}


def test_an_interrupted_block_ends_as_interrupted() -> None:
    stage, _ = make_stage()
    stage.submit_bml(smile_bml("a"), 0.0)
    stage.tick(0.1)
    stage.interrupt("default", "a", 0.2)
    events = [m for t in stage.tick(0.3) for m in t.messages if isinstance(m, BlockEvent)]
    assert [(e.block_id, e.state) for e in events] == [("a", "interrupted")]


def test_interrupting_an_unknown_character_is_a_warning() -> None:
    stage, _ = make_stage()
    (warning,) = stage.interrupt("nobody", "a", 0.0)
    assert isinstance(warning, WireFeedback) and 'type="NO_SUCH_TARGET"' in warning.xml


def test_interrupt_all_stops_every_open_block() -> None:
    stage, _ = make_stage()
    stage.submit_bml(smile_bml("a", character="A"), 0.0)
    stage.submit_bml(smile_bml("b", character="B"), 0.0)
    stage.interrupt_all(0.5)
    events = [m for t in stage.tick(0.5) for m in t.messages if isinstance(m, BlockEvent)]
    assert sorted((e.character, e.state) for e in events) == [
        ("A", "interrupted"),
        ("B", "interrupted"),
    ]


def test_time_given_to_sessions_never_goes_backwards() -> None:
    stage, made = make_stage()
    stage.submit_bml(smile_bml("a"), 1.004)  # arrives after frame 60's due time
    ticks = stage.tick(1.0)  # ...but before the clock computed frame 60
    assert ticks[0].time == 1.004
    times = [now for _, now in made["default"].calls]
    assert times == sorted(times)


def test_frames_are_encoded_once_per_kind_of_viewer_and_deformed_only_on_change() -> None:
    face = FakeFace()
    encoder = FrameEncoder("a", face, fake_deform, 60.0)
    stage, _ = make_stage()
    stage.submit_bml(smile_bml("a"), 0.0)
    wanted = [ViewOptions(), ViewOptions(fap=False, vertices="int16"), ViewOptions()]
    (tick,) = stage.tick(0.1)
    first = encoder.encode(6, tick.time, tick.frame, wanted)
    (tick,) = stage.tick(0.2)
    encoder.encode(12, tick.time, tick.frame, wanted)
    assert len(first) == 2 and encoder.deformations == 1
    mesh = codec.unpack(encoder.mesh_bytes)
    frame = codec.unpack(first[ViewOptions(fap=False, vertices="int16")])
    vertices = codec.decode_vertices(frame, mesh)
    assert frame["n"] == 6 and "fap" not in frame
    assert np.isclose(vertices[0, 1], 100 * 1e-5, atol=codec.DELTA_STEP)
    assert codec.decode_faps(codec.unpack(first[ViewOptions()])["fap"]) == {12: 100.0}


def test_a_failing_session_does_not_stop_the_other_characters(
    caplog: pytest.LogCaptureFixture,
) -> None:
    class Broken(FakeSession):
        def tick(self, now: float) -> None:
            raise RuntimeError("a bug")

    stage = Stage(lambda c: Broken(c) if c == "bad" else FakeSession(c))
    stage.submit_bml(smile_bml("a", character="bad"), 0.0)
    stage.submit_bml(smile_bml("b", character="good"), 0.0)
    ticks = stage.tick(0.1)
    assert [t.character for t in ticks] == ["bad", "good"]
    assert "character 'bad' failed" in caplog.text
    # every accepted block ends: the broken session's block fails, with a warning
    bad = ticks[0]
    events = [(m.block_id, m.state) for m in bad.messages if isinstance(m, BlockEvent)]
    assert events == [("a", "failed")]
    assert not bad.frame.mask.any()  # a fresh session: the neutral face
    assert stage.submit_bml(smile_bml("c", character="bad"), 0.2).accepted
