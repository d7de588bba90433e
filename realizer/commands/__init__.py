"""Sub-commands of the ``realizer`` command line, one module each.

Each module's docstring is also its ``--help`` description; :func:`plain_text`
turns the reStructuredText markup of a docstring into the plain text a
terminal shows.
"""

from __future__ import annotations

import re

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
