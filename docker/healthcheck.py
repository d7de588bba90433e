"""The image's HEALTHCHECK: GET /health on the port the service was started with.

The port is read from the command line of PID 1 (``--port N`` or
``--port=N``), so ``docker run ... realizer serve --port 9000`` stays healthy;
without one it is $REALIZER_PORT (8765). Exit 0 when /health answers 200.
"""

from __future__ import annotations

import os
import sys
import urllib.request


def port(cmdline_path: str = "/proc/1/cmdline") -> str:
    try:
        with open(cmdline_path, "rb") as cmdline:
            words = [w.decode() for w in cmdline.read().split(b"\0") if w]
    except OSError:
        words = []
    for at, word in enumerate(words):
        if word == "--port" and at + 1 < len(words):
            return words[at + 1]
        if word.startswith("--port="):
            return word.partition("=")[2]
    return os.environ.get("REALIZER_PORT", "8765")


def main(cmdline_path: str = "/proc/1/cmdline") -> int:
    try:
        url = f"http://127.0.0.1:{port(cmdline_path)}/health"
        with urllib.request.urlopen(url, timeout=2) as reply:
            return 0 if reply.status == 200 else 1
    except OSError:
        return 1


if __name__ == "__main__":
    sys.exit(main())
