"""Every example of docs/tutorial.md runs, as written, against a real server.

The examples connect to ws://127.0.0.1:8765; the test starts ``realizer
serve`` on a free port and runs each example in its own interpreter with
that port put in. Each example asserts what it shows, so one that stops
doing what the tutorial says fails here. Section 8's JavaScript runs too:
the Node example under ``node`` beside a copy of the client module, and the
browser example as a module script in Debian's headless chromium, on a page
the same server serves.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.service.conftest import UNIT
from tests.service.process import ServeProcess, serve_process

ROOT = Path(__file__).resolve().parents[2]
TUTORIAL = ROOT / "docs" / "tutorial.md"
BLOCK = re.compile(r"^```python\n(.*?)^```", re.MULTILINE | re.DOTALL)


def examples() -> list[str]:
    return BLOCK.findall(TUTORIAL.read_text(encoding="utf-8"))


def test_the_tutorial_has_its_python_examples() -> None:
    assert len(examples()) >= 6


@pytest.fixture(scope="module")
def server() -> Iterator[ServeProcess]:
    with serve_process() as running:
        yield running


@pytest.mark.slow
@pytest.mark.parametrize("number", range(len(examples())))
def test_the_tutorial_example_runs(number: int, server: ServeProcess, tmp_path: Path) -> None:
    code = examples()[number].replace("127.0.0.1:8765", f"127.0.0.1:{server.port}")
    done = subprocess.run(
        [sys.executable, "-c", code],
        cwd=tmp_path,
        env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"},
        capture_output=True,
        text=True,
        timeout=120 * UNIT,
    )
    assert done.returncode == 0, f"example {number + 1}:\n{code}\n{done.stdout}\n{done.stderr}"
    assert done.stdout.strip(), "the example printed nothing"


# -- the JavaScript of section 8 ---------------------------------------------------

CLIENT_JS = ROOT / "realizer" / "service" / "static" / "realizer-client.js"
#: Debian's node-ws (scripts/setup.sh installs it)
NODE_WS = Path("/usr/share/nodejs/ws")
NODE = shutil.which("node") or shutil.which("nodejs")


def fenced(language: str) -> list[str]:
    """The tutorial's code blocks fenced as ``language``."""
    pattern = re.compile(rf"^```{language}\n(.*?)^```", re.MULTILINE | re.DOTALL)
    return pattern.findall(TUTORIAL.read_text(encoding="utf-8"))


def test_the_tutorial_has_its_javascript_examples() -> None:
    assert len(fenced("js")) == 1 and len(fenced("html")) == 1
    assert '<script type="module">' in fenced("html")[0]


@pytest.mark.slow
def test_the_tutorial_node_example_runs(server: ServeProcess, tmp_path: Path) -> None:
    """Section 8's Node example, as written, beside a copy of the client module
    (its ``./realizer-client.js``) and the ws package in a node_modules."""
    if NODE is None:
        pytest.skip("no node here (Debian's nodejs package; scripts/setup.sh installs it)")
    if not (NODE_WS / "package.json").exists():
        pytest.skip(f"no ws package at {NODE_WS} (Debian's node-ws; scripts/setup.sh)")
    (code,) = fenced("js")
    assert "127.0.0.1:8765" in code
    shutil.copy(CLIENT_JS, tmp_path / "realizer-client.js")
    (tmp_path / "node_modules").mkdir()
    (tmp_path / "node_modules" / "ws").symlink_to(NODE_WS)
    script = tmp_path / "tutorial.mjs"
    script.write_text(code.replace("127.0.0.1:8765", f"127.0.0.1:{server.port}"), "utf-8")
    done = subprocess.run(
        [NODE, str(script)],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120 * UNIT,
    )
    assert done.returncode == 0, f"{done.stdout}\n{done.stderr}"
    assert done.stdout.strip().splitlines()[-1] == "long ended interrupted", done.stdout


@pytest.mark.slow
def test_the_tutorial_browser_example_runs(server: ServeProcess) -> None:
    """Section 8's module script, run in a page the realizer serves, in Debian's
    headless chromium: its console shows the sync points and the block's end."""
    from tests.service.browser import CHROMIUM, CHROMIUM_ARGS, chromium_missing

    reason = chromium_missing()
    if reason:
        pytest.skip(reason)
    from playwright.sync_api import sync_playwright

    (html,) = fenced("html")
    module = re.search(r'<script type="module">\n(.*?)</script>', html, re.DOTALL)
    assert module is not None
    timeout_ms = 60_000 * UNIT
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page()
            lines: list[str] = []
            page.on("console", lambda message: lines.append(message.text))
            errors: list[str] = []
            page.on("pageerror", lambda error: errors.append(str(error)))
            # a page the realizer serves (its health report), so that
            # location.host and "/static/realizer-client.js" are the realizer's
            page.goto(f"http://127.0.0.1:{server.port}/health")
            page.add_script_tag(content=module.group(1), type="module")
            deadline = time.monotonic() + timeout_ms / 1000
            while not any(line.startswith("hello ended") for line in lines) and not errors:
                if time.monotonic() > deadline:
                    break
                page.wait_for_timeout(100)
        finally:
            browser.close()
    assert not errors, errors
    assert "hello ended done" in lines, lines
    assert "block hello accepted" in lines and "block hello done" in lines, lines
    assert any(re.fullmatch(r"nod:\w+ at [0-9.]+ s", line) for line in lines), lines
