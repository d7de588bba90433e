"""protocols/schemas/ and protocols/asyncapi.yaml describe what a real session sends.

Every schema is a valid JSON Schema (draft 2020-12); the AsyncAPI document
names every schema and every one it names exists; and the messages of a real
``realizer serve`` session (welcome, feedback and block states of a block that
runs, one that is refused and one that is interrupted; the viewer's mesh and
frames; /health and /version) and the messages the clients send all validate.
"""

from __future__ import annotations

import base64
import json
import urllib.request
from pathlib import Path
from typing import Any

import pytest

jsonschema = pytest.importorskip("jsonschema", reason="jsonschema comes with the dev extra")
yaml = pytest.importorskip("yaml", reason="PyYAML comes with the dev extra")

from realizer.client import SubmitClient, ViewClient  # noqa: E402
from realizer.service.client import SubmitterProtocol  # noqa: E402
from tests.service.conftest import UNIT  # noqa: E402
from tests.service.process import serve_process  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
PROTOCOLS = ROOT / "protocols"
SCHEMAS = PROTOCOLS / "schemas"
SMILE = (ROOT / "examples" / "bml" / "01_smile.xml").read_text(encoding="utf-8")
LONG = (
    '<bml xmlns="http://www.bml-initiative.org/bml/bml-1.0" id="long">'
    '<head id="nod" lexeme="NOD" start="0" end="30"/></bml>'
)


def schema(name: str) -> Any:
    return json.loads((SCHEMAS / f"{name}.schema.json").read_text(encoding="utf-8"))


def check(name: str, message: Any) -> None:
    jsonschema.Draft202012Validator(schema(name)).validate(message)


def as_json(value: Any) -> Any:
    """A msgpack message as JSON would carry it: bytes base64-encoded."""
    if isinstance(value, bytes):
        return base64.b64encode(value).decode()
    if isinstance(value, dict):
        return {k: as_json(v) for k, v in value.items()}
    if isinstance(value, list):
        return [as_json(v) for v in value]
    return value


def test_every_schema_is_valid_and_the_asyncapi_document_names_them_all() -> None:
    files = sorted(SCHEMAS.glob("*.schema.json"))
    assert len(files) >= 10
    for path in files:
        jsonschema.Draft202012Validator.check_schema(json.loads(path.read_text()))
    document = yaml.safe_load((PROTOCOLS / "asyncapi.yaml").read_text(encoding="utf-8"))
    assert document["asyncapi"].startswith("3.")
    named = set()
    for channel in document["channels"].values():
        for message in channel["messages"].values():
            ref = message["payload"]["$ref"]
            assert (PROTOCOLS / ref).is_file(), ref
            named.add(Path(ref).name)
    http_only = {"health.schema.json", "version.schema.json"}
    assert named | http_only == {p.name for p in files}
    for operation in document["operations"].values():
        channel = operation["channel"]["$ref"].removeprefix("#/channels/")
        assert channel in document["channels"]
        for message in operation["messages"]:
            _, _, name = message["$ref"].rpartition("/")
            assert name in document["channels"][channel]["messages"]


def test_the_schemas_refuse_what_the_protocol_forbids() -> None:
    with pytest.raises(jsonschema.ValidationError):
        check(
            "block", {"type": "block", "character": "a", "block": "b", "state": "gone", "time": 0}
        )
    with pytest.raises(jsonschema.ValidationError):
        check("interrupt-request", {"type": "interrupt"})
    with pytest.raises(jsonschema.ValidationError):
        check("bml-request", {"type": "bml", "bml": "<bml/>", "character": "no spaces"})


