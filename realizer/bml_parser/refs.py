"""The parsed sync reference, :class:`SyncRef`; :mod:`realizer.bml_parser.syncref` parses them.

A plain Python class apart from the parsing functions, which may run
compiled (:mod:`realizer.compiled`): references are pickled with parse
results and built slot by slot (:func:`realizer.bml_parser.nodes.builder`),
which need an ordinary class. ``syncref`` re-exports it.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True, slots=True)
class SyncRef:
    """A parsed sync reference; ``raw`` is the text as written.

    Exactly one of two shapes:

    * a time: ``behaviour is None`` and ``offset`` is seconds from the block start;
    * a sync point: ``behaviour`` and ``sync`` set (``block`` when it names
      another block, ``iteration`` for ``stroke:N``), ``offset`` in seconds.

    ``bml:start`` is the sync point ``("bml", "start")`` of the current block.
    """

    raw: str = field(compare=False)
    behaviour: str | None
    sync: str | None
    block: str | None = None
    iteration: int | None = None
    offset: float = 0.0

    @property
    def is_time(self) -> bool:
        """True for a bare number: a time relative to the block start."""
        return self.behaviour is None

    @property
    def sync_name(self) -> str:
        """The sync point's name as the behaviour lists it (``stroke:2`` for iterations)."""
        assert self.sync is not None
        return self.sync if self.iteration is None else f"{self.sync}:{self.iteration}"

    def __str__(self) -> str:
        return self.raw
