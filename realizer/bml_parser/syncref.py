"""Sync references: ``[block:]behaviour:sync[:iteration][+|-offset]``.

BML 1.0 (section "Synchronization") lets a behaviour's sync attribute, a
``<sync ref>`` and a constraint's ``ref`` name a time as

* a bare number: seconds after the start of the block (``"2.5"``);
* ``behaviour:sync`` in the same block, or ``block:behaviour:sync`` in an
  earlier block, optionally ``:iteration`` for repeated strokes
  (``nod1:stroke:2``), optionally ``+offset``/``-offset`` seconds;
* ``bml:start``, the start of this block.

Whitespace around the parts is tolerated. The raw text is kept beside the
parsed form so that a document serialises back exactly as written.
Malformed references raise :class:`~realizer.bml_parser.errors.SyncRefError`
with a message that says what is wrong; the parser adds line and column.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from functools import lru_cache

from realizer.bml_parser.errors import SyncRefError

_NUMBER = r"[0-9]+(?:\.[0-9]*)?(?:[eE][+-]?[0-9]+)?|\.[0-9]+(?:[eE][+-]?[0-9]+)?"
_NUMBER_RE = re.compile(rf"\s*[+-]?(?:{_NUMBER})\s*")
_OFFSET_RE = re.compile(rf"^(?P<rest>.*?)\s*(?P<sign>[+-])\s*(?P<num>{_NUMBER})\s*$", re.S)
_NAME_RE = re.compile(r"[A-Za-z_][\w.\-]*")
_INT_RE = re.compile(r"[0-9]+")


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


def _parse_number(text: str, raw: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise SyncRefError(f"sync reference {raw!r}: offset is not a finite number")
    return value


# The common shapes, ``behaviour:sync[+|-offset]`` and a bare number, in one
# match; anything else goes through the full grammar below.
_FAST_RE = re.compile(
    rf"\s*(?:(?P<time>[+-]?(?:{_NUMBER}))|(?P<beh>[A-Za-z_][\w.\-]*?):(?P<sync>[A-Za-z_][\w.]*)"
    rf"(?:(?P<sign>[+-])(?P<num>{_NUMBER}))?)\s*"
)


def parse_sync_ref(raw: str, *, sync_aliases: tuple[tuple[str, str], ...] = ()) -> SyncRef:
    """Parse one sync reference; raise :class:`SyncRefError` if it is malformed.

    ``sync_aliases`` maps dialect sync names (``stroke_start``) to BML 1.0
    names (``strokeStart``); the raw text keeps the original spelling.
    """
    match = _FAST_RE.fullmatch(raw)
    if match is not None and not sync_aliases:
        time = match.group("time")
        if time is not None:
            value = float(time)
            if math.isfinite(value):
                return SyncRef(raw, None, None, None, None, value)
        else:
            number = match.group("num")
            offset = 0.0
            if number is not None:
                offset = float(number)
                if match.group("sign") == "-":
                    offset = -offset
            if math.isfinite(offset):
                return SyncRef(raw, match.group("beh"), match.group("sync"), None, None, offset)
    return _parse_sync_ref(raw, sync_aliases)


@lru_cache(maxsize=4096)
def _parse_sync_ref(raw: str, sync_aliases: tuple[tuple[str, str], ...]) -> SyncRef:
    text = raw.strip()
    if not text:
        raise SyncRefError("empty sync reference")
    if _NUMBER_RE.fullmatch(text):
        return SyncRef(raw=raw, behaviour=None, sync=None, offset=_parse_number(text, raw))

    offset = 0.0
    rest = text
    match = _OFFSET_RE.match(text)
    if match and ":" in match.group("rest"):
        rest = match.group("rest")
        offset = _parse_number(match.group("num"), raw)
        if match.group("sign") == "-":
            offset = -offset
    elif re.search(r"[+]", text) or re.search(r"(?<=\S)\s*-\s*[^:\w]|-\s*$", text):
        raise SyncRefError(f"sync reference {raw!r}: offset after + or - is not a number")

    if rest.startswith(":"):
        raise SyncRefError(f"sync reference {raw!r} starts with a colon")
    if rest.endswith(":"):
        raise SyncRefError(f"sync reference {raw!r} ends with a colon")
    parts = [p.strip() for p in rest.split(":")]
    if len(parts) < 2:
        raise SyncRefError(
            f"sync reference {raw!r}: expected behaviour:sync, a number, or block:behaviour:sync"
        )
    if len(parts) > 4:
        raise SyncRefError(f"sync reference {raw!r} has too many parts ({len(parts)}; at most 4)")
    iteration: int | None = None
    block: str | None = None
    if len(parts) == 4:
        if not _INT_RE.fullmatch(parts[3]):
            raise SyncRefError(
                f"sync reference {raw!r}: iteration {parts[3]!r} is not a positive integer"
            )
        iteration = int(parts[3])
        block, behaviour, sync = parts[0], parts[1], parts[2]
    elif len(parts) == 3:
        if _INT_RE.fullmatch(parts[2]):
            iteration = int(parts[2])
            behaviour, sync = parts[0], parts[1]
        else:
            block, behaviour, sync = parts
    else:
        behaviour, sync = parts
    for name in (block, behaviour, sync):
        if name is not None and not _NAME_RE.fullmatch(name):
            raise SyncRefError(f"sync reference {raw!r}: {name!r} is not a valid name")
    sync = dict(sync_aliases).get(sync, sync)
    if iteration is not None:
        if sync != "stroke":
            raise SyncRefError(
                f"sync reference {raw!r}: an iteration is only allowed on 'stroke', not {sync!r}"
            )
        if iteration < 1:
            raise SyncRefError(f"sync reference {raw!r}: iteration must be 1 or more")
    return SyncRef(
        raw=raw, behaviour=behaviour, sync=sync, block=block, iteration=iteration, offset=offset
    )