@pytest.mark.slow
def test_a_real_session_sends_only_messages_the_schemas_allow() -> None:
    seen: dict[str, int] = {}
    with serve_process() as server:
        with SubmitClient(server.url, character="Alice") as client:
            check("welcome", client.welcome)
            seen["welcome"] = 1
            messages: list[dict[str, Any]] = []
            client.run_block(SMILE, on_message=messages.append, timeout=30 * UNIT)
            client.run_block("<bml", on_message=messages.append, timeout=30 * UNIT)
            client.submit(LONG)
            while True:
                message = client.receive(30 * UNIT)
                messages.append(message)
                if message.get("type") == "block" and message["state"] == "accepted":
                    client.interrupt("long")
                if message.get("type") == "block" and message["state"] == "interrupted":
                    break
        for message in messages:
            check(message["type"], message)
            seen[message["type"]] = seen.get(message["type"], 0) + 1
        states = {m["state"] for m in messages if m["type"] == "block"}
        kinds = {m["kind"] for m in messages if m["type"] == "feedback"}
        assert states == {"accepted", "done", "rejected", "interrupted"}
        assert kinds == {"prediction", "blockProgress", "syncPointProgress", "warning"}

        with ViewClient(server.url, character="Alice", vertices="int16") as view:
            check("mesh", as_json(view.mesh))
            # as sent: the whole first frame, then (the face rests) `same` messages
            sent = [view.receive(30 * UNIT) for _ in range(5)]
            view.subscribe(character="Bob", vertices="float32")
            while view.receive(30 * UNIT)["type"] != "mesh":
                pass
            sent += [view.receive(30 * UNIT) for _ in range(2)]
        for message in sent:
            if message["type"] in ("frame", "same"):
                check(message["type"], as_json(message))
        assert sent[0]["type"] == "frame" and any("vertices" in m for m in sent)
        assert any(m["type"] == "same" for m in sent)

        for path, name in (("/health", "health"), ("/version", "version")):
            with urllib.request.urlopen(f"http://127.0.0.1:{server.port}{path}", timeout=10) as r:
                check(name, json.loads(r.read()))

    check("bml-request", json.loads(SubmitterProtocol.bml(SMILE, "Alice")))
    check("interrupt-request", json.loads(SubmitterProtocol.interrupt("long")))
    check("subscribe-request", {"type": "subscribe", "character": "Bob", "vertices": "float32"})
    check("subscribe-request", {"type": "subscribe", "same": False})
    assert seen["welcome"] == 1 and seen["feedback"] > 5 and seen["block"] == 5


def test_health_is_what_the_readme_shows_and_nothing_more() -> None:
    readme = (PROTOCOLS / "README.md").read_text(encoding="utf-8")
    after = readme.split("`GET /health`:", 1)[1]
    example = json.loads(after.split("```json\n", 1)[1].split("```", 1)[0])
    check("health", example)
    # an internal field that nobody documented is refused, at the top and in clock
    with pytest.raises(jsonschema.ValidationError, match="Additional properties"):
        check("health", {**example, "planner_threads": 4})
    with pytest.raises(jsonschema.ValidationError, match="Additional properties"):
        check("health", {**example, "clock": {**example["clock"], "queue": []}})


SPEECH = (
    '<bml xmlns="http://www.bml-initiative.org/bml/bml-1.0" id="talk">'
    '<speech id="say"><text>Hello there, this is a long sentence that goes on for a while, '
    "so that it can be interrupted before it ends, and then some more words.</text></speech></bml>"
)


@pytest.mark.slow
def test_speech_audio_its_cut_the_model_and_a_viewer_error_are_what_the_schemas_allow() -> None:
    """The viewer's other messages from a real server: ``audio`` of a speech,
    the ``audioCut`` of its interruption, the ``model`` (``model=true``) and
    the ``error`` answering a subscribe it cannot follow; and the client's
    ``target`` request."""
    import msgpack
    from websockets.sync.client import connect

    check("target-request", json.loads(SubmitterProtocol.target("door", (2.0, 0.0, 1.0))))
    with pytest.raises(jsonschema.ValidationError):
        check("target-request", {"type": "target", "name": "door", "position": [1, 2]})
    with serve_process() as server:
        url = f"ws://127.0.0.1:{server.port}/view?character=Carl&model=true"
        with connect(url, max_size=None) as raw:  # the model is about 1.8 MB

            def next_message() -> dict[str, Any]:
                message: dict[str, Any] = msgpack.unpackb(raw.recv(30 * UNIT), raw=False)
                return message

            assert next_message()["type"] == "mesh"
            model = next_message()
            check("model", as_json(model))
            raw.send(json.dumps({"type": "subscribe", "vertices": "bogus"}))
            while (error := next_message())["type"] != "error":
                pass
            check("viewer-error", as_json(error))
        with (
            ViewClient(server.url, character="Carl") as view,
            SubmitClient(server.url, character="Carl") as speaker,
        ):
            speaker.target("door", (2.0, 0.0, 1.0))
            speaker.submit(SPEECH)
            audio: dict[str, Any] | None = None
            cut: dict[str, Any] | None = None
            for _ in range(3000):  # about a minute of frames at 60 fps
                message = view.receive(30 * UNIT)
                if message["type"] == "audio" and audio is None:
                    audio = message
                    speaker.interrupt("talk")
                elif message["type"] == "audioCut":
                    cut = message
                    break
            if audio is None:
                pytest.skip("the server sent no speech audio (no TTS here)")
            check("audio", as_json(audio))
            assert cut is not None, "no audioCut after the speech was interrupted"
            check("audio-cut", as_json(cut))
            assert cut["t"] >= audio["t"]
