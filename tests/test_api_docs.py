"""The API reference builds from the docstrings with no warning from pdoc."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_the_api_reference_builds_without_warnings(tmp_path: Path) -> None:
    if importlib.util.find_spec("pdoc") is None:
        pytest.skip("pdoc is not installed (it comes with the dev extra)")
    done = subprocess.run(
        [sys.executable, "scripts/build_api_docs.py", "-o", str(tmp_path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""
    for page in ("index.html", "realizer/client.html", "realizer/session.html"):
        assert (tmp_path / page).is_file(), page
    client = (tmp_path / "realizer" / "client.html").read_text(encoding="utf-8")
    assert "SubmitClient" in client
