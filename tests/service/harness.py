"""Run the real service in-process on a free loopback port, for tests."""

from __future__ import annotations

import asyncio
import itertools
import json
import os
import urllib.request
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from typing import Any

import pytest
from websockets.asyncio.client import connect
from websockets.exceptions import ConnectionClosed

from realizer.service.limits import ServiceLimits
from realizer.service.server import FaceAssets, RealizerService, ServiceConfig
from realizer.service.stage import Stage
from realizer.session import Session


@asynccontextmanager
async def running_service(
    make_session: Callable[[str], Session],
    assets: FaceAssets,
    *,
    limits: ServiceLimits | None = None,
    **config: Any,
) -> AsyncIterator[RealizerService]:
    limits = limits or ServiceLimits()
    service = RealizerService(
        ServiceConfig(host="127.0.0.1", port=0, limits=limits, **config),
        Stage(make_session, limits),
        assets,
    )
    await service.start()
    try:
        yield service
    finally:
        await service.shutdown()


async def http_get(port: int, path: str) -> tuple[int, str, bytes]:
    """(status, content type, body) of a plain HTTP GET on the service."""

    def fetch() -> tuple[int, str, bytes]:
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}{path}", timeout=10) as reply:
                return reply.status, reply.headers["Content-Type"], reply.read()
        except urllib.error.HTTPError as error:
            return error.code, error.headers["Content-Type"], error.read()

    return await asyncio.to_thread(fetch)


async def http_json(port: int, path: str) -> Any:
    status, _, body = await http_get(port, path)
    assert status == 200
    return json.loads(body)


async def viewers_and_close_codes(
    base: str, count: int, timeout: float
) -> tuple[list[Any], list[int | None]]:
    """Open ``count`` viewers of characters v0, v1, ... on ``base``; each one's
    close code if it was closed instead of getting its first message (the
    mesh), else None."""
    viewers = [await connect(f"{base}/view?character=v{n}") for n in range(count)]
    codes: list[int | None] = []
    for viewer in viewers:
        try:
            await asyncio.wait_for(viewer.recv(), timeout)
            codes.append(None)
        except ConnectionClosed:
            codes.append(viewer.close_code)
    return viewers, codes


def judge_frame_gaps(window: list[float], bound: float, where: str) -> None:
    """Assert no gap between consecutive arrival times in ``window`` exceeds ``bound``.

    Timing is judged only on a machine that is not overloaded (load average
    at most the core count): otherwise the test skips, naming the largest gap.
    """
    gaps = [b - a for a, b in itertools.pairwise(window)]
    load = os.getloadavg()[0]
    cpus = os.cpu_count() or 1
    if load > cpus:
        pytest.skip(f"timing not judged: load average {load:.1f} > {cpus} CPUs "
                    f"(largest gap {max(gaps) * 1e3:.1f} ms)")  # fmt: skip
    assert max(gaps) <= bound, f"a gap of {max(gaps) * 1e3:.1f} ms in {where}"
