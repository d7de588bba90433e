"""The viewer protocol's audio stream, end to end: the real server, sessions and eSpeak NG."""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import json
from typing import Any

import numpy as np
from websockets.asyncio.client import ClientConnection, connect

from realizer.service import codec
from tests.service.conftest import UNIT
from tests.service.harness import running_service
from tests.service.test_end_to_end import BML_NS, real_assets, real_sessions

SPEECH = (
    f'<bml xmlns="{BML_NS}" id="talk"><speech id="s"><text>Hello there, '
    'my <sync id="m"/>friend. How are you today?</text></speech></bml>'
)


async def collect(viewer: ClientConnection, seconds: float) -> list[dict[str, Any]]:
    messages: list[dict[str, Any]] = []
    loop = asyncio.get_running_loop()
    until = loop.time() + seconds
    while (left := until - loop.time()) > 0:
        try:
            data = await asyncio.wait_for(viewer.recv(), left)
        except TimeoutError:
            break
        messages.append(codec.unpack(data))  # type: ignore[arg-type]
    return messages


async def submit(port: int, text: str) -> ClientConnection:
    submitter = await connect(f"ws://127.0.0.1:{port}/bml?format=json")
    assert json.loads(await submitter.recv())["type"] == "welcome"
    await submitter.send(text)
    return submitter


def test_a_viewer_receives_audio_chunks_whose_timestamps_match_the_frames() -> None:
    async def scenario() -> list[dict[str, Any]]:
        async with running_service(real_sessions(), real_assets(), fps=30.0) as service:
            viewer = await connect(f"ws://127.0.0.1:{service.port}/view")
            assert codec.unpack(await viewer.recv())["type"] == "mesh"  # type: ignore[arg-type]
            submitter = await submit(service.port, SPEECH)
            messages = await collect(viewer, 3.5 * max(UNIT, 1.0))
            await submitter.close()
            await viewer.close()
            return messages

    messages = asyncio.run(scenario())
    audio = [m for m in messages if m["type"] == "audio"]
    frames = [m for m in messages if m["type"] == "frame"]
    assert audio and frames
    rate = audio[0]["rate"]
    assert rate == 22050 and all(m["format"] == "pcm16" and m["channels"] == 1 for m in audio)
    # chunks join sample for sample on the server clock
    for earlier, later in itertools.pairwise(audio):
        assert round(later["t"] * rate) == round(earlier["t"] * rate) + earlier["count"]
    samples = np.concatenate([np.frombuffer(m["samples"], dtype="<i2") for m in audio])
    assert len(samples) == sum(m["count"] for m in audio)
    assert np.abs(samples.astype(np.int32)).max() > 1000  # speech, not silence
    # the audio starts with the speech block, whose frames show the same clock:
    # each chunk was sent at a frame's tick, ahead of it by at most the lead
    frame_times = np.array([f["t"] for f in frames])
    for chunk in audio[:-1]:
        sent_with = frame_times[frame_times <= chunk["t"] + 1e-9]
        assert sent_with.size and chunk["t"] - sent_with.max() <= 0.1 + 1.0 / 30.0 + 1e-6
    # the mouth moves while the audio plays
    speaking = [f for f in frames if audio[0]["t"] <= f["t"] <= audio[-1]["t"]]
    assert any(3 in set(f["fap"]["ids"]) for f in speaking if "fap" in f)


def test_a_viewer_can_opt_out_of_audio() -> None:
    async def scenario() -> list[dict[str, Any]]:
        async with running_service(real_sessions(), real_assets(), fps=30.0) as service:
            viewer = await connect(f"ws://127.0.0.1:{service.port}/view?audio=none")
            await viewer.recv()
            submitter = await submit(service.port, SPEECH)
            messages = await collect(viewer, 1.5 * max(UNIT, 1.0))
            await submitter.close()
            await viewer.close()
            return messages

    messages = asyncio.run(scenario())
    assert any(m["type"] == "frame" for m in messages)
    assert not any(m["type"] == "audio" for m in messages)


