"""Every ``--help`` is plain text: no reStructuredText markup from the docstrings."""

from __future__ import annotations

import argparse
import re

import pytest

from realizer.cli import COMMANDS, build_parser
from realizer.commands import plain_text

MARKUP = re.compile(r"`|:(?:mod|class|func|meth|data|attr|exc|obj):")


def helps() -> dict[str, str]:
    parser = build_parser()
    texts = {"realizer": parser.format_help()}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                texts[name] = sub.format_help()
    return texts


def test_every_command_has_a_help() -> None:
    assert len(helps()) == len(COMMANDS) + 1


@pytest.mark.parametrize("command", sorted(helps()))
def test_the_help_shows_no_markup(command: str) -> None:
    text = helps()[command]
    found = [line for line in text.splitlines() if MARKUP.search(line)]
    assert not found, f"realizer {command} --help shows markup:\n" + "\n".join(found)


def test_plain_text_keeps_the_words_and_drops_the_markup() -> None:
    doc = "Run ``realizer parse`` (see :mod:`realizer.bml_parser` and :class:`~a.B`)::"
    assert plain_text(doc + "\n") == "Run realizer parse (see realizer.bml_parser and a.B):\n"
