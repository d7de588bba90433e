"""The scene on the viewer stream (protocols/viewer.md ``scene``): a viewer that
asks gets the characters' eyes and the targets after its mesh and whenever
the scene changes; one that does not ask gets none. Real server, real
WebSocket clients."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path
from typing import Any

import pytest
from websockets.asyncio.client import connect

from realizer.service import codec
from tests.service.conftest import UNIT
from tests.service.harness import running_service
from tests.service.test_end_to_end import real_assets, real_sessions, smile

SCHEMA = Path(__file__).resolve().parents[2] / "protocols" / "schemas" / "scene.schema.json"


async def until_type(viewer: Any, kind: str, timeout: float = 10 * UNIT) -> dict[str, Any]:
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    while True:
        message = codec.unpack(await asyncio.wait_for(viewer.recv(), deadline - loop.time()))
        if message["type"] == kind:
            return message  # type: ignore[no-any-return]


def test_a_viewer_that_asks_gets_the_scene_and_its_changes() -> None:
    async def scenario() -> tuple[list[str], dict[str, Any], dict[str, Any], list[str]]:
        async with (
            running_service(real_sessions(), real_assets()) as service,
            connect(f"ws://127.0.0.1:{service.port}/view?character=Ann&scene=true") as viewer,
            connect(f"ws://127.0.0.1:{service.port}/view?character=Ann") as plain,
            connect(f"ws://127.0.0.1:{service.port}/bml?format=json") as submitter,
        ):
            first = [codec.unpack(await viewer.recv())["type"] for _ in range(2)]
            await submitter.send(json.dumps({"type": "bml", "bml": smile("b", 0, 0.2, "Bob")}))
            await submitter.send(
                json.dumps({"type": "target", "name": "door", "position": [2.0, 0.5, 1.0]})
            )
            scene = await until_type(viewer, "scene")
            while "door" not in scene["targets"] or "Bob" not in scene["characters"]:
                scene = await until_type(viewer, "scene")
            # a subscribe that switches character sends the scene again after the mesh
            await viewer.send(json.dumps({"type": "subscribe", "character": "Bob"}))
            assert (await until_type(viewer, "mesh"))["character"] == "Bob"
            again = codec.unpack(await viewer.recv())
            # the viewer that did not ask: frames only (and its mesh)
            kinds = set()
            for _ in range(30):
                kinds.add(codec.unpack(await asyncio.wait_for(plain.recv(), 5 * UNIT))["type"])
            return first, scene, again, sorted(kinds)

    first, scene, again, kinds = asyncio.run(scenario())
    assert first == ["mesh", "scene"]
    assert scene["v"] == 1 and scene["targets"]["door"] == [2.0, 0.5, 1.0]
    assert {"Ann", "Bob"} <= set(scene["characters"])
    # Ann and Bob stand side by side: their eyes differ along x only
    ann, bob = scene["targets"]["Ann"], scene["targets"]["Bob"]
    assert ann[1:] == bob[1:] and ann[0] != bob[0]
    assert again["type"] == "scene" and again["version"] >= scene["version"]
    assert kinds == ["frame"] or kinds == ["frame", "mesh"]
    jsonschema = pytest.importorskip("jsonschema")
    jsonschema.Draft202012Validator(json.loads(SCHEMA.read_text())).validate(scene)


def test_an_unsent_scene_message_is_replaced_by_the_newer_one() -> None:
    from realizer.service.messages import ViewOptions
    from realizer.service.server import RealizerService, Viewer

    viewer = Viewer(connection=None, character="a", options=ViewOptions())  # type: ignore[arg-type]
    viewer.scene = True
    offer = RealizerService._offer_scene
    for n in range(10):
        offer(None, viewer, f"scene {n}".encode())  # type: ignore[arg-type]
    assert list(viewer.control) == [b"scene 9"]
    viewer.control.popleft()  # sent: the next one queues anew
    offer(None, viewer, b"scene 10")  # type: ignore[arg-type]
    assert list(viewer.control) == [b"scene 10"]
