"""The commands around the service: ``realizer serve`` as a process (its
shutdown), ``realizer send`` and ``realizer render``."""

from __future__ import annotations

import asyncio
import json
import os
import re
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from websockets.asyncio.client import connect
from websockets.exceptions import ConnectionClosed

from tests.service.conftest import UNIT
from tests.service.harness import http_json, running_service
from tests.service.test_end_to_end import (
    BML_NS,
    read_json,
    real_assets,
    real_face,
    real_sessions,
    smile,
)

ROOT = Path(__file__).resolve().parents[2]


async def start_serve(*extra: str) -> tuple[asyncio.subprocess.Process, int]:
    process = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "realizer", "serve", "--port", "0", *extra,
        cwd=ROOT, stderr=asyncio.subprocess.PIPE, stdout=asyncio.subprocess.DEVNULL,
    )  # fmt: skip
    assert process.stderr is not None
    while True:
        line = (await asyncio.wait_for(process.stderr.readline(), 60 * UNIT)).decode()
        if not line:
            raise AssertionError(f"realizer serve exited with {await process.wait()}")
        match = re.search(r"serving on \S+:(\d+)", line)
        if match:
            return process, int(match.group(1))


def test_serve_shuts_down_cleanly_on_sigterm() -> None:
    async def scenario() -> tuple[int, list[dict[str, Any]], int | None, int | None]:
        process, port = await start_serve()
        try:
            assert (await http_json(port, "/health"))["status"] == "ok"
            async with (
                connect(f"ws://127.0.0.1:{port}/view") as viewer,
                connect(f"ws://127.0.0.1:{port}/bml?format=json") as submitter,
            ):
                await viewer.recv()
                await read_json(submitter)
                await submitter.send(json.dumps({"type": "bml", "bml": smile("long", 0, 60)}))
                while (await read_json(submitter)).get("state") != "accepted":
                    pass
                process.send_signal(signal.SIGTERM)
                messages = []
                with pytest.raises(ConnectionClosed):
                    while True:
                        messages.append(await read_json(submitter))
                with pytest.raises(ConnectionClosed):
                    while True:
                        await asyncio.wait_for(viewer.recv(), 10 * UNIT)
            status = await asyncio.wait_for(process.wait(), 20 * UNIT)
            return status, messages, submitter.close_code, viewer.close_code
        finally:
            if process.returncode is None:
                process.kill()

    status, messages, submitter_code, viewer_code = asyncio.run(scenario())
    assert status == 0
    assert submitter_code == 1001 and viewer_code == 1001
    assert [m["state"] for m in messages if m["type"] == "block"] == ["interrupted"]
    assert any(m.get("kind") == "blockProgress" for m in messages)


def test_serve_refuses_a_public_address_without_tokens() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "realizer", "serve", "--host", "0.0.0.0", "--port", "0"],
        cwd=ROOT, capture_output=True, text=True, timeout=60 * UNIT,
    )  # fmt: skip
    assert done.returncode == 2 and "without tokens" in done.stderr


def run_send(port: int, path: Path, *extra: str) -> tuple[int, list[str]]:
    async def send() -> tuple[int, list[str]]:
        process = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "realizer", "send", str(path), "--port", str(port), *extra,
            cwd=ROOT, stdout=asyncio.subprocess.PIPE,
        )  # fmt: skip
        out, _ = await asyncio.wait_for(process.communicate(), 60 * UNIT)
        assert process.returncode is not None
        return process.returncode, out.decode().splitlines()

    return asyncio.run(send())


def test_send_prints_each_feedback_line_and_exits_0_when_the_block_ends(tmp_path: Path) -> None:
    path = tmp_path / "smile.xml"
    path.write_text(smile("sent", 0, 0.4))

    async def scenario() -> tuple[int, list[str]]:
        async with running_service(real_sessions(), real_assets()) as service:
            return await asyncio.to_thread(run_send, service.port, path, "--character", "Eve")

    status, lines = asyncio.run(scenario())
    assert status == 0
    assert lines[0].startswith("<predictionFeedback")
    assert any('id="sent:end"' in line for line in lines)
    assert all(line.startswith("<") and line.endswith(">") for line in lines)


