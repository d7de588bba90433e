"""The three.js browser viewer in headless Chromium: no request leaves the
machine, several characters side by side, the coded and ARKit streams drive
the face, the FAPs the page decodes equal the server's, the timeline and the
interrupt buttons follow the feedback, refused connections read plainly."""

from __future__ import annotations

from urllib.parse import urlsplit

import pytest

from realizer.client import ViewClient
from realizer.face.fapcoding import DEFAULT_FAP_QUANT, quant_steps
from tests.service.browser import chromium_on_service
from tests.service.conftest import UNIT
from tests.service.test_end_to_end import real_assets, real_sessions

LONG_SMILE = """<bml xmlns="http://www.bml-initiative.org/bml/bml-1.0" id="longsmile">
  <faceLexeme id="smile" lexeme="RAISE_MOUTH_CORNERS" amount="1"
              start="0" attackPeak="0.5" relax="6" end="7"/>
  <head id="nod" lexeme="NOD" start="0.2"/>
</bml>"""


@pytest.mark.slow
def test_the_viewer_loads_everything_from_its_server_and_shows_two_characters() -> None:
    timeout = 60_000 * UNIT
    with chromium_on_service(real_sessions(), real_assets()) as (service, browser):
        origin = f"127.0.0.1:{service.port}"
        page = browser.new_page()
        requested: list[str] = []
        page.on("request", lambda request: requested.append(request.url))
        page.goto(f"http://127.0.0.1:{service.port}/?character=Ann,Bob")
        page.wait_for_function(
            "window.realizerViewer.ready && window.realizerViewer.gpu"
            " && window.realizerViewer.characters.size === 2"
            " && [...window.realizerViewer.characters.values()].every(c => c.frames > 3)",
            timeout=timeout,
        )
        page.wait_for_function("document.querySelectorAll('#examples button').length > 5")
        # one click on an example sends it; the timeline and the interrupt button follow
        page.fill("#character", "Ann")
        page.fill("#bml", LONG_SMILE)
        page.click("#send")
        page.wait_for_selector("#running button[data-block=longsmile]", timeout=timeout)
        page.wait_for_function(
            "(() => { const b = window.realizerViewer.blocks.get('longsmile');"
            " return b && b.behaviours.get('smile') &&"
            " b.behaviours.get('smile').syncs.get('attackPeak').fired !== null; })()",
            timeout=timeout,
        )
        page.click("#running button[data-block=longsmile]")
        page.wait_for_function(
            "window.realizerViewer.blocks.get('longsmile').state === 'interrupted'",
            timeout=timeout,
        )
        assert page.locator("#running button").count() == 0
    hosts = {urlsplit(url).netloc for url in requested if not url.startswith("data:")}
    assert hosts == {origin}, f"requests left the machine: {sorted(hosts)}"
    assert any("three.module.min.js" in url for url in requested)


