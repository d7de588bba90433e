"""``realizer send FILE.bml``: send one BML block to a running service.

Prints each feedback message (BML feedback XML, one per line) as it
arrives, and exits when the block has ended: 0 when it ran to its end, 1
when it was refused or interrupted (the warning says why), 2 when the
service could not be reached.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from realizer.commands import error_line, plain_text


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "send",
        help="send a BML file to a running service and print its feedback",
        description=plain_text(__doc__.split("\n\n")[1]) if __doc__ else None,
    )
    parser.add_argument("file", type=Path, metavar="FILE.bml")
    parser.add_argument("--host", default="127.0.0.1", help="service host (default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=8765, help="service port (default 8765)")
    parser.add_argument("--character", default=None, help="character (default: the block's)")
    parser.add_argument("--token", default=None, help="submit token, if the service needs one")
    parser.add_argument(
        "--timeout", type=float, default=None, help="give up after this many quiet seconds"
    )
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from realizer.bml_parser import BmlError, parse_bml
    from realizer.client import SubmitClient

    try:
        text = args.file.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        print(error_line("send", exc, args.file), file=sys.stderr)
        return 2
    try:
        block_id: str | None = parse_bml(text).block.id
    except BmlError:
        block_id = None  # the service answers with the warning; take its id from there

    def show(message: dict[str, Any]) -> None:
        if message.get("type") == "feedback":
            print(" ".join(str(message["xml"]).split()), flush=True)

    host = f"[{args.host}]" if ":" in args.host else args.host
    try:
        with SubmitClient(
            f"ws://{host}:{args.port}", character=args.character, token=args.token
        ) as client:
            state = client.run_block(
                text,
                block_id=block_id,
                character=args.character,
                on_message=show,
                timeout=args.timeout,
            )
    except TimeoutError:
        print(f"realizer send: no message for {args.timeout} s", file=sys.stderr)
        return 1
    except BrokenPipeError:  # the reader of our output went away (`| head`)
        raise
    except Exception as exc:  # connection refused, handshake refused, closed
        print(f"realizer send: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 2
    return 0 if state == "done" else 1
