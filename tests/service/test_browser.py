"""The browser viewer, end to end in headless Chromium (Debian's chromium
driven by Playwright): pick a character, watch the face, send a smile and
see the canvas change around the mouth, deformed on the GPU path."""

from __future__ import annotations

import numpy as np
import pytest

from tests.service.browser import canvas, chromium_on_service, patch
from tests.service.conftest import UNIT
from tests.service.test_end_to_end import real_assets, real_face, real_sessions

SMILE = """<bml xmlns="http://www.bml-initiative.org/bml/bml-1.0" id="browsersmile">
  <faceLexeme id="smile" lexeme="RAISE_MOUTH_CORNERS" amount="1"
              start="0" attackPeak="0.3" relax="20" end="21"/>
</bml>"""


@pytest.mark.slow
def test_the_browser_viewer_shows_a_smile_sent_from_the_page() -> None:
    timeout_ms = 30_000 * UNIT
    with chromium_on_service(real_sessions(), real_assets()) as (service, browser):
        page = browser.new_page(viewport={"width": 1100, "height": 800})
        page.goto(f"http://127.0.0.1:{service.port}/?character=Zoe")
        page.wait_for_function(
            "window.realizerViewer.meshLoaded && window.realizerViewer.frames > 3",
            timeout=timeout_ms,
        )
        neutral = canvas(page)
        points = real_face().params.feature_points

        def on_canvas(name: str) -> tuple[float, float]:
            x, y = page.evaluate(
                "([x, y, z]) => window.realizerViewer.project(x, y, z)", list(points[name])
            )
            return float(x), float(y)

        page.fill("#bml", SMILE)
        page.click("#send")
        page.wait_for_function(
            "window.realizerViewer.feedback.some(f => f.text.includes('accepted'))",
            timeout=timeout_ms,
        )
        # wait until the frames show the smile past its attack peak (0.3 s)
        page.wait_for_function(
            "window.realizerViewer.lastFrame && window.realizerViewer.lastFrame.faps > 0",
            timeout=timeout_ms,
        )
        lit = page.evaluate("window.realizerViewer.lastFrame.t")
        page.wait_for_function(
            f"window.realizerViewer.lastFrame.t > {lit + 0.5}", timeout=timeout_ms
        )
        page.wait_for_timeout(200)  # one more animation frame drawn
        smiling = canvas(page)
        log = page.evaluate("window.realizerViewer.feedback.map(f => f.text)")
        where = {name: on_canvas(name) for name in ("8.3", "8.4", "3.5", "3.6")}
        on_gpu = page.evaluate("window.realizerViewer.gpu")

    difference = np.abs(smiling - neutral).sum(axis=2)
    mouth = [patch(difference, where[p], 25) for p in ("8.3", "8.4")]
    eyes = [patch(difference, where[p], 25) for p in ("3.5", "3.6")]
    # both mouth corners changed; the eyes did not (or far less)
    for corner in mouth:
        assert np.count_nonzero(corner > 30) >= 20
    assert sum(float(c.mean()) for c in mouth) > 5 * sum(float(e.mean()) for e in eyes) + 1
    assert on_gpu  # the shader deformed the face from FAP frames (the model came once)
    assert any("predictionFeedback" in line for line in log)
    assert any("blockProgress" in line for line in log)
