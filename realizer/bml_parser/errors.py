"""Errors and warnings of the BML parser.

::

    RealizerError                      (realizer.errors)
     └── BmlError                      bad BML; carries line, column, warning_type
          ├── BmlSyntaxError           not well-formed XML, or not a BML block
          ├── BmlSecurityError         DTDs, entities, oversized documents
          └── SyncRefError             a malformed sync reference

A :class:`BmlError` rejects the whole block. Problems the BML 1.0 standard
says to survive (an unknown behaviour in a foreign namespace, a behaviour with
an impossible timing) are :class:`BmlWarning` values on the parse result
instead, and the rest of the block stays usable.

The warning types are those of BML 1.0 ``<warningFeedback type="...">``.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from realizer.errors import RealizerError


class WarningType(StrEnum):
    """The warning types of BML 1.0 ``warningFeedback``."""

    PARSING_FAILURE = "PARSING_FAILURE"
    NO_SUCH_TARGET = "NO_SUCH_TARGET"
    IMPOSSIBLE_TO_SCHEDULE = "IMPOSSIBLE_TO_SCHEDULE"
    BEHAVIOR_TYPE_NOT_SUPPORTED = "BEHAVIOR_TYPE_NOT_SUPPORTED"
    CUSTOM_BEHAVIOUR_NOT_SUPPORTED = "CUSTOM_BEHAVIOUR_NOT_SUPPORTED"
    CUSTOM_ATTRIBUTE_NOT_SUPPORTED = "CUSTOM_ATTRIBUTE_NOT_SUPPORTED"
    CANNOT_CREATE_BEHAVIOR = "CANNOT_CREATE_BEHAVIOR"


class BmlError(RealizerError):
    """A BML document the realizer cannot accept.

    ``line`` and ``column`` are 1-based positions in the source (0 when
    unknown); ``warning_type`` is what the realizer puts in the
    ``warningFeedback`` it answers with.
    """

    def __init__(
        self,
        message: str,
        *,
        line: int = 0,
        column: int = 0,
        source: str = "<bml>",
        warning_type: WarningType = WarningType.PARSING_FAILURE,
    ) -> None:
        super().__init__(message)
        self.message = message
        self.line = line
        self.column = column
        self.source = source
        self.warning_type = warning_type

    def __str__(self) -> str:
        return f"{self.source}:{self.line}:{self.column}: error: {self.message}"


class BmlSyntaxError(BmlError):
    """Not well-formed XML, or well-formed XML that is not a BML block."""


class BmlSecurityError(BmlError):
    """A document refused for safety: a DTD, an entity declaration, too large."""


class SyncRefError(BmlError):
    """A sync reference that does not follow ``[block:]behaviour:sync[:iteration][+|-offset]``."""


@dataclass(frozen=True, slots=True)
class BmlWarning:
    """Something wrong with part of a block that the rest of the block survives."""

    type: WarningType
    message: str
    id: str = ""  # "block:behaviour" or "block" that the warning is about
    line: int = 0
    column: int = 0

    def __str__(self) -> str:
        return f"{self.line}:{self.column}: warning: {self.type}: {self.message}"
