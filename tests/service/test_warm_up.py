"""The service imports the sparse solver's scipy at start, not on the clock's watch."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from realizer.scheduler import solver
from realizer.service.limits import ServiceLimits
from realizer.service.server import RealizerService, ServiceConfig
from realizer.service.stage import Stage
from tests.service.doubles import FakeSession
from tests.service.test_server_shell import ASSETS


def test_warm_up_imports_what_the_sparse_path_needs() -> None:
    code = textwrap.dedent(
        """
        import sys
        from realizer.scheduler import solver
        before = "scipy.sparse.linalg" in sys.modules
        print(before, solver.warm_up(), "scipy.sparse.linalg" in sys.modules)
        """
    )
    run = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    assert run.stdout.split() == ["False", "True", "True"]


def test_a_new_service_warms_the_solver_up_before_its_first_frame(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # Regression: scipy was imported by the first big block on a planner
    # thread, holding the interpreter lock long enough to stall the frame
    # clock (678 ms seen on a cluster worker, which is this same class).
    calls: list[int] = []
    monkeypatch.setattr(solver, "warm_up", lambda: calls.append(1) or True)
    limits = ServiceLimits()
    RealizerService(ServiceConfig(port=0, limits=limits), Stage(FakeSession, limits), ASSETS)
    assert calls == [1]
