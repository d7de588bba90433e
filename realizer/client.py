"""A small Python client of the realizer service: see :mod:`realizer.service.client`.

Re-exported here so users write ``from realizer.client import SubmitClient``;
the implementation stays under :mod:`realizer.service`, the only package that
may import websockets (the core is sans-I/O, see docs/architecture.md).
"""

from __future__ import annotations

from realizer.service.client import ClientError, SubmitClient, ViewClient

__all__ = ["ClientError", "SubmitClient", "ViewClient"]
