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

Complexity and limits (a reference is peer input): parsing is linear in the
reference's length. The common shapes (``h1:stroke+0.2``, ``2.5``) go
through a few ``str`` methods (:func:`fast_sync_ref`); everything else is a
scanner over ``str`` methods (``strip``, ``rfind``, ``split``) and
regular expressions in which no two neighbouring parts can match the same
character, so they never backtrack more than a character; each looks at
each character a bounded number of times. Times and offsets are finite and at
most :data:`MAX_SECONDS` in magnitude; an iteration is at most
:data:`MAX_ITERATION`. Only references up to :data:`_CACHED_CHARS`
characters are memoised, so the cache holds a bounded amount of text.
"""

from __future__ import annotations

import re
from functools import lru_cache
from typing import Final

from realizer.bml_parser.errors import SyncRefError
from realizer.bml_parser.nodes import builder

# a plain Python class (pickled, compared, replaced), outside this module,
# which may be compiled (realizer/compiled.py)
from realizer.bml_parser.refs import SyncRef as SyncRef

#: The largest magnitude of a time or an offset, seconds (one hour). Beyond
#: it a block would not end within any session a person watches, and the
#: frame arithmetic downstream loses precision or overflows.
MAX_SECONDS: Final = 3600.0
#: The largest stroke iteration a reference may name (``nod1:stroke:N``);
#: the same bound as the parser's ``Limits.max_repetition`` default.
MAX_ITERATION: Final = 32

# Deterministic: each alternative starts with a different character class,
# and every quantified part is followed by a character it cannot match.
_NUMBER: Final = r"[0-9]+(?:\.[0-9]*)?(?:[eE][+-]?[0-9]+)?|\.[0-9]+(?:[eE][+-]?[0-9]+)?"
_UNSIGNED_RE: Final = re.compile(_NUMBER)
_SIGNED_RE: Final = re.compile(rf"[+-]?(?:{_NUMBER})")
_NAME_RE: Final = re.compile(r"[A-Za-z_][\w.\-]*")
_CACHED_CHARS: Final = 256


_new_ref: Final = builder(SyncRef)


def _seconds(text: str, raw: str, what: str) -> float:
    """``text`` (already known to be a decimal number) as seconds within the limit."""
    value = float(text)
    if not abs(value) <= MAX_SECONDS:  # also refuses inf and nan
        raise SyncRefError(
            f"sync reference {_short(raw)}: {what} {_short(text)} is beyond the limit "
            f"of {MAX_SECONDS:g} seconds"
        )
    return value


def _short(text: str) -> str:
    """``text`` quoted for a message, cut to a readable length."""
    return repr(text) if len(text) <= 80 else repr(text[:77] + "...")


def fast_sync_ref(raw: str) -> SyncRef | None:
    """The common shapes, ``behaviour:sync[+|-offset]`` with ASCII names and a
    plain decimal offset, or a plain decimal time, within :data:`MAX_SECONDS`;
    None for anything else (which :func:`parse_sync_ref` parses, or refuses,
    in full: whitespace, signs on times, exponents, blocks, iterations,
    names with ``.`` or ``-``, Unicode). No dialect aliases.

    A few string methods instead of a regular expression: a match costs
    more than the rest of building the reference. Linear in the length.
    """
    if ":" not in raw:
        # a time: digits with at most one point in them
        if raw.isascii() and raw.replace(".", "", 1).isdigit():
            value = float(raw)
            if value <= MAX_SECONDS:
                return _new_ref(raw, None, None, None, None, value)
        return None
    behaviour, _, rest = raw.partition(":")
    # an ASCII identifier is a name of the grammar ([A-Za-z_][A-Za-z0-9_]*)
    if not (behaviour.isascii() and behaviour.isidentifier()):
        return None
    offset = 0.0
    at = rest.find("+")
    if at < 0:
        at = rest.find("-")
    if at >= 0:
        number = rest[at + 1 :]
        if not (number.isascii() and number.replace(".", "", 1).isdigit()):
            return None
        offset = float(number)
        if offset > MAX_SECONDS:
            return None
        if rest[at] == "-":
            offset = -offset
        rest = rest[:at]
    if not (rest.isascii() and rest.isidentifier()):
        return None
    return _new_ref(raw, behaviour, rest, None, None, offset)


def parse_sync_ref(raw: str, *, sync_aliases: tuple[tuple[str, str], ...] = ()) -> SyncRef:
    """Parse one sync reference; raise :class:`SyncRefError` if it is malformed.

    ``sync_aliases`` maps dialect sync names (``stroke_start``) to BML 1.0
    names (``strokeStart``); the raw text keeps the original spelling.
    """
    if not sync_aliases:
        ref = fast_sync_ref(raw)
        if ref is not None:
            return ref
    if len(raw) <= _CACHED_CHARS:
        return _parse_cached(raw, sync_aliases)
    return _parse(raw, sync_aliases)


@lru_cache(maxsize=4096)
def _parse_cached(raw: str, sync_aliases: tuple[tuple[str, str], ...]) -> SyncRef:
    return _parse(raw, sync_aliases)


def _last_sign(text: str, end: int) -> int:
    """The index of the last ``+`` or ``-`` before ``end``, or -1."""
    return max(text.rfind("+", 0, end), text.rfind("-", 0, end))


def _split_offset(text: str) -> tuple[str, str, str] | None:
    """``(rest, sign, number)`` when ``text`` ends in ``[+-] number``, else None.

    The earliest sign after which only a number (and whitespace) follows
    wins; a number holds at most one sign (in its exponent), so only the
    last two signs of the text can be that one.
    """
    last = _last_sign(text, len(text))
    if last < 0:
        return None
    before = _last_sign(text, last)
    for at in (before, last):
        if at >= 0:
            number = text[at + 1 :].strip()
            if _UNSIGNED_RE.fullmatch(number):
                return text[:at].rstrip(), text[at], number
    return None


def _dangling_sign(text: str) -> bool:
    """True when a ``+``, or a ``-`` that cannot be part of a name, is in ``text``.

    ``text`` is stripped; a ``-`` inside a name (``my-nod``) is followed by
    a name character or a colon.
    """
    if "+" in text:
        return True
    at = text.find("-", 1)
    while at >= 0:
        following = text[at + 1 : at + 2]
        if not following or not (following.isalnum() or following in "_:"):
            return True
        at = text.find("-", at + 1)
    return False


def _parse(raw: str, sync_aliases: tuple[tuple[str, str], ...]) -> SyncRef:
    text = raw.strip()
    if not text:
        raise SyncRefError("empty sync reference")
    if _SIGNED_RE.fullmatch(text):
        return SyncRef(raw=raw, behaviour=None, sync=None, offset=_seconds(text, raw, "time"))

    offset = 0.0
    rest = text
    split = _split_offset(text)
    if split is not None and ":" in split[0]:
        rest, sign, number = split
        offset = _seconds(number, raw, "offset")
        if sign == "-":
            offset = -offset
    elif _dangling_sign(text):
        raise SyncRefError(f"sync reference {_short(raw)}: offset after + or - is not a number")

    if rest.startswith(":"):
        raise SyncRefError(f"sync reference {_short(raw)} starts with a colon")
    if rest.endswith(":"):
        raise SyncRefError(f"sync reference {_short(raw)} ends with a colon")
    parts = rest.split(":", 4)
    if len(parts) < 2:
        raise SyncRefError(
            f"sync reference {_short(raw)}: expected behaviour:sync, a number, "
            "or block:behaviour:sync"
        )
    if len(parts) > 4:
        raise SyncRefError(
            f"sync reference {_short(raw)} has too many parts ({rest.count(':') + 1}; at most 4)"
        )
    parts = [part.strip() for part in parts]
    iteration: int | None = None
    block: str | None = None
    if len(parts) == 4:
        iteration = _iteration(parts[3], raw)
        block, behaviour, sync = parts[0], parts[1], parts[2]
    elif len(parts) == 3:
        if parts[2].isascii() and parts[2].isdigit():
            iteration = _iteration(parts[2], raw)
            behaviour, sync = parts[0], parts[1]
        else:
            block, behaviour, sync = parts
    else:
        behaviour, sync = parts
    for name in (block, behaviour, sync):
        if name is not None and not _NAME_RE.fullmatch(name):
            raise SyncRefError(f"sync reference {_short(raw)}: {_short(name)} is not a valid name")
    sync = dict(sync_aliases).get(sync, sync)
    if iteration is not None and sync != "stroke":
        raise SyncRefError(
            f"sync reference {_short(raw)}: an iteration is only allowed on 'stroke', not {sync!r}"
        )
    return SyncRef(
        raw=raw, behaviour=behaviour, sync=sync, block=block, iteration=iteration, offset=offset
    )


def _iteration(text: str, raw: str) -> int:
    """A stroke iteration: a whole number from 1 to :data:`MAX_ITERATION`."""
    if not (text.isascii() and text.isdigit()):
        raise SyncRefError(
            f"sync reference {_short(raw)}: iteration {_short(text)} is not a positive integer"
        )
    # Compared as text first: int() of thousands of digits is slow, then refused.
    if len(text.lstrip("0")) > len(str(MAX_ITERATION)) or int(text) > MAX_ITERATION:
        raise SyncRefError(
            f"sync reference {_short(raw)}: iteration {_short(text)} is beyond the limit "
            f"of {MAX_ITERATION}"
        )
    if int(text) < 1:
        raise SyncRefError(f"sync reference {_short(raw)}: iteration must be 1 or more")
    return int(text)
