"""Property tests: generated blocks round-trip; mutated documents fail cleanly."""

from __future__ import annotations

from xml.sax.saxutils import escape, quoteattr

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from realizer.bml_parser import (
    BML_NS,
    EXT_NS,
    REALIZER_NS,
    BmlError,
    canonical,
    parse_bml,
    serialise,
)
from tests.conftest import EXAMPLES, conformance_files

NAMES = st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{0,6}", fullmatch=True)
TEXT = st.text(
    alphabet=st.characters(codec="utf-8", exclude_categories=("Cs", "Cc"), exclude_characters="\r"),
    max_size=12,
)
NUMBER = st.floats(min_value=0, max_value=100, allow_nan=False).map(lambda x: f"{x:.3g}")


@st.composite
def sync_refs(draw: st.DrawFn, ids: list[str]) -> str:
    if not ids or draw(st.booleans()):
        return draw(NUMBER)
    target = draw(st.sampled_from(ids))
    sync = draw(st.sampled_from(["start", "end", "stroke", "relax", "ready"]))
    offset = draw(st.sampled_from(["", "+1", "-0.5", " + 2", "+0.25"]))
    space = draw(st.sampled_from(["", " "]))
    return f"{space}{target}:{sync}{offset}{space}"


BEHAVIOURS = [
    ("head", 'lexeme="NOD"', ("start", "stroke", "end", "relax")),
    ("gesture", 'lexeme="BEAT" mode="LEFT_HAND"', ("start", "stroke", "strokeEnd", "end")),
    ("faceLexeme", 'lexeme="RAISE_BROWS" amount="0.5"', ("start", "attackPeak", "relax", "end")),
    ("gaze", 'target="camera"', ("start", "ready", "relax", "end")),
    ("ext:faceFacs", 'au="12" side="LEFT"', ("start", "attackPeak", "end")),
    ("rf:emotion", 'word="afraid"', ("start", "attackPeak", "end")),
    ("rf:fap", 'values="3=100 31=-20"', ("start", "end")),
    ("wait", "", ("start", "end")),
]


@st.composite
def blocks(draw: st.DrawFn) -> str:
    count = draw(st.integers(min_value=0, max_value=6))
    ids = [f"b{i}" for i in range(count)]
    parts: list[str] = []
    for index, behaviour_id in enumerate(ids):
        if draw(st.booleans()):
            parts.append(escape(draw(TEXT)).replace("--", "-"))
        if draw(st.integers(0, 5)) == 0:
            parts.append(f"<!--{draw(TEXT).replace('-', '_')}-->")
        if index == 0 and draw(st.booleans()):
            words = escape(draw(TEXT))
            parts.append(
                f'<speech id="{behaviour_id}"><text>{words}<sync id="s1"/>'
                f"{escape(draw(TEXT))}</text></speech>"
            )
            continue
        element, attrs, syncs = draw(st.sampled_from(BEHAVIOURS))
        sync_attrs = "".join(
            f" {name}={quoteattr(draw(sync_refs(ids[:index])))}"
            for name in draw(st.lists(st.sampled_from(syncs), unique=True, max_size=2))
        )
        custom = f" x:{draw(NAMES)}={quoteattr(draw(TEXT))}" if draw(st.booleans()) else ""
        child = f"<x:note>{escape(draw(TEXT))}</x:note>" if draw(st.booleans()) else ""
        closing = f">{child}</{element}>" if child else "/>"
        parts.append(f'<{element} id="{behaviour_id}" {attrs}{sync_attrs}{custom}{closing}')
    if len(ids) >= 2 and draw(st.booleans()):
        kind = draw(st.sampled_from(["synchronize", "before", "after"]))
        ref = "" if kind == "synchronize" else f' ref="{ids[0]}:start"'
        parts.append(
            f'<constraint id="c1"><{kind}{ref}><sync ref="{ids[1]}:end"/>'
            f'<sync ref="{ids[-1]}:start+1"/></{kind}></constraint>'
        )
    composition = draw(st.sampled_from(["", ' composition="APPEND"', ' composition="REPLACE"']))
    return (
        f'<bml xmlns="{BML_NS}" xmlns:ext="{EXT_NS}" xmlns:rf="{REALIZER_NS}" '
        f'xmlns:x="urn:x" id="blk"{composition}>{"".join(parts)}</bml>'
    )


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(blocks())
def test_serialise_then_parse_gives_the_same_tree(document: str) -> None:
    first = parse_bml(document)
    text = serialise(first.block)
    second = parse_bml(text)
    assert second.block == first.block
    assert second.warnings == first.warnings or [w.type for w in second.warnings] == [
        w.type for w in first.warnings
    ]
    assert canonical(text) == canonical(document)


def _seed_documents() -> list[bytes]:
    paths = sorted(EXAMPLES.glob("*.xml")) + conformance_files()
    return [path.read_bytes() for path in paths]


SEEDS = _seed_documents()


@st.composite
def mutated(draw: st.DrawFn) -> bytes:
    data = bytearray(draw(st.sampled_from(SEEDS)))
    for _ in range(draw(st.integers(1, 6))):
        position = draw(st.integers(0, max(0, len(data) - 1)))
        action = draw(st.sampled_from(["delete", "insert", "replace"]))
        byte = draw(st.sampled_from(list(b'<>/:="+-&;!? abc0\x00\xff')))
        if action == "delete" and data:
            del data[position]
        elif action == "insert":
            data.insert(position, byte)
        elif data:
            data[position] = byte
    return bytes(data)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated())
def test_mutated_documents_raise_nothing_but_the_parsers_own_errors(document: bytes) -> None:
    try:
        result = parse_bml(document)
    except BmlError as error:
        assert error.warning_type
        return
    # Whatever survives mutation must still serialise and re-parse.
    assert parse_bml(serialise(result.block)).block == result.block
