"""The README's one test command also runs the linters, the formatter and mypy.

``ruff check``, ``ruff format --check`` (rules and line length from
pyproject.toml) over the code, tests, benchmarks and scripts, and ``mypy``
with the strict settings of pyproject.toml over the package. A failure prints
what the tool said; fix it with ``ruff check --fix``, ``ruff format`` or by
typing the code.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CODE = ["realizer", "tests", "benchmarks", "scripts", "docker"]


def tool(module: str, *args: str) -> subprocess.CompletedProcess[str]:
    if importlib.util.find_spec(module) is None:
        pytest.skip(f"{module} is not installed (it comes with the dev extra)")
    return subprocess.run(
        [sys.executable, "-m", module, *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )


def test_ruff_finds_nothing() -> None:
    done = tool("ruff", "check", "--no-cache", *CODE)
    assert done.returncode == 0, done.stdout + done.stderr


def test_the_code_is_formatted() -> None:
    done = tool("ruff", "format", "--check", "--no-cache", *CODE)
    assert done.returncode == 0, done.stdout + done.stderr


def test_mypy_strict_passes_on_the_package() -> None:
    done = tool("mypy", "--strict", "realizer")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "Success" in done.stdout
