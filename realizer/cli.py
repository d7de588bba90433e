"""The ``realizer`` command.

Each sub-command lives in its own module under :mod:`realizer.commands` and
exposes ``register(subparsers)``; the module imports its heavy dependencies
only inside its run function, so ``realizer parse`` never loads OpenGL.
To add a command, write the module and add its name to :data:`COMMANDS`.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from realizer import __version__

#: Modules of :mod:`realizer.commands`, in the order ``--help`` lists them.
COMMANDS: tuple[str, ...] = (
    "parse",
    "schedule",
    "plot",
    "render",
    "serve",
    "send",
    "face",
    "fap_sheet",
    "facs",
    "emotion",
    "faps",
    "plot_faps",
    "bench",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="realizer",
        description="A real-time BML 1.0 realizer with MPEG-4 facial animation.",
    )
    parser.add_argument("--version", action="version", version=f"realizer {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        module = importlib.import_module(f"realizer.commands.{name}")
        module.register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the process exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    try:
        status: int = args.run(args)
    except BrokenPipeError:  # e.g. `realizer parse ... | head`
        return 0
    except KeyboardInterrupt:
        return 130
    return status


if __name__ == "__main__":
    sys.exit(main())
