"""``realizer --help`` starts fast: it imports no command module and no heavy library."""

from __future__ import annotations

import argparse
import subprocess
import sys

from realizer import cli

#: Libraries that cost milliseconds to import and that no ``--help`` needs.
HEAVY = ("numpy", "scipy", "lxml", "msgpack", "websockets", "OpenGL", "pyrender", "trimesh",
         "matplotlib", "PIL", "psutil", "av", "imageio")  # fmt: skip

PROBE = """
import sys
from realizer.cli import main
try:
    main(sys.argv[1:])
except SystemExit:
    pass
sys.stdout.flush()
print("\\n".join(sorted(sys.modules)), file=sys.stderr)
"""


def imported_by(*argv: str) -> set[str]:
    done = subprocess.run(
        [sys.executable, "-c", PROBE, *argv], capture_output=True, text=True, timeout=60
    )
    assert "usage: realizer" in done.stdout, done.stdout + done.stderr
    return set(done.stderr.split())


def test_help_imports_no_heavy_library_and_no_command_module() -> None:
    modules = imported_by("--help")
    heavy = sorted(m for m in modules if m.split(".")[0] in HEAVY)
    assert heavy == []
    assert sorted(m for m in modules if m.startswith("realizer.commands.")) == []


def test_a_command_help_imports_only_that_command() -> None:
    modules = imported_by("schedule", "--help")
    commands = sorted(m for m in modules if m.startswith("realizer.commands."))
    assert commands == ["realizer.commands.schedule"]
    assert not [m for m in modules if m.split(".")[0] in HEAVY]


def test_every_summary_is_the_help_its_command_registers() -> None:
    parser = cli.build_parser()  # every module imported
    (subparsers,) = (a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    registered = {action.dest: action.help for action in subparsers._choices_actions}
    assert registered == cli.SUMMARIES
    assert sorted(registered) == sorted(name.replace("_", "-") for name in cli.COMMANDS)


def test_the_listing_without_imports_equals_the_full_one() -> None:
    assert cli.build_parser(["--help"]).format_help() == cli.build_parser().format_help()
