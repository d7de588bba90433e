"""Headless Chromium for the browser viewer's test: Debian's chromium driven
by Playwright, never a downloaded browser."""

from __future__ import annotations

import asyncio
import io
import os
import shutil
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
import numpy.typing as npt

from realizer.service.limits import ServiceLimits
from realizer.service.server import FaceAssets, RealizerService, ServiceConfig
from realizer.service.stage import Stage
from realizer.session import Session

CHROMIUM = os.environ.get("REALIZER_CHROMIUM", "/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]


def chromium_missing() -> str | None:
    """Why the browser test cannot run here, or None."""
    if shutil.which(CHROMIUM) is None and not os.path.exists(CHROMIUM):
        return f"no Chromium at {CHROMIUM} (scripts/setup.sh installs Debian's chromium)"
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "the playwright package is not installed (pip install -e '.[dev]')"
    return None


@contextmanager
def service_in_thread(
    make_session: Callable[[str], Session], assets: FaceAssets, **config: Any
) -> Iterator[RealizerService]:
    """The real service on a free loopback port, its event loop in a thread,
    so that Playwright's blocking API can run in the test's thread."""
    loop = asyncio.new_event_loop()
    started = threading.Event()
    holder: dict[str, Any] = {}

    async def main() -> None:
        service = RealizerService(
            ServiceConfig(host="127.0.0.1", port=0, **config),
            Stage(make_session, config.get("limits", ServiceLimits())),
            assets,
        )
        await service.start()
        holder["service"] = service
        holder["stop"] = asyncio.Event()
        started.set()
        await holder["stop"].wait()
        await service.shutdown()

    thread = threading.Thread(target=loop.run_until_complete, args=(main(),), daemon=True)
    thread.start()
    if not started.wait(30):
        raise RuntimeError("the service did not start")
    try:
        yield holder["service"]
    finally:
        loop.call_soon_threadsafe(holder["stop"].set)
        thread.join(30)
        loop.close()


@contextmanager
def chromium_on_service(
    make_session: Callable[[str], Session],
    assets: FaceAssets,
    *,
    args: tuple[str, ...] = (),
    **config: Any,
) -> Iterator[tuple[RealizerService, Any]]:
    """The real service (:func:`service_in_thread`) and Debian's headless
    Chromium launched by Playwright with :data:`CHROMIUM_ARGS` and ``args``.

    The calling test skips, with the reason, where Chromium or Playwright is
    missing; on exit the browser is closed and the service stopped.
    """
    import pytest

    reason = chromium_missing()
    if reason:
        pytest.skip(reason)
    from playwright.sync_api import sync_playwright

    with service_in_thread(make_session, assets, **config) as service, sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=[*CHROMIUM_ARGS, *args])
        try:
            yield service, browser
        finally:
            browser.close()


def canvas(page: Any, selector: str = "#face") -> npt.NDArray[np.int16]:
    """A screenshot of the page's canvas as RGB, int16 (differences may be negative)."""
    from PIL import Image

    png = page.locator(selector).screenshot()
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.int16)


def patch(image: npt.NDArray[Any], centre: tuple[float, float], radius: int) -> npt.NDArray[Any]:
    """The square of ``image`` within ``radius`` pixels of ``centre`` (x, y)."""
    x, y = round(centre[0]), round(centre[1])
    return image[max(0, y - radius) : y + radius, max(0, x - radius) : x + radius]
