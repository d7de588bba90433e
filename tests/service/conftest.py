"""Shared fixtures of the service tests.

Every wait in these tests is a multiple of :data:`UNIT` seconds, which the
environment variable ``REALIZER_TEST_TIME_UNIT`` scales (e.g. 3 on a slow
or loaded machine), as websockets' own tests do.
"""

from __future__ import annotations

import os

UNIT = float(os.environ.get("REALIZER_TEST_TIME_UNIT", "1.0"))
