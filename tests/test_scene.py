"""A scene to gaze at: named targets, characters' eyes, targets moved while blocks run."""

from __future__ import annotations

import asyncio
import json

import pytest
from websockets.asyncio.client import connect

from realizer.bml_parser import BML_NS
from realizer.scene import Scene, SceneError
from realizer.service.stage import Stage, WireFeedback
from realizer.session import Session
from tests.service.harness import running_service
from tests.service.test_end_to_end import read_json, real_assets, real_sessions, until_block_final

#: eyeball yaw FAP 23 (yaw_l_eyeball, left positive) and pitch FAP 25 (down positive)
YAW, PITCH = 22, 24


def gaze(block: str, target: str, character: str = "", end: float = 3.0) -> str:
    who = f' characterId="{character}"' if character else ""
    return (
        f'<bml xmlns="{BML_NS}" id="{block}"{who}><gaze id="g" target="{target}" '
        f'influence="EYES" start="0" ready="0.2" relax="{end - 0.2}" end="{end}"/></bml>'
    )


def test_the_default_targets_lie_ahead_and_characters_side_by_side() -> None:
    scene = Scene()
    assert scene.direction("Alice", "camera") == pytest.approx((0.0, 0.0))
    yaw, pitch = scene.direction("Alice", "user") or (None, None)
    assert yaw == pytest.approx(0.0) and pitch is not None and pitch < 0  # below the camera
    scene.add_character("Bob")
    left, _ = scene.direction("Alice", "Bob") or (None, None)
    right, _ = scene.direction("Bob", "Alice") or (None, None)
    assert left == pytest.approx(90.0) and right == pytest.approx(-90.0)
    assert scene.direction("Alice", "nowhere") is None


@pytest.mark.parametrize(
    "name, position",
    [("", (0, 0, 1)), ("x" * 65, (0, 0, 1)), ("ball", (0, float("nan"), 1)), ("ball", (0, 1e9, 1))],
)
def test_bad_targets_are_refused(name: str, position: tuple[float, float, float]) -> None:
    with pytest.raises(SceneError):
        Scene().place(name, position)


def test_a_session_looks_at_named_targets_and_warns_about_unknown_ones() -> None:
    scene = Scene()
    scene.place("left", (1.0, 0.0, 1.0))  # 45 degrees to the character's left
    session = Session("Alice", scene=scene)
    session.receive_bml(gaze("b1", "left"), now=0.0)
    assert [f.kind for f in session.take_feedback()].count("warning") == 0
    assert session.frame(1.0).values[YAW] > 0
    session.receive_bml(gaze("b2", "nobody"), now=5.0)
    warnings = [f.xml for f in session.take_feedback() if f.kind == "warning"]
    assert len(warnings) == 1 and "NO_SUCH_TARGET" in warnings[0] and "'nobody'" in warnings[0]
    assert session.frame(6.0).values[YAW] == pytest.approx(0.0)  # straight ahead


def test_two_characters_look_at_each_other() -> None:
    stage = Stage(lambda character: Session(character))
    stage.submit_bml(gaze("a", "Bob", "Alice"), 0.0)  # Bob does not exist yet: warned
    stage.submit_bml(gaze("b", "Alice", "Bob"), 0.0)
    # now he does; the new gaze replaces the first (a MERGE gaze inside it
    # would be removed: the channel is taken, docs/scheduler.md)
    stage.submit_bml(
        gaze("a2", "Bob", "Alice").replace(' id="a2"', ' id="a2" composition="REPLACE"'), 0.0
    )
    stage.tick(1.0)
    alice = stage.characters["Alice"].session.frame(1.0).values[YAW]
    bob = stage.characters["Bob"].session.frame(1.0).values[YAW]
    assert alice > 0 > bob  # Alice turns to her left, where Bob stands; he to his right
    assert stage.scene.snapshot()["characters"] == ["Alice", "Bob"]


def test_a_target_moved_while_the_block_runs_is_followed() -> None:
    stage = Stage(lambda character: Session(character))
    stage.place_target("ball", (1.0, 0.0, 1.0), 0.0)
    stage.submit_bml(gaze("b1", "ball"), 0.0)
    stage.tick(0.5)
    session = stage.characters["default"].session
    before = session.frame(0.5).values[YAW]
    stage.place_target("ball", (-1.0, 0.5, 1.0), 1.0)  # to the right and up
    stage.tick(1.5)
    after = session.frame(1.5).values
    assert before > 0 and after[YAW] == pytest.approx(-before) and after[PITCH] < 0
    assert session.frame(0.9).values[YAW] == pytest.approx(before)  # the past is as it was


def test_a_bad_target_message_is_answered_with_a_warning() -> None:
    stage = Stage(lambda character: Session(character))
    [answer] = stage.place_target("", (0.0, 0.0, 1.0), 0.0)
    assert isinstance(answer, WireFeedback) and "NO_SUCH_TARGET" in answer.xml


def test_a_client_places_a_target_over_the_protocol() -> None:
    async def scenario() -> list[dict[str, object]]:
        async with running_service(real_sessions(), real_assets()) as service:
            url = f"ws://127.0.0.1:{service.port}/bml?format=json"
            async with connect(url) as submitter:
                await read_json(submitter)
                message = {"type": "target", "name": "door", "position": [2.0, 0.0, 1.0]}
                await submitter.send(json.dumps(message))
                await submitter.send(gaze("look", "door", end=0.6))
                return await until_block_final(submitter, "look")

    messages = asyncio.run(scenario())
    kinds = [m.get("kind") for m in messages if m["type"] == "feedback"]
    assert "warning" not in kinds and messages[-1]["state"] == "done"
