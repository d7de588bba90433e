"""The Python clients against the real ``realizer serve``: events, typed errors, asyncio."""

from __future__ import annotations

import asyncio
import socket
from collections.abc import Iterator
from pathlib import Path

import pytest

from realizer.bml_parser.feedback import BlockProgress, PredictionFeedback, SyncPointProgress
from realizer.client import (
    AsyncSubmitClient,
    AsyncViewClient,
    BlockEvent,
    ConnectionLost,
    Event,
    FeedbackEvent,
    Forbidden,
    ServerBusy,
    ServerUnavailable,
    SubmitClient,
    Unauthorized,
    ViewClient,
)
from tests.service.conftest import UNIT
from tests.service.process import ServeProcess, serve_process

ROOT = Path(__file__).resolve().parents[2]
SMILE = (ROOT / "examples" / "bml" / "01_smile.xml").read_text(encoding="utf-8")
LONG_NOD = (
    '<bml xmlns="http://www.bml-initiative.org/bml/bml-1.0" id="{id}">'
    '<head id="nod" lexeme="NOD" start="0" end="30"/></bml>'
)


@pytest.fixture(scope="module")
def server() -> Iterator[ServeProcess]:
    with serve_process() as running:
        yield running


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
    return port


def test_run_block_hands_out_parsed_feedback_and_the_final_state(server: ServeProcess) -> None:
    events: list[Event] = []
    with SubmitClient(server.url, character="Alice") as client:
        assert client.welcome["protocol"] == 1 and client.welcome["character"] == "Alice"
        state = client.run_block(SMILE, on_event=events.append, timeout=30 * UNIT)
    assert state == "done"
    blocks = [e for e in events if isinstance(e, BlockEvent)]
    assert [b.state for b in blocks] == ["accepted", "done"] and blocks[-1].final
    feedback = [e for e in events if isinstance(e, FeedbackEvent)]
    assert {e.character for e in feedback} == {"Alice"}
    parsed = [e.feedback for e in feedback]
    assert any(isinstance(p, PredictionFeedback) for p in parsed)
    ends = [p for p in parsed if isinstance(p, BlockProgress) and p.sync == "end"]
    assert len(ends) == 1 and ends[0].block_id == blocks[0].block_id
    syncs = [p for p in parsed if isinstance(p, SyncPointProgress)]
    assert syncs and all(p.block_id == blocks[0].block_id and p.behaviour_id for p in syncs)
    assert [p.global_time for p in syncs] == sorted(p.global_time for p in syncs)


def test_an_interrupted_block_ends_interrupted(server: ServeProcess) -> None:
    with SubmitClient(server.url, character="Bob") as client:
        client.submit(LONG_NOD.format(id="long"))
        while True:
            event = client.receive_event(30 * UNIT)
            if isinstance(event, BlockEvent) and event.state == "accepted":
                break
        client.interrupt("long")
        states: list[str] = []
        while True:
            event = client.receive_event(30 * UNIT)
            if isinstance(event, BlockEvent):
                states.append(event.state)
                if event.final:
                    break
    assert states == ["interrupted"]


def test_nothing_listening_raises_server_unavailable_naming_the_url() -> None:
    port = free_port()
    with pytest.raises(ServerUnavailable, match=f"cannot connect to ws://127.0.0.1:{port}/bml"):
        SubmitClient(f"ws://127.0.0.1:{port}")


def test_the_asyncio_client_runs_a_block_and_watches_frames(server: ServeProcess) -> None:
    async def scenario() -> tuple[str, list[Event], int, dict[int, float]]:
        events: list[Event] = []
        async with (
            AsyncViewClient(server.url, character="Carol") as view,
            AsyncSubmitClient(server.url, character="Carol") as client,
        ):
            assert view.mesh["type"] == "mesh" and view.mesh["vertexCount"] > 0
            running = asyncio.create_task(
                client.run_block(
                    SMILE, character="Carol", on_event=events.append, timeout=30 * UNIT
                )
            )
            moving: dict[int, float] = {}
            frames = 0
            async for frame in view.frames(count=int(240 * UNIT), timeout=30 * UNIT):
                frames += 1
                moving.update(view.faps(frame))
                if moving and running.done():
                    break
            state = await running
        return state, events, frames, moving

    state, events, frames, moving = asyncio.run(scenario())
    assert state == "done" and frames > 0
    assert any(isinstance(e, FeedbackEvent) for e in events)
    assert moving, "the smile moved no FAP in the frames watched"


def test_the_asyncio_client_interrupts() -> None:
    async def scenario(url: str) -> list[str]:
        async with AsyncSubmitClient(url, character="Dave") as client:
            await client.submit(LONG_NOD.format(id="n"))
            states: list[str] = []
            async for event in client.events(30 * UNIT):
                if isinstance(event, BlockEvent):
                    states.append(event.state)
                    if event.state == "accepted":
                        await client.interrupt("n")
                    if event.final:
                        break
            return states

    with serve_process() as running:
        assert asyncio.run(scenario(running.url)) == ["accepted", "interrupted"]


def test_tokens_give_unauthorized_and_forbidden_and_a_full_server_is_busy() -> None:
    with serve_process(
        "--submit-token", "s3cret", "--view-token", "look", "--limit", "submitters=1"
    ) as running:
        with pytest.raises(Unauthorized) as refused:
            SubmitClient(running.url)
        assert refused.value.status == 401 and "token" in str(refused.value)
        with pytest.raises(Forbidden):
            SubmitClient(running.url, token="look")
        with ViewClient(running.url, token="look") as view:
            assert view.mesh["type"] == "mesh"
        with SubmitClient(running.url, token="s3cret"), pytest.raises(ServerBusy) as busy:
            SubmitClient(running.url, token="s3cret")
        assert busy.value.code == 1013

        async def refused_async() -> None:
            async with AsyncSubmitClient(running.url, token="wrong"):
                pass

        with pytest.raises(Unauthorized):
            asyncio.run(refused_async())


def test_a_server_that_stops_is_a_lost_connection_with_1001() -> None:
    with serve_process() as running, SubmitClient(running.url) as client:
        running.process.terminate()
        with pytest.raises(ConnectionLost) as lost:
            client.receive(30 * UNIT)
    assert lost.value.code == 1001
