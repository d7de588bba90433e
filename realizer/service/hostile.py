"""Hostile messages: the inputs of the service's hostile-input audit, as data.

Each one froze, filled or broke an earlier version of the service (the
numbers are those of the audit's defects); they stay here so that the
hostile end-to-end test (``tests/service/test_hostile.py``) and
``realizer bench hostile`` feed the very same bytes. ``docs/service.md``
("Guarantees under hostile input") says what the service does with them.

A :class:`HostileMessage` is a text message for the submitter endpoint
(``/bml``) or the viewer endpoint (``/view``); :data:`HTTP_REQUESTS` are raw
HTTP requests with the status each must get.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

BML_NS = "http://www.bml-initiative.org/bml/bml-1.0"
DRAFT_NS = "http://www.mindmakers.org/projects/BML"


@dataclass(frozen=True, slots=True)
class HostileMessage:
    """``text`` sent to ``endpoint``; ``defect`` is the audit's number."""

    name: str
    defect: int
    endpoint: Literal["/bml", "/view"]
    text: str


def _bml(block_id: str, body: str, extra: str = "", character: str = "") -> str:
    who = f' characterId="{character}"' if character else ""
    return f'<bml xmlns="{BML_NS}" id="{block_id}"{who}{extra}>{body}</bml>'


def hostile_messages(character: str = "alice") -> list[HostileMessage]:
    """The hostile messages, the BML ones addressed to ``character``."""

    def bml(name: str, defect: int, block_id: str, body: str, extra: str = "") -> HostileMessage:
        return HostileMessage(name, defect, "/bml", _bml(block_id, body, extra, character))

    heads = "".join(f'<head id="h{n}" lexeme="NOD" repetition="3000"/>' for n in range(256))
    attributes_21000 = " ".join(f'u{n}="1"' for n in range(21_000))
    attributes_4200 = " ".join(f'u{n}="1"' for n in range(4_200))
    many_warnings = "".join(
        f'<faceLexeme id="f{n}" lexeme="RAISE_BROWS" odd="1" end="1"/>' for n in range(250)
    )
    face = '<faceLexeme id="a" lexeme="RAISE_BROWS" '
    return [
        HostileMessage(
            "28 spaces before the root", 1, "/bml", " " * 28 + _bml("d1", "", "", character)
        ),
        HostileMessage(
            "a comment and 12 CRLF before the root",
            1,
            "/bml",
            "<!-- c -->" + "\r\n" * 12 + _bml("d2", "", "", character),
        ),
        bml("repetition 1e308", 2, "r1", '<head id="h1" lexeme="NOD" repetition="1e308"/>'),
        HostileMessage(
            "draft repeats 1e308",
            2,
            "/bml",
            f'<bml xmlns="{DRAFT_NS}" id="r2" characterId="{character}">'
            '<head id="h" type="NOD" repeats="1e308"/></bml>',
        ),
        bml("256 heads with repetition 3000", 2, "r3", heads),
        bml(
            "51 kB of whitespace in a sync reference", 3, "s1", f'{face}start="x:{" " * 51_000}y"/>'
        ),
        bml("21,000 unknown attributes on one line", 4, "c1", f"{face}{attributes_21000}/>"),
        bml("4,200 unknown attributes", 5, "w1", f"{face}{attributes_4200}/>"),
        bml("250 behaviours with unknown attributes", 5, "w2", many_warnings),
        bml("an empty block", 6, "e0", ""),
        *(bml(f"empty block {n}", 6, f"e{n}", "") for n in range(1, 40)),
        bml("start 1e308", 7, "n1", f'{face}start="1e308"/>'),
        bml("start bml:start+1e308", 7, "n2", f'{face}start="bml:start+1e308"/>'),
        bml("start of 400 digits", 7, "n3", f'{face}start="{"1" * 400}"/>'),
        bml("APPEND ending at 1e308", 7, "n4", f'{face}end="1e308"/>', ' composition="APPEND"'),
        HostileMessage(
            "interrupt with a lone surrogate",
            8,
            "/bml",
            f'{{"type":"interrupt","block":"\\udc80","character":"{character}"}}',
        ),
        HostileMessage(
            "a lone surrogate as the character",
            8,
            "/bml",
            '{"type":"bml","bml":"<bml/>","character":"\\udc80"}',
        ),
        HostileMessage("JSON with a lone surrogate", 9, "/bml", '{"type":"bml","bml":"\\ud800"}'),
        HostileMessage("JSON nested 100,000 deep", 9, "/bml", '{"a":' + "[" * 100_000),
        HostileMessage(
            "JSON with a 5,000-digit integer", 9, "/bml", '{"type":"bml","n":' + "9" * 5000 + "}"
        ),
        HostileMessage("subscribe nested 100,000 deep", 9, "/view", "[" * 100_000),
        HostileMessage(
            "subscribe with a 5,000-digit integer",
            9,
            "/view",
            '{"type":"subscribe","fap":' + "9" * 5000 + "}",
        ),
        HostileMessage(
            "subscribe with a lone surrogate",
            9,
            "/view",
            '{"type":"subscribe","character":"\\udc80"}',
        ),
        HostileMessage(
            "interrupt with NUL and control characters",
            10,
            "/bml",
            f'{{"type":"interrupt","block":"\\u0000\\u0001x\\u001f","character":"{character}"}}',
        ),
        HostileMessage(
            "a refused character id with control characters",
            10,
            "/bml",
            '{"type":"bml","bml":"<bml/>","character":"\\u0007\\u0000"}',
        ),
        bml("a duplicate block id", 11, "dup", f'{face}end="2"/>'),
        bml("the same block id again", 11, "dup", f'{face}end="2"/>'),
    ]


#: (name, defect, raw request bytes, the status it must get); the endpoint
#: path is ``/bml``. ``KEY`` lines make a request a WebSocket handshake.
_KEY = b"Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
HTTP_REQUESTS: list[tuple[str, int, bytes, int]] = [
    (
        "a doubled Upgrade header",
        12,
        b"GET /bml HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\nUpgrade: websocket\r\n"
        b"Connection: Upgrade\r\n" + _KEY + b"\r\n",
        400,
    ),
    (
        "a doubled Upgrade header on a plain path",
        12,
        b"GET /health HTTP/1.1\r\nHost: x\r\nUpgrade: a\r\nUpgrade: b\r\n\r\n",
        400,
    ),
    ("POST", 12, b"POST /health HTTP/1.1\r\nHost: x\r\nContent-Length: 0\r\n\r\n", 405),
    ("POST with a body", 12, b"POST /bml HTTP/1.1\r\nHost: x\r\nContent-Length: 2\r\n\r\n{}", 400),
    (
        "two pipelined requests",
        12,
        b"GET /health HTTP/1.1\r\nHost: x\r\n\r\nGET /health HTTP/1.1\r\nHost: x\r\n\r\n",
        400,
    ),
]
