"""The browser viewer draws several characters where the server's scene puts
them, so characters that gaze at each other are seen looking at each other
(protocols/viewer.md ``scene``). Headless Debian Chromium, the real service."""

from __future__ import annotations

import json
from typing import Any

import pytest

from tests.service.browser import chromium_on_service
from tests.service.conftest import UNIT
from tests.service.test_end_to_end import real_assets, real_sessions

BML_NS = "http://www.bml-initiative.org/bml/bml-1.0"
#: FAP 23, yaw_l_eyeball (positive: to the character's left), index 22 of a FAP vector
EYE_YAW = 22


def gaze(block: str, character: str, target: str) -> str:
    return (
        f'<bml xmlns="{BML_NS}" id="{block}" characterId="{character}">'
        f'<gaze id="g" target="{target}" influence="EYES" start="0" ready="0.2" '
        'relax="29.8" end="30"/></bml>'
    )


@pytest.mark.slow
def test_two_characters_are_drawn_at_their_scene_places_looking_at_each_other() -> None:
    from websockets.sync.client import connect

    timeout = 60_000 * UNIT
    with chromium_on_service(real_sessions(), real_assets()) as (service, browser):
        page = browser.new_page()
        page.goto(f"http://127.0.0.1:{service.port}/?character=Ann,Bob")
        # viewer.js's placeholder (no characters) is window.realizerViewer until the
        # viewer's module has loaded: read it with ?. (a TypeError fails the wait)
        page.wait_for_function(
            "(() => { const s = window.realizerViewer;"
            " return s.characters?.size === 2 && s.scene && s.scene.targets.Ann"
            " && s.scene.targets.Bob"
            " && [...s.characters.values()].every(c => c.frames > 3 && c.group); })()",
            timeout=timeout,
        )
        with connect(f"ws://127.0.0.1:{service.port}/bml?format=json") as submitter:
            json.loads(submitter.recv())  # welcome
            submitter.send(gaze("ann", "Ann", "Bob"))
            submitter.send(gaze("bob", "Bob", "Ann"))
            # both eyes turned well away from straight ahead, in the newest frames
            page.wait_for_function(
                "(() => { const d = window.realizerViewer.decoded;"
                " const last = (id) => [...d].reverse().find(f => f.character === id);"
                " const a = last('Ann'), b = last('Bob');"
                f" return a && b && Math.abs(a.faps[{EYE_YAW}]) > 1000"
                f" && Math.abs(b.faps[{EYE_YAW}]) > 1000; }})()",
                timeout=timeout,
            )
        seen: dict[str, Any] = page.evaluate(
            "(() => { const s = window.realizerViewer; const out = {};"
            " for (const [id, c] of s.characters) {"
            "   const f = [...s.decoded].reverse().find(x => x.character === id);"
            f"   out[id] = {{x: c.group.position.x, yaw: f.faps[{EYE_YAW}],"
            "              eyes: s.scene.targets[id]}; }"
            " return out; })()"
        )
    ann, bob = seen["Ann"], seen["Bob"]
    # drawn as far apart as the scene places them, in the same order
    assert bob["x"] - ann["x"] == pytest.approx(bob["eyes"][0] - ann["eyes"][0], abs=1e-6)
    assert ann["x"] != bob["x"]
    # each looks towards the other as drawn: yaw to the left (+) where the other is at +x
    assert (ann["yaw"] > 0) == (bob["x"] > ann["x"])
    assert (bob["yaw"] > 0) == (ann["x"] > bob["x"])
