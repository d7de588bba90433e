"""``realizer serve`` as a child process on a free loopback port, for tests.

The real command (parser, session, default face), started with
``sys.executable -m realizer serve --port 0``; the port is read from its
"serving on HOST:PORT" line on stderr. Leaving the ``with`` block sends
SIGTERM and waits, so no server outlives its test.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from tests.service.conftest import UNIT

ROOT = Path(__file__).resolve().parents[2]


@dataclass
class ServeProcess:
    process: subprocess.Popen[str]
    port: int
    stderr: list[str] = field(default_factory=list)

    @property
    def url(self) -> str:
        return f"ws://127.0.0.1:{self.port}"


@contextmanager
def serve_process(*extra: str, env: dict[str, str] | None = None) -> Iterator[ServeProcess]:
    environment = {**os.environ, **(env or {})}
    process = subprocess.Popen(
        [sys.executable, "-m", "realizer", "serve", "--port", "0", *extra],
        cwd=ROOT,
        env=environment,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert process.stderr is not None
    lines: list[str] = []
    found = threading.Event()
    port: list[int] = []

    def read() -> None:  # keeps draining stderr so the server never blocks on it
        assert process.stderr is not None
        for line in process.stderr:
            lines.append(line)
            match = re.search(r"serving on \S+:(\d+)", line)
            if match and not port:
                port.append(int(match.group(1)))
                found.set()
        found.set()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        if not found.wait(60 * UNIT) or not port:
            raise AssertionError("realizer serve did not start:\n" + "".join(lines))
        yield ServeProcess(process, port[0], lines)
    finally:
        if process.poll() is None:
            process.send_signal(signal.SIGTERM)
            try:
                process.wait(30 * UNIT)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        reader.join(10)
        process.stderr.close()
