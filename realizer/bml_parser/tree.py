"""The immutable BML tree: a block, its behaviours and its constraints.

Each typed node is an :class:`~realizer.bml_parser.nodes.XmlElement` (so it
serialises back exactly as written) with the parsed meaning added:

* :class:`Block`: ``<bml id characterId composition>``; ``behaviours`` lists
  every behaviour the realizer understands, in document order, including
  those inside ``<required>`` (``behaviour.required``);
* :class:`Behaviour`: ``type`` (``faceLexeme``, ``head``, ``speech``, ...,
  the same for every dialect), ``syncs`` (its sync points in canonical
  order), ``sync_refs`` (the sync attributes, parsed), ``params`` (the
  attributes the realizer understands, under their BML 1.0 names);
* :class:`Constraint` with :class:`Relation` children (``<synchronize>``,
  ``<before>``, ``<after>``);
* speech: :class:`SpeechText` with its runs of text and :class:`TextSync`
  markers; :class:`Description` for ``<description>`` alternatives.

Build trees with :func:`realizer.bml_parser.parse_bml`; the reader is the one
place that derives the parsed fields from the XML, so they always agree.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

from realizer.bml_parser.nodes import Comment, ProcessingInstruction, XmlElement

# the fields these classes inherit from XmlElement are annotated with Node:
# tools that resolve annotations (pdoc, typing.get_type_hints) look for it here
from realizer.bml_parser.nodes import Node as Node
from realizer.bml_parser.syncref import SyncRef


@dataclass(frozen=True, slots=True)
class TextSync(XmlElement):
    """A ``<sync id="..."/>`` marker inside a speech ``<text>``."""

    id: str = ""
    ref: SyncRef | None = None


@dataclass(frozen=True, slots=True)
class SpeechText(XmlElement):
    """A speech behaviour's ``<text>``: runs of words and sync markers."""

    runs: tuple[str | TextSync, ...] = ()

    @property
    def plain(self) -> str:
        """The words alone, markers removed."""
        return "".join(run for run in self.runs if isinstance(run, str))

    @property
    def sync_ids(self) -> tuple[str, ...]:
        return tuple(run.id for run in self.runs if isinstance(run, TextSync))


@dataclass(frozen=True, slots=True)
class Description(XmlElement):
    """A ``<description priority type>``: an alternative, richer form of a behaviour."""

    priority: int = 0
    type: str = ""


@dataclass(frozen=True, slots=True)
class Behaviour(XmlElement):
    """One behaviour of a block.

    ``syncs`` are the sync point names in canonical order (``stroke:2`` for a
    head's second repetition; a speech's marker ids between start and end).
    ``sync_refs`` pairs each sync attribute (BML 1.0 name) with its parsed
    reference. ``params`` are the understood attributes under BML 1.0 names
    (the draft's ``<face type="FACS">`` gives ``au``/``side``/``amount`` of a
    ``faceFacs``); the raw attributes stay in ``attributes``.
    """

    id: str = ""
    type: str = ""
    dialect: str = "bml"
    syncs: tuple[str, ...] = ()
    sync_refs: tuple[tuple[str, SyncRef], ...] = ()
    params: tuple[tuple[str, str], ...] = ()
    required: bool = False
    speech: SpeechText | None = None
    descriptions: tuple[Description, ...] = ()

    def param(self, name: str, default: str | None = None) -> str | None:
        for key, value in self.params:
            if key == name:
                return value
        return default

    def number(self, name: str, default: float) -> float:
        """A numeric parameter (validated by the parser), or ``default``."""
        value = self.param(name)
        return default if value is None else float(value)

    @property
    def lexeme(self) -> str | None:
        return self.param("lexeme")


@dataclass(frozen=True, slots=True)
class Relation(XmlElement):
    """``<synchronize>``, ``<before>`` or ``<after>`` inside a constraint.

    ``kind`` is the element name. For ``before``/``after``, every sync in
    ``syncs`` lies before/after ``ref``; ``synchronize`` makes all of them
    (and ``ref``, if given) coincide.
    """

    kind: str = "synchronize"
    ref: SyncRef | None = None
    syncs: tuple[SyncRef, ...] = ()


@dataclass(frozen=True, slots=True)
class Constraint(XmlElement):
    """A ``<constraint>``; ``required`` when inside ``<required>``."""

    id: str = ""
    required: bool = False
    relations: tuple[Relation, ...] = ()


@dataclass(frozen=True, slots=True)
class Required(XmlElement):
    """A ``<required>`` group; its members are also listed on the block."""


@dataclass(frozen=True, slots=True)
class BlockControl:
    """AsapRealizer's BMLA attributes of a ``<bml>`` block (namespace
    ``http://www.asap-project.org/bmla``; protocols/bml-extensions.md).

    Each list holds block ids, as written (comma-separated) in the attribute
    of the same name: ``interrupt`` the blocks this one interrupts when it
    arrives, ``on_start`` the preplanned blocks it activates when it starts,
    ``append_after`` / ``chunk_after`` the blocks it starts after,
    ``prepend_before`` the not yet started blocks that wait for its end;
    ``preplan``: planned now, started only when activated.
    """

    interrupt: tuple[str, ...] = ()
    on_start: tuple[str, ...] = ()
    append_after: tuple[str, ...] = ()
    chunk_after: tuple[str, ...] = ()
    prepend_before: tuple[str, ...] = ()
    preplan: bool = False

    @property
    def after(self) -> tuple[str, ...]:
        """The blocks this one starts after (appendAfter and chunkAfter)."""
        return self.append_after + self.chunk_after


NO_CONTROL = BlockControl()


@dataclass(frozen=True, slots=True)
class Block(XmlElement):
    """A ``<bml>`` block.

    ``composition`` is ``MERGE`` (the default), ``APPEND`` or ``REPLACE``.
    ``prolog``/``epilog`` are the comments and processing instructions before
    and after the root element.

    ``source`` is the document as the parser read it (its XML declaration
    left out), or ``""``: the writer gives it back as it is instead of
    writing the tree again. It is not an argument of the constructor, so a
    block built by hand, or changed with :func:`dataclasses.replace` (the
    only way to change an immutable tree: any change below makes a new
    block), has none and is written from its fields.
    """

    id: str = ""
    character_id: str | None = None
    composition: str = "MERGE"
    dialect: str = "bml"
    behaviours: tuple[Behaviour, ...] = ()
    constraints: tuple[Constraint, ...] = ()
    prolog: tuple[Comment | ProcessingInstruction, ...] = ()
    epilog: tuple[Comment | ProcessingInstruction, ...] = ()
    control: BlockControl = NO_CONTROL
    source: str = field(default="", init=False, repr=False, compare=False)

    def behaviour(self, behaviour_id: str) -> Behaviour | None:
        for behaviour in self.behaviours:
            if behaviour.id == behaviour_id:
                return behaviour
        return None

    def all_sync_refs(self) -> Iterator[tuple[Behaviour | Constraint, SyncRef]]:
        """Every sync reference in the block with the node that holds it."""
        for behaviour in self.behaviours:
            for _, ref in behaviour.sync_refs:
                yield behaviour, ref
            if behaviour.speech is not None:
                for run in behaviour.speech.runs:
                    if isinstance(run, TextSync) and run.ref is not None:
                        yield behaviour, run.ref
        for constraint in self.constraints:
            for relation in constraint.relations:
                if relation.ref is not None:
                    yield constraint, relation.ref
                for ref in relation.syncs:
                    yield constraint, ref
