"""The JavaScript client (realizer/service/static/realizer-client.js) under Node.

tests/js/client.test.mjs runs with ``node --test`` against two real
``realizer serve`` processes (one open, one with tokens and a limit of one
submitter) and a port where nothing listens. Node gets its WebSocket either
built in (Node 22, or Node 20 with --experimental-websocket) or from the ws
package (Debian's node-ws, which scripts/setup.sh installs); each that exists
here is tested, and the test skips, saying why, when Node is missing.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
from pathlib import Path

import pytest

from tests.service.conftest import UNIT
from tests.service.process import serve_process

ROOT = Path(__file__).resolve().parents[2]
NODE = shutil.which("node") or shutil.which("nodejs")
#: where Debian's node packages (node-ws) live
NODE_PATH = "/usr/share/nodejs"


def _works(*args: str, env: dict[str, str] | None = None) -> bool:
    if NODE is None:
        return False
    done = subprocess.run(
        [NODE, *args], capture_output=True, timeout=60, env={**os.environ, **(env or {})}
    )
    return done.returncode == 0


def websocket_variants() -> dict[str, list[str] | None]:
    """WebSocket source -> node flags to use it (None: not available here)."""
    check = "process.exit(typeof WebSocket === 'function' ? 0 : 1)"
    native: list[str] | None = None
    if _works("-e", check):
        native = []
    elif _works("--experimental-websocket", "-e", check):
        native = ["--experimental-websocket"]
    ws = [] if _works("-e", "require('ws')", env={"NODE_PATH": NODE_PATH}) else None
    return {"native": native, "ws": ws}


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
    return port


@pytest.mark.slow
@pytest.mark.parametrize("websocket", ["native", "ws"])
def test_the_javascript_client_against_a_real_server(websocket: str) -> None:
    if NODE is None:
        pytest.skip("no node here (Debian's nodejs package; scripts/setup.sh installs it)")
    flags = websocket_variants()[websocket]
    if flags is None:
        pytest.skip(f"this node has no {websocket} WebSocket")
    guarded = ("--submit-token", "s3cret", "--view-token", "look", "--limit", "submitters=1")
    # no idle motion: a resting face is unchanged (the `same` messages), and
    # only blocks move it
    with serve_process("--no-idle") as open_server, serve_process(*guarded) as guarded_server:
        env = {
            **os.environ,
            "NODE_PATH": NODE_PATH,
            "REALIZER_URL": open_server.url,
            "REALIZER_GUARDED_URL": guarded_server.url,
            "REALIZER_DEAD_URL": f"ws://127.0.0.1:{free_port()}",
            "REALIZER_JS_WEBSOCKET": websocket,
            "REALIZER_TEST_TIME_UNIT": str(UNIT),
        }
        done = subprocess.run(
            [NODE, *flags, "--test", "tests/js/client.test.mjs"],
            cwd=ROOT,
            env=env,
            capture_output=True,
            text=True,
            timeout=300,
        )
    assert done.returncode == 0, done.stdout[-6000:] + done.stderr[-3000:]
    assert "# fail 0" in done.stdout and "# pass 6" in done.stdout, done.stdout[-3000:]
