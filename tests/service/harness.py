"""Run the real service in-process on a free loopback port, for tests."""

from __future__ import annotations

import asyncio
import json
import urllib.request
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from typing import Any

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
