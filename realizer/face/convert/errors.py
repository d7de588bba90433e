"""Errors of the face converters.

::

    RealizerError
     └── ConversionError        a request a converter cannot answer (unknown AU,
          │                     lexeme, emotion word, profile, viseme ...)
          └── DataFileError     a malformed data file; carries source and line
"""

from __future__ import annotations

from realizer.errors import RealizerError


class ConversionError(RealizerError):
    """A converter was asked for something its data does not define."""


class DataFileError(ConversionError):
    """A converter data file could not be read; ``source`` and ``line`` say where."""

    def __init__(self, message: str, *, source: str = "<text>", line: int = 0) -> None:
        self.source = source
        self.line = line
        where = f"{source}:{line}: " if line else f"{source}: "
        super().__init__(where + message)
