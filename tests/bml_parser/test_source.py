"""The writer's two paths: a parsed, unchanged block comes back as its source
text; a changed or hand-built one is written from its fields.

The round-trip tests elsewhere call ``serialise`` as users do, so they now
see the source path; the tests here hold the writer itself to the same
checks (``from_source=False``) on the same documents.
"""

from __future__ import annotations

import dataclasses
import pickle
import re

import pytest
from hypothesis import HealthCheck, given, settings

from realizer.bml_parser import (
    BML_NS,
    Behaviour,
    canonical,
    parse_bml,
    serialise,
)
from tests.bml_parser.test_properties import SEEDS, blocks
from tests.conftest import EXAMPLES, conformance_files

PATHS = sorted(EXAMPLES.glob("*.xml")) + conformance_files()
_DECLARATION = re.compile(r"\A(?:\ufeff)?<\?xml\s[^?]*\?>\s*")


def _accepted(paths: list) -> list:  # type: ignore[type-arg]
    kept = []
    for path in paths:
        try:
            parse_bml(path.read_bytes())
        except Exception:
            continue  # the deliberately broken ones
        kept.append(path)
    return kept


ACCEPTED = _accepted(PATHS)


@pytest.mark.parametrize("path", ACCEPTED, ids=lambda p: p.name)
def test_an_unchanged_block_is_its_source_byte_for_byte(path) -> None:  # type: ignore[no-untyped-def]
    data = path.read_bytes()
    block = parse_bml(data).block
    expected = _DECLARATION.sub("", data.decode("utf-8"))
    assert serialise(block) == expected
    assert block.source == expected


@pytest.mark.parametrize("path", ACCEPTED, ids=lambda p: p.name)
def test_the_writer_alone_round_trips_every_document(path) -> None:  # type: ignore[no-untyped-def]
    data = path.read_bytes()
    block = parse_bml(data).block
    written = serialise(block, from_source=False)
    assert canonical(written) == canonical(data)
    assert parse_bml(written).block == block


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(blocks())
def test_the_writer_alone_gives_the_same_tree(document: str) -> None:
    first = parse_bml(document)
    text = serialise(first.block, from_source=False)
    assert parse_bml(text).block == first.block
    assert canonical(text) == canonical(document)


def test_a_changed_block_is_written_from_its_fields() -> None:
    text = (
        f'<bml xmlns="{BML_NS}" id="b">\n'
        '  <head id="h1" lexeme="NOD" start="1"/>\n'
        "  <!-- kept -->\n"
        "</bml>\n"
    )
    block = parse_bml(text).block
    assert serialise(block) == text
    head = next(child for child in block.children if isinstance(child, Behaviour))
    shaken = dataclasses.replace(
        head, attributes=tuple((k, "SHAKE" if k == "lexeme" else v) for k, v in head.attributes)
    )
    changed = dataclasses.replace(
        block, children=tuple(shaken if c is head else c for c in block.children)
    )
    assert changed.source == ""
    out = serialise(changed)
    assert 'lexeme="SHAKE"' in out and "NOD" not in out and "<!-- kept -->" in out
    assert canonical(out) == canonical(text.replace("NOD", "SHAKE"))
    # a replace that changes nothing still drops the source: written, and equal
    same = dataclasses.replace(block)
    assert same.source == "" and same == block
    assert canonical(serialise(same)) == canonical(text)


def test_a_copy_through_pickle_keeps_its_source() -> None:
    block = parse_bml(SEEDS[0]).block
    copy = pickle.loads(pickle.dumps(block))
    assert copy == block and copy.source == block.source and serialise(copy) == serialise(block)


def test_the_xml_declaration_is_left_out_and_other_encodings_are_written() -> None:
    body = f'<bml xmlns="{BML_NS}" id="b"><head id="h" lexeme="NOD"/></bml>'
    declared = f'<?xml version="1.0" encoding="UTF-8"?>\n{body}'
    assert serialise(parse_bml(declared).block) == body
    assert serialise(parse_bml(declared.encode()).block) == body
    assert serialise(parse_bml(b"\xef\xbb\xbf" + body.encode()).block) == body
    # a processing instruction whose name starts with xml is no declaration
    styled = f'<?xml-stylesheet href="a.css"?>{body}'
    assert serialise(parse_bml(styled).block) == styled
    # bytes in another encoding: no source, the writer gives the same document
    latin = f'<?xml version="1.0" encoding="ISO-8859-1"?><bml xmlns="{BML_NS}" id="b">'
    latin += '<speech id="s"><text>caf\u00e9</text></speech></bml>'
    block = parse_bml(latin.encode("latin-1")).block
    assert block.source == ""
    assert canonical(serialise(block)) == canonical(latin.split("?>", 1)[1])
