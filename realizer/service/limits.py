"""Named limits on everything a peer can make the service hold.

Every input has a named limit (docs/architecture.md), and input over a
limit is answered (a BML ``warningFeedback``, or a WebSocket close code with
a reason), never a crash and never a silent drop. The defaults are sized for
one machine serving a handful of characters to a classroom of viewers; the
Simple Face object of MPEG-4 level 2 (Tekalp and Ostermann 2000, section 3) animates up to 4
faces at 60 Hz, and the service is meant to do well beyond that.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

#: What a character id may look like: it appears in URLs, log lines and
#: msgpack maps, so it is kept to a safe, short alphabet.
CHARACTER_ID_PATTERN = re.compile(r"[A-Za-z0-9_.\-]{1,64}")


@dataclass(frozen=True, slots=True)
class ServiceLimits:
    """Limits with their defaults. All counts are inclusive maxima.

    ``message_bytes``: the largest WebSocket message a peer may send (bytes);
    larger ones close the connection with 1009 (message too big).
    ``behaviours_per_block``: behaviours in one BML block.
    ``queued_blocks``: blocks of one character that are accepted and not yet
    ended (pending or running).
    ``characters``: sessions one process keeps.
    ``viewers``: viewer connections in all; ``viewers_per_character`` of them
    on one character.
    ``submitters``: submitter connections in all.
    ``feedback_backlog``: feedback messages waiting for one submitter that
    does not read; over it, the submitter is closed with 1008.
    ``subscribe_backlog``: mesh messages waiting for one viewer (each
    subscribe asks for one); over it, the viewer is closed with 1008.
    ``feedback_stall_seconds``: how long the oldest queued feedback message
    of a submitter over its backlog may wait before the submitter is closed
    (a burst that a prompt reader takes closes nothing).
    ``warnings_per_block``: warningFeedback messages about one block in
    answer to one submission; the rest are counted in the last one.
    ``viewer_characters``: characters that viewers alone (with no block
    submitted to them) may make exist; over it a viewer of a new character
    is refused, so viewers cannot take the submitters' characters.
    ``character_idle_seconds``: a character with no open block, no viewer
    and no submitter naming it is freed after this many seconds.
    ``planning_milliseconds``: the time a planner process may spend on one
    message (parsing it, the engines' preparation, scheduling and
    realizing its block); over it the block is refused with a
    ``warningFeedback`` naming this limit and the process is replaced
    (realizer.service.planner). A block of ``behaviours_per_block``
    behaviours plans in tens of milliseconds on an idle machine, a few
    hundred under heavy load; the budget is for what must never happen.
    """

    message_bytes: int = 256 * 1024
    behaviours_per_block: int = 256
    queued_blocks: int = 32
    characters: int = 64
    viewers: int = 1024
    viewers_per_character: int = 256
    submitters: int = 64
    feedback_backlog: int = 4096
    subscribe_backlog: int = 4
    feedback_stall_seconds: int = 5
    warnings_per_block: int = 100
    viewer_characters: int = 8
    character_idle_seconds: int = 300
    planning_milliseconds: int = 5000

    def __post_init__(self) -> None:
        for name in self.__slots__:
            value = getattr(self, name)
            if not isinstance(value, int) or value < 1:
                raise ValueError(f"limit {name} must be a positive integer, not {value!r}")


DEFAULT_LIMITS = ServiceLimits()


def valid_character_id(character_id: str) -> bool:
    """True when ``character_id`` may name a character (see the pattern)."""
    return CHARACTER_ID_PATTERN.fullmatch(character_id) is not None
