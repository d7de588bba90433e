"""Feedback at the same instant comes in the documented order (docs/scheduler.md).

Time first; at equal times (as written, to the microsecond) the blocks in the
order they arrived, so a block's end precedes the start of the block
appended after it; inside a block its start, then the sync points of its
behaviours in document order, each behaviour's in canonical order (start,
a speech's markers in text order, ..., end), then its end.
"""

from __future__ import annotations

from realizer.bml_parser import BML_NS
from realizer.bml_parser.feedback import BlockProgress, SyncPointProgress, parse_feedback
from realizer.session import Session


def bml(block_id: str, body: str, extra: str = "") -> str:
    return f'<bml xmlns="{BML_NS}" id="{block_id}"{extra}>{body}</bml>'


def ids(session: Session, until: float) -> list[str]:
    """Every progress id queued so far and up to ``until``, in the order given."""
    out = []
    now = 0.0
    queued = session.take_feedback()
    while now < until:
        now = round(now + 0.05, 6)
        session.tick(now)
        queued += session.take_feedback()
    for fb in queued:
        message = parse_feedback(fb.xml)
        if isinstance(message, BlockProgress):
            out.append(f"{message.block_id}:{message.sync}")
        elif isinstance(message, SyncPointProgress):
            out.append(f"{message.block_id}:{message.behaviour_id}:{message.sync}")
    return out


def test_a_marker_at_the_start_of_the_text_comes_after_the_speech_start() -> None:
    session = Session()
    session.receive_bml(
        bml("b1", '<speech id="a"><text><sync id="m0"/>Hello <sync id="m1"/>you</text></speech>'),
        now=0.0,
    )
    order = ids(session, 10.0)
    speech = [i for i in order if i.startswith("b1:a:")]
    assert speech == ["b1:a:start", "b1:a:m0", "b1:a:m1", "b1:a:end"]


def test_syncs_at_one_instant_follow_the_canonical_order_not_the_alphabet() -> None:
    session = Session()
    # attackPeak = start and relax = end: alphabetically attackPeak < end < relax < start
    session.receive_bml(
        bml(
            "b1",
            '<faceLexeme id="f" lexeme="RAISE_MOUTH_CORNERS" start="0" attackPeak="0" '
            'relax="1" end="1"/>',
        ),
        now=0.0,
    )
    order = ids(session, 2.0)
    assert order == ["b1:start", "b1:f:start", "b1:f:attackPeak", "b1:f:relax", "b1:f:end",
                     "b1:end"]  # fmt: skip


def test_a_block_ends_before_the_block_appended_after_it_starts() -> None:
    session = Session()
    session.receive_bml(bml("b1", '<head id="h" lexeme="NOD" start="0" end="1"/>'), now=0.0)
    session.receive_bml(
        bml("b2", '<head id="h" lexeme="NOD" start="0" end="1"/>', ' composition="APPEND"'),
        now=0.0,
    )
    order = ids(session, 3.0)
    assert order.index("b1:end") + 1 == order.index("b2:start")
    assert order.index("b1:h:end") < order.index("b1:end")
    assert order[order.index("b2:start") + 1] == "b2:h:start"


def test_behaviours_at_one_instant_come_in_document_order() -> None:
    session = Session()
    session.receive_bml(
        bml(
            "b1",
            '<head id="z" lexeme="NOD" start="0" end="1"/>'
            '<faceLexeme id="a" lexeme="RAISE_MOUTH_CORNERS" start="0" end="1"/>',
        ),
        now=0.0,
    )
    order = [i for i in ids(session, 2.0) if i.endswith(":end")]
    assert order == ["b1:z:end", "b1:a:end", "b1:end"]
