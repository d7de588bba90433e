"""Sub-commands of the ``realizer`` command line, one module each.

Each module's docstring is also its ``--help`` description; :func:`plain_text`
turns the reStructuredText markup of a docstring into the plain text a
terminal shows.
"""

from __future__ import annotations

import argparse
import os
import re
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from realizer.face.model import Face

_ROLE = re.compile(r":(?:mod|class|func|meth|data|attr|exc|obj):`~?([^`<]+?)`")
_LITERAL = re.compile(r"``([^`]+?)``")


def plain_text(docstring: str) -> str:
    """``docstring`` without reStructuredText markup: ``x`` and :role:`x` read x.

    Linear in the text's length (no backtracking: each pattern stops at the
    first backquote).
    """
    text = _ROLE.sub(r"\1", docstring)
    text = _LITERAL.sub(r"\1", text)
    return text.replace("::\n", ":\n")


def error_line(command: str, error: BaseException, path: object = None) -> str:
    """How every command reports an error on stderr.

    A missing file reads ``PATH: error: no such file``; a message that
    already names its place (``path:line:col: error: ...`` from a parser,
    ``path: error: ...``) is kept as it is; anything else reads ``realizer
    COMMAND: error: MESSAGE``.
    """
    if isinstance(error, FileNotFoundError):
        return f"{error.filename or path}: error: no such file"
    if isinstance(error, IsADirectoryError):
        return f"{error.filename or path}: error: is a folder, not a file"
    if isinstance(error, OSError) and error.filename is not None:
        return f"{error.filename}: error: {error.strerror or error}"
    message = str(error)
    head = message.partition(" ")[0]
    if head.endswith(":") and ": error: " in message:
        return message
    if path is not None:
        return f"{path}: error: {message}"
    return f"realizer {command}: error: {message}"


def load_face_option(path: str | None) -> Face:
    """The face a ``--face`` option names (STEM, STEM.npz or STEM.xml), or the
    built-in default face when it names none. Imports the face package only
    when called, so ``--help`` stays light."""
    if path:
        from realizer.face.paramfile import load_face

        return load_face(path)
    from realizer.face.default import load_default_face

    return load_default_face()


def add_idle_options(parser: argparse.ArgumentParser) -> None:
    """``--idle/--no-idle`` and ``--seed``: the idle motion of the faces a
    command drives (on unless ``REALIZER_IDLE=0``)."""
    parser.add_argument(
        "--idle",
        action=argparse.BooleanOptionalAction,
        default=os.environ.get("REALIZER_IDLE", "1") != "0",
        help="keep faces alive: blinks, saccades, breathing, head motion "
        "(default on; REALIZER_IDLE=0 turns it off)",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the idle motion (0)")
