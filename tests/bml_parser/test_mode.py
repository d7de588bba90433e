"""The parser's tests run against the modules the caller asked for.

``tests/test_compiled.py`` runs this folder again with ``REALIZER_PURE=1``
and ``REALIZER_EXPECT_MODE=pure``; this test fails that run if the compiled
modules were loaded all the same.
"""

from __future__ import annotations

import os

import pytest

from realizer import compiled


def test_the_mode_is_the_one_expected() -> None:
    expected = os.environ.get("REALIZER_EXPECT_MODE")
    if not expected:
        pytest.skip(f"no mode asked for; running {compiled.describe()}")
    assert compiled.mode() == expected, compiled.describe()