@pytest.mark.slow
@pytest.mark.parametrize("stream", ["coded", "arkit"])
def test_the_page_decodes_the_faps_the_server_sent(stream: str) -> None:
    timeout = 60_000 * UNIT
    steps = quant_steps() * DEFAULT_FAP_QUANT
    with chromium_on_service(real_sessions(), real_assets(), fps=25.0) as (service, browser):
        url = f"ws://127.0.0.1:{service.port}"
        page = browser.new_page()
        page.goto(f"http://127.0.0.1:{service.port}/?character=Cy&stream={stream}")
        page.wait_for_function(
            "window.realizerViewer.gpu && window.realizerViewer.frames > 3", timeout=timeout
        )
        with ViewClient(url, character="Cy") as reference:
            page.fill("#bml", LONG_SMILE)
            page.click("#send")
            server: dict[int, dict[int, float]] = {}
            lit = 0
            # the page may be slow to send (software WebGL on a busy machine): read
            # until the smile has been on for 40 frames (or 600 frames passed)
            for frame in reference.frames(600, timeout=10 * UNIT):
                server[frame["n"]] = reference.faps(frame)
                lit += bool(server[frame["n"]])
                if lit >= 40:
                    break
            page.wait_for_timeout(500)
        page_frames = page.evaluate("window.realizerViewer.decoded")
        page_log = page.evaluate("window.realizerViewer.feedback.map(f => f.text).join('|')")
        arkit = page.evaluate(
            "[...window.realizerViewer.characters.values()][0].arkit?.weights?.length ?? 0"
        )
    decoded = {f["n"]: f["faps"] for f in page_frames}
    common = [n for n in sorted(server) if n in decoded]
    assert len(common) > 20
    moving = 0
    for n in common:
        for fap in range(1, 69):
            value = server[n].get(fap, 0.0)
            tolerance = steps[fap - 1] / 2 + 1e-3 if stream == "coded" else 1e-3
            assert abs(decoded[n][fap - 1] - value) <= tolerance, (n, fap)
        moving += bool(server[n])
    assert moving > 10, page_log[-300:]
    if stream == "arkit":
        assert arkit == 52


@pytest.mark.slow
def test_a_refused_connection_reads_as_plain_words() -> None:
    with chromium_on_service(
        real_sessions(), real_assets(), submit_token="s3cret", view_token="v1ew"
    ) as (service, browser):
        page = browser.new_page()
        page.goto(f"http://127.0.0.1:{service.port}/?character=Dee")
        page.wait_for_function(
            "document.getElementById('status').textContent.includes('token')",
            timeout=60_000 * UNIT,
        )
        status = page.inner_text("#status")
        page.goto(f"http://127.0.0.1:{service.port}/?character=Dee&token=v1ew")
        page.wait_for_function("window.realizerViewer.frames > 2", timeout=60_000 * UNIT)
        page.click("#send")
        page.wait_for_function(
            "window.realizerViewer.errors.some(e => e.includes('submit token'))",
            timeout=60_000 * UNIT,
        )
    assert "needs a token" in status
    assert "1006" not in status


@pytest.mark.slow
def test_a_gltf_avatar_follows_the_arkit_stream_and_names_its_missing_targets() -> None:
    from dataclasses import replace

    from realizer.face.arkit import has_targets
    from realizer.face.gltf import avatar_report, default_face_glb

    if not has_targets():
        pytest.skip("ARKit targets not extracted")
    glb = default_face_glb(omit=("tongueOut", "cheekPuff"))  # made here, never committed
    report = avatar_report(glb)
    assert report.missing == ("cheekPuff", "tongueOut")
    assets = replace(real_assets(), avatar=glb, avatar_missing=report.missing)
    timeout = 60_000 * UNIT
    with chromium_on_service(real_sessions(), assets) as (service, browser):
        page = browser.new_page()
        page.goto(f"http://127.0.0.1:{service.port}/?character=Eve")
        page.wait_for_function(
            "window.realizerViewer.avatar && window.realizerViewer.avatar.frames > 3",
            timeout=timeout,
        )
        avatar = page.evaluate(
            "({missing: window.realizerViewer.avatar.missing,"
            " bones: window.realizerViewer.avatar.bones})"
        )
        page.fill("#bml", LONG_SMILE)
        page.click("#send")
        page.wait_for_function(
            "window.realizerViewer.avatar.weights[24] > 0.05", timeout=timeout
        )  # mouthSmileRight
        warnings = page.evaluate(
            "window.realizerViewer.feedback.filter(f => f.kind === 'warning').map(f => f.text)"
        )
    assert avatar["missing"] == ["cheekPuff", "tongueOut"]
    assert avatar["bones"]["head"] == "head" and avatar["bones"]["leftEye"] == "leftEye"
    listed = [w for w in warnings if "morph targets missing" in w]
    assert len(listed) == 1 and "cheekPuff" in listed[0] and "tongueOut" in listed[0]
