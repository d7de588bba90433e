"""``realizer record``: connect to a running service as a viewer and write what it receives.

Records ``--seconds`` of one character's viewer stream in ``--format`` (fap,
coded, arkit, int16, float32) to ``-o FILE``: ``.fap`` writes the decoded
FAP frames (from ``fap`` or ``coded``), ``.csv`` the ARKit weights (from
``arkit``), ``.jsonl`` one line per message with its type, frame number,
time and size in bytes. Prints the bytes per second received.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from realizer.commands import plain_text

FORMATS = ("fap", "coded", "arkit", "int16", "float32")


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "record",
        help="record a character's viewer stream to .fap, .csv or .jsonl",
        description=plain_text(__doc__.split("\n\n")[1]) if __doc__ else None,
    )
    parser.add_argument("--host", default="127.0.0.1", help="service host (default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=8765, help="service port (default 8765)")
    parser.add_argument("--character", default=None, help="character (default: the server's)")
    parser.add_argument("--format", choices=FORMATS, default="fap", help="viewer format (fap)")
    parser.add_argument("--seconds", type=float, default=10.0, help="how long to record (10)")
    parser.add_argument("--token", default=None, help="view token, if the service needs one")
    parser.add_argument("-o", "--output", type=Path, required=True, help=".fap, .csv or .jsonl")
    parser.set_defaults(run=run)


def _options(fmt: str) -> dict[str, Any]:
    if fmt == "coded":
        return {"fap": False, "coded": True}
    if fmt == "arkit":
        return {"fap": False, "arkit": True}
    if fmt in ("int16", "float32"):
        return {"fap": False, "vertices": fmt}
    return {"fap": True}


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from realizer.client import ViewClient
    from realizer.service.client import ClientError

    suffix = args.output.suffix.lower()
    if suffix not in (".fap", ".csv", ".jsonl"):
        print("realizer record: error: -o must end in .fap, .csv or .jsonl", file=sys.stderr)
        return 2
    if suffix == ".fap" and args.format not in ("fap", "coded"):
        print("realizer record: error: .fap needs --format fap or coded", file=sys.stderr)
        return 2
    if suffix == ".csv" and args.format != "arkit":
        print("realizer record: error: .csv needs --format arkit", file=sys.stderr)
        return 2
    if not args.seconds > 0:
        print("realizer record: error: --seconds must be positive", file=sys.stderr)
        return 2
    url = f"ws://{args.host}:{args.port}"
    lines: list[str] = []
    rows: list[tuple[float, Any]] = []
    frames: list[tuple[Any, Any]] = []
    fps = 0.0
    received = 0
    try:
        with ViewClient(
            url, character=args.character, token=args.token, **_options(args.format)
        ) as view:
            fps = float(view.mesh["fps"])
            began = time.monotonic()
            message: dict[str, Any] = view.mesh
            size = 0
            while True:
                left = args.seconds - (time.monotonic() - began)
                if left <= 0:
                    break
                try:
                    data = view.connection.recv(left)
                except TimeoutError:
                    break
                size = len(data)
                received += size
                message = view.decode(data)
                kind = message.get("type")
                lines.append(
                    json.dumps(
                        {"type": kind, "n": message.get("n"), "t": message.get("t"), "bytes": size}
                    )
                )
                if kind == "same":  # frame n shows what the last frame showed
                    if suffix == ".fap" and frames:
                        frames.append(frames[-1])
                    elif suffix == ".csv" and rows:
                        rows.append((rows[-1][0] + 1.0 / fps, rows[-1][1]))
                    continue
                if kind != "frame":
                    continue
                if suffix == ".fap":
                    faps = view.decoded_faps(message)
                    if faps is None:
                        continue  # a coded stream before its first intra frame
                    values, mask = np.zeros(68), np.zeros(68, dtype=bool)
                    for number, value in faps.items():
                        values[number - 1], mask[number - 1] = value, True
                    frames.append((values, mask))
                elif suffix == ".csv":
                    arkit = view.arkit(message)
                    if arkit is not None:
                        rows.append((float(message["t"]), arkit))
            elapsed = time.monotonic() - began
    except (OSError, ClientError) as error:
        print(f"realizer record: error: {url}: {error}", file=sys.stderr)
        return 1
    if suffix == ".jsonl":
        args.output.write_text("\n".join(lines) + "\n", encoding="utf-8")
    elif suffix == ".fap":
        from realizer.face.fapfile import fap_file_from_frames, write_fap_file

        write_fap_file(args.output, fap_file_from_frames(args.output.stem, fps, frames))
    else:
        from realizer.face.arkit import ARKIT_NAMES, POSE_FIELDS

        header = ["time", *ARKIT_NAMES, *(name for name, _ in POSE_FIELDS)]
        out = [",".join(header)]
        for t, arkit in rows:
            cells = [f"{t:.4f}", *(f"{w:.4f}" for w in arkit.weights)]
            out.append(",".join(cells + [f"{a:.5f}" for a in arkit.pose]))
        args.output.write_text("\n".join(out) + "\n", encoding="utf-8")
    rate = received / elapsed if elapsed > 0 else 0.0
    print(
        f"{args.output}: {len(lines)} messages, {received} bytes in {elapsed:.1f} s: "
        f"{rate:.0f} bytes/s ({rate * 8 / 1000:.2f} kbit/s)"
    )
    return 0
