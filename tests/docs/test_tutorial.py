"""Every Python example of docs/tutorial.md runs, as written, against a real server.

The examples connect to ws://127.0.0.1:8765; the test starts ``realizer
serve`` on a free port and runs each example in its own interpreter with
that port put in. Each example asserts what it shows, so one that stops
doing what the tutorial says fails here.
"""

from __future__ import annotations

import re
import subprocess
import sys
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
