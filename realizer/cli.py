"""The ``realizer`` command.

Each sub-command lives in its own module under :mod:`realizer.commands` and
exposes ``register(subparsers)``; the module imports its heavy dependencies
only inside its run function, so ``realizer parse`` never loads OpenGL.
To add a command, write the module, add its name to :data:`COMMANDS` and its
one-line help to :data:`SUMMARIES`.

Start-up: only the module of the command being run is imported. Every other
command is listed by ``--help`` from :data:`SUMMARIES` without importing its
module, so ``realizer --help`` imports no command module at all and costs
little more than the interpreter's start (``realizer bench startup``; a test
pins that it imports no numpy, scipy or lxml).
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence
from typing import Any

from realizer import __version__
from realizer.errors import RealizerError

#: Modules of :mod:`realizer.commands`, in the order ``--help`` lists them.
COMMANDS: tuple[str, ...] = (
    "parse",
    "schedule",
    "plot",
    "render",
    "say",
    "serve",
    "worker",
    "gateway",
    "send",
    "record",
    "face",
    "fap_sheet",
    "fap_audit",
    "expressions",
    "facs",
    "emotion",
    "faps",
    "plot_faps",
    "bench",
)

#: The ``help`` each command's ``register`` gives, by command name (a module's
#: name with ``-`` for ``_``): ``--help`` lists a command from here without
#: importing its module. A command missing here is imported to be listed
#: (correct, only slower); a test checks each entry against its module.
SUMMARIES: dict[str, str] = {
    "parse": "parse BML files and print their behaviours",
    "schedule": "solve BML blocks and print every sync point's time",
    "plot": "draw a scheduled BML block as a Gantt chart",
    "render": "render a BML block offscreen to a video or PNG files",
    "say": "speak a text with the TTS to a WAV and print its phonemes and times",
    "serve": "run the real-time BML service (WebSocket + browser viewer)",
    "worker": "run characters for a cluster of workers and gateways over NATS",
    "gateway": "serve the realizer's endpoints for a cluster of workers over NATS",
    "send": "send a BML file to a running service and print its feedback",
    "record": "record a character's viewer stream to .fap, .csv or .jsonl",
    "face": "render one FAP pose of a face to a PNG",
    "fap-sheet": "render every FAP 3..68 of a face on one contact sheet (PNG)",
    "fap-audit": "check every FAP displacement of a face: folds, direction, side, size",
    "expressions": "render emotions, FAP 2 expressions, visemes and AUs on one sheet (PNG)",
    "facs": "print the FAP values of FACS Action Units",
    "emotion": "print the FAP profile of an emotion",
    "faps": "write a BML block's FAP stream to a .fap file",
    "plot-faps": "plot a BML block's FAP curves with its sync points",
    "bench": "run benchmarks and print figures and ratios",
}


def _chosen(argv: Sequence[str]) -> str | None:
    """The command named on the command line: the first word that is not an option
    (the top-level options, ``--help`` and ``--version``, take no value)."""
    for word in argv:
        if word == "--":
            return None
        if not word.startswith("-"):
            return word
    return None


class _Version(argparse.Action):
    """``--version``: the version and whether the hot modules run compiled
    (:mod:`realizer.compiled`), worked out only when asked (it imports them)."""

    def __init__(self, option_strings: Sequence[str], dest: str, **kwargs: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser: argparse.ArgumentParser, *args: object) -> None:
        from realizer import compiled

        print(f"realizer {__version__}, {compiled.describe()}")
        parser.exit()


def build_parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """The whole command line; given the ``argv`` it will parse, only the module of
    the command in it is imported (``None``: every command's module)."""
    chosen = None if argv is None else _chosen(argv)
    parser = argparse.ArgumentParser(
        prog="realizer",
        description="A real-time BML 1.0 realizer with MPEG-4 facial animation.",
    )
    parser.add_argument(
        "--version", action=_Version, help="print the version, compiled or pure Python, and exit"
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        command = name.replace("_", "-")
        summary = SUMMARIES.get(command)
        if argv is None or command == chosen or summary is None:
            module = importlib.import_module(f"realizer.commands.{name}")
            module.register(subparsers)
        else:
            subparsers.add_parser(command, help=summary)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the process exit status."""
    words = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser(words)
    args = parser.parse_args(words)
    if args.command is None:
        parser.print_help()
        return 2
    try:
        status: int = args.run(args)
    except BrokenPipeError:  # e.g. `realizer parse ... | head`
        return 0
    except KeyboardInterrupt:
        return 130
    except ImportError as exc:
        # an optional dependency is missing: name the extra that brings it
        from realizer.extras import explain

        command = args.command.replace("_", "-")
        missing = explain(exc, f"realizer {command}", command)
        if missing is None:
            raise
        print(f"realizer: error: {missing}", file=sys.stderr)
        return 2
    except (OSError, RealizerError) as exc:
        # input the command did not catch itself: one line, never a traceback
        from realizer.commands import error_line

        print(error_line(args.command.replace("_", "-"), exc), file=sys.stderr)
        return 2
    return status


if __name__ == "__main__":
    sys.exit(main())