def test_send_exits_1_when_the_block_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "broken.xml"
    path.write_text(f'<bml xmlns="{BML_NS}" id="broken"><faceLexeme')

    async def scenario() -> tuple[int, list[str]]:
        async with running_service(real_sessions(), real_assets()) as service:
            return await asyncio.to_thread(run_send, service.port, path)

    status, lines = asyncio.run(scenario())
    assert status == 1
    assert len(lines) == 1 and "warningFeedback" in lines[0] and "PARSING_FAILURE" in lines[0]


def test_send_exits_2_when_no_service_listens(tmp_path: Path) -> None:
    path = tmp_path / "smile.xml"
    path.write_text(smile("x", 0, 1))
    status, _ = run_send(1, path)  # port 1: nothing listens there
    assert status == 2


def opengl_missing() -> str | None:
    from realizer.errors import RealizerError
    from realizer.face.render import FaceRenderer

    try:
        FaceRenderer(real_face(), 32, 32).close()
    except RealizerError as error:
        return str(error)
    return None


@pytest.mark.opengl
def test_render_writes_one_png_per_frame_and_the_mouth_moves(tmp_path: Path) -> None:
    reason = opengl_missing()
    if reason:
        pytest.skip(f"no OpenGL offscreen context: {reason}")
    from PIL import Image

    path = tmp_path / "smile.xml"
    path.write_text(smile("r", 0.2, 1.0))
    out = tmp_path / "frames"
    done = subprocess.run(
        [sys.executable, "-m", "realizer", "render", str(path), "-o", str(out),
         "--size", "96x96", "--fps", "10", "--tail", "0.3", "--quiet"],
        cwd=ROOT, capture_output=True, text=True, timeout=300 * UNIT,
        env={**os.environ},
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    files = sorted(out.glob("frame_*.png"))
    # frames at 0.0, 0.1, ... until 0.3 s after the block's end at 1.0 s
    assert len(files) == 14
    images = [np.asarray(Image.open(f).convert("RGB"), dtype=np.int16) for f in files]
    assert images[0].shape == (96, 96, 3)
    # the feedback is printed on stdout as the block plays, in time order
    progress = re.findall(r'<(?:blockProgress|syncPointProgress)[^>]* id="([^"]+)"', done.stdout)
    assert progress[0] == "r:start" and progress[-1] == "r:end"
    assert progress.index("r:smile:start") < progress.index("r:smile:end")
    assert np.array_equal(images[0], images[1])  # nothing before the smile starts
    assert np.abs(images[6] - images[0]).sum() > 0  # mid-smile
    assert np.array_equal(images[0], images[-1])  # neutral again after the end


@pytest.mark.opengl
def test_render_writes_an_mp4_through_ffmpeg(tmp_path: Path) -> None:
    reason = opengl_missing()
    if reason:
        pytest.skip(f"no OpenGL offscreen context: {reason}")
    path = tmp_path / "smile.xml"
    path.write_text(smile("v", 0, 0.5))
    out = tmp_path / "smile.mp4"
    done = subprocess.run(
        [sys.executable, "-m", "realizer", "render", str(path), "-o", str(out),
         "--size", "64x64", "--fps", "10", "--tail", "0"],
        cwd=ROOT, capture_output=True, text=True, timeout=300 * UNIT,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "6 frames at 10 fps" in done.stderr
    # the feedback on stdout, as `realizer send` prints it; no bar off a terminal
    assert "blockProgress" in done.stdout and "\r" not in done.stderr
    probe = subprocess.run(
        ["ffprobe", "-v", "error", "-count_frames", "-select_streams", "v:0",
         "-show_entries", "stream=nb_read_frames,width", "-of", "json", str(out)],
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    stream = json.loads(probe.stdout)["streams"][0]
    assert stream["width"] == 64 and int(stream["nb_read_frames"]) == 6


def test_render_refuses_an_output_it_cannot_write(tmp_path: Path) -> None:
    path = tmp_path / "smile.xml"
    path.write_text(smile("v", 0, 0.5))
    done = subprocess.run(
        [sys.executable, "-m", "realizer", "render", str(path), "-o", str(tmp_path / "x.avi")],
        cwd=ROOT, capture_output=True, text=True, timeout=120 * UNIT,
    )  # fmt: skip
    assert done.returncode == 2
    assert "cannot write .avi files" in done.stderr and "Traceback" not in done.stderr
    assert not (tmp_path / "x.avi").exists()
