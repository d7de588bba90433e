"""What a parse gives and what bounds it: :class:`ParseResult` and :class:`Limits`.

Plain Python classes, apart from the reader (:mod:`realizer.bml_parser.reader`),
which may run compiled (:mod:`realizer.compiled`): the service's planner
processes pickle parse results, and pickling, ``dataclasses.replace`` and
the slot-by-slot builder (:func:`realizer.bml_parser.nodes.builder`) need
ordinary classes. The reader re-exports both names.
"""

from __future__ import annotations

from dataclasses import dataclass

from realizer.bml_parser.errors import BmlWarning
from realizer.bml_parser.syncref import MAX_ITERATION
from realizer.bml_parser.tree import Block


@dataclass(frozen=True, slots=True)
class Limits:
    """Named limits on one BML document; over one, the block is refused.

    ``max_bytes``: the document's size in bytes. ``max_behaviours``:
    behaviours in the block. ``max_depth``: element nesting.
    ``max_attributes``: attributes on one element. ``max_sync_refs``: sync
    references inside one behaviour's text or one constraint relation.
    ``max_repetition``: strokes of one repeated behaviour (``repetition``,
    the draft's ``repeats``). ``max_number``: the magnitude of a numeric
    attribute (times and offsets have their own bound,
    :data:`~realizer.bml_parser.syncref.MAX_SECONDS`). ``max_warnings``:
    distinct warnings reported for one block; warnings of one type about one
    target are one warning that counts them, and what is over this limit is
    counted in a last warning. ``max_speech_chars``: characters of text in
    one speech behaviour (what the speech synthesiser is given).
    """

    max_bytes: int = 4 * 1024 * 1024
    max_behaviours: int = 20_000
    max_depth: int = 64
    max_attributes: int = 128
    max_sync_refs: int = 1024
    max_repetition: int = MAX_ITERATION
    max_number: float = 1e6
    max_warnings: int = 64
    max_speech_chars: int = 10_000


DEFAULT_LIMITS = Limits()


@dataclass(frozen=True, slots=True)
class ParseResult:
    """A parsed block with what the parser had to say about it.

    ``dropped`` names behaviours that stay in the tree (so the document
    serialises back) but that the realizer must not run, each with a warning
    saying why (an impossible timing, as the BML 1.0 standard asks).
    """

    block: Block
    warnings: tuple[BmlWarning, ...] = ()
    dropped: frozenset[str] = frozenset()
