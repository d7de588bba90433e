"""Reading the client messages of both endpoints (protocols/)."""

from __future__ import annotations

import pytest
from lxml import etree

from realizer.bml_parser import BML_NS
from realizer.service.errors import BadMessage
from realizer.service.messages import (
    read_submitter_message,
    read_subscribe_message,
    warning_feedback_xml,
)


def test_plain_bml_text_is_a_bml_request() -> None:
    assert read_submitter_message("  <bml id='b'/>") == {"type": "bml", "bml": "  <bml id='b'/>"}


def test_a_json_envelope_carries_bml_and_the_character() -> None:
    request = read_submitter_message('{"type": "bml", "bml": "<bml/>", "character": "Alice"}')
    assert request == {"type": "bml", "bml": "<bml/>", "character": "Alice"}


def test_an_interrupt_envelope_names_the_block() -> None:
    assert read_submitter_message('{"type": "interrupt", "block": "bml1"}') == {
        "type": "interrupt",
        "block": "bml1",
    }


@pytest.mark.parametrize(
    "text",
    [
        "hello",
        "{not json",
        "[1, 2]",
        '{"type": "dance"}',
        '{"type": "bml"}',
        '{"type": "bml", "bml": 3}',
        '{"type": "interrupt", "block": ""}',
        '{"type": "bml", "bml": "<bml/>", "character": 7}',
    ],
)
def test_anything_else_is_refused_with_a_reason(text: str) -> None:
    with pytest.raises(BadMessage) as caught:
        read_submitter_message(text)
    assert caught.value.message


def test_subscribe_changes_only_the_fields_it_names() -> None:
    assert read_subscribe_message('{"type": "subscribe", "vertices": "int16"}') == {
        "type": "subscribe",
        "vertices": "int16",
    }
    with pytest.raises(BadMessage):
        read_subscribe_message('{"type": "subscribe", "vertices": "png"}')


def test_service_warnings_are_bml_warning_feedback_with_escaped_text() -> None:
    xml = warning_feedback_xml("b<1", "Alice", "PARSING_FAILURE", "a < b & c")
    element = etree.fromstring(xml.encode())
    assert element.tag == f"{{{BML_NS}}}warningFeedback"
    assert element.get("id") == "b<1" and element.get("characterId") == "Alice"
    assert element.get("type") == "PARSING_FAILURE" and element.text == "a < b & c"