def test_interrupting_a_speech_cuts_the_audio_sent_ahead() -> None:
    async def scenario() -> list[dict[str, Any]]:
        async with running_service(real_sessions(), real_assets(), fps=30.0) as service:
            viewer = await connect(f"ws://127.0.0.1:{service.port}/view")
            await viewer.recv()
            submitter = await submit(service.port, SPEECH)
            messages = await collect(viewer, 0.6)
            await submitter.send(json.dumps({"type": "interrupt", "block": "talk"}))
            messages += await collect(viewer, 1.0)
            await submitter.close()
            await viewer.close()
            return messages

    messages = asyncio.run(scenario())
    cuts = [m for m in messages if m["type"] == "audioCut"]
    assert len(cuts) == 1
    cut = cuts[0]["t"]
    after = [m for m in messages[messages.index(cuts[0]) :] if m["type"] == "audio"]
    # nothing sounds after the cut
    for chunk in after:
        assert not np.frombuffer(chunk["samples"], dtype="<i2").any()
    before = [m for m in messages[: messages.index(cuts[0])] if m["type"] == "audio"]
    assert before and before[-1]["t"] + before[-1]["count"] / before[-1]["rate"] > cut


class SlowTts:
    """eSpeak NG taking ``delay`` seconds longer per synthesis, as Piper may."""

    def __init__(self, delay: float) -> None:
        from realizer.engines.speech import load_backend

        self.inner = load_backend("espeak")
        self.name = "slow-espeak"
        self.delay = delay

    def has_language(self, language: str) -> bool:
        return bool(self.inner.has_language(language))

    def synthesize(self, text: Any, language: str | None = None) -> Any:
        import time

        time.sleep(self.delay)
        return self.inner.synthesize(text, language)


def test_a_speech_that_takes_long_to_synthesise_starts_when_its_audio_is_ready() -> None:
    """Regression: a block was timed from its arrival, so a speech whose
    synthesis took longer than itself was over before it was planned: no
    audio reached a viewer and every syncPointProgress came at once."""
    from realizer.engines import EngineRegistry
    from realizer.engines.face import FaceEngine
    from realizer.engines.speech import SpeechEngine
    from realizer.session import Session

    delay = 1.5
    engine = SpeechEngine(SlowTts(delay))  # type: ignore[arg-type]

    def sessions(character: str) -> Session:
        return Session(character, registry=EngineRegistry([FaceEngine.default(), engine]))

    async def scenario() -> tuple[list[dict[str, Any]], list[dict[str, Any]], float]:
        async with running_service(sessions, real_assets(), fps=30.0) as service:
            viewer = await connect(f"ws://127.0.0.1:{service.port}/view")
            await viewer.recv()
            sent = service.now()
            submitter = await submit(service.port, SPEECH)
            messages = await collect(viewer, delay + 3.5 * max(UNIT, 1.0))
            feedback = []
            with contextlib.suppress(TimeoutError):
                while True:
                    feedback.append(json.loads(await asyncio.wait_for(submitter.recv(), 0.2)))
            await submitter.close()
            await viewer.close()
            return messages, feedback, sent

    messages, feedback, sent = asyncio.run(scenario())
    audio = [m for m in messages if m["type"] == "audio"]
    loud = [m for m in audio if np.abs(np.frombuffer(m["samples"], dtype="<i2")).max() > 1000]
    assert loud, "no audible chunk reached the viewer"
    progress = [f for f in feedback if f.get("kind") == "syncPointProgress" and ":s:" in f["xml"]]
    assert progress
    start = min(f["time"] for f in progress)
    # timed from when the audio was ready, not from arrival ...
    assert start >= sent + delay - 0.05
    # ... so the speech plays out: its markers and end come over seconds, not at once
    assert max(f["time"] for f in progress) - start > 1.0
    assert loud[0]["t"] >= start - 0.2
