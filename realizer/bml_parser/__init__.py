"""BML text to an immutable, lossless BML tree, and back.

::

    from realizer.bml_parser import parse_bml, serialise

    result = parse_bml(text)          # ParseResult(block, warnings, dropped)
    for behaviour in result.block.behaviours:
        print(behaviour.id, behaviour.type, behaviour.syncs)
    assert canonical(serialise(result.block)) == canonical(text)

BML 1.0 core (namespace ``http://www.bml-initiative.org/bml/bml-1.0``), core
extensions, the older draft dialect (Paul 2010) and this project's face
extensions (``urn:realizer:bml:face-1.0``, see ``protocols/bml-extensions.md``).
"""

from __future__ import annotations

from realizer.bml_parser.errors import (
    BmlError,
    BmlSecurityError,
    BmlSyntaxError,
    BmlWarning,
    SyncRefError,
    WarningType,
)
from realizer.bml_parser.groups import ConstraintGroup, GroupMember, constraint_groups
from realizer.bml_parser.nodes import Comment, Node, ProcessingInstruction, XmlElement
from realizer.bml_parser.reader import DEFAULT_LIMITS, Limits, ParseResult, parse_bml
from realizer.bml_parser.syncref import SyncRef, parse_sync_ref
from realizer.bml_parser.tree import (
    Behaviour,
    Block,
    Constraint,
    Description,
    Relation,
    Required,
    SpeechText,
    TextSync,
)
from realizer.bml_parser.vocabulary import BML_NS, BMLA_NS, DRAFT_NS, EXT_NS, REALIZER_NS
from realizer.bml_parser.writer import canonical, serialise

__all__ = [
    "BMLA_NS",
    "BML_NS",
    "DEFAULT_LIMITS",
    "DRAFT_NS",
    "EXT_NS",
    "REALIZER_NS",
    "Behaviour",
    "Block",
    "BmlError",
    "BmlSecurityError",
    "BmlSyntaxError",
    "BmlWarning",
    "Comment",
    "Constraint",
    "ConstraintGroup",
    "Description",
    "GroupMember",
    "Limits",
    "Node",
    "ParseResult",
    "ProcessingInstruction",
    "Relation",
    "Required",
    "SpeechText",
    "SyncRef",
    "SyncRefError",
    "TextSync",
    "WarningType",
    "XmlElement",
    "canonical",
    "constraint_groups",
    "parse_bml",
    "parse_sync_ref",
    "serialise",
]
