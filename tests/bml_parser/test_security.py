"""The hardened reader refuses documents that attack XML parsers."""

from __future__ import annotations

import pytest

from realizer.bml_parser import (
    BML_NS,
    BmlError,
    BmlSecurityError,
    Limits,
    WarningType,
    parse_bml,
)

BILLION_LAUGHS = f"""<?xml version="1.0"?>
<!DOCTYPE bml [
 <!ENTITY lol "lol">
 <!ENTITY lol1 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">
 <!ENTITY lol2 "&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;">
 <!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">
 <!ENTITY lol4 "&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;">
 <!ENTITY lol5 "&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;">
 <!ENTITY lol6 "&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;">
 <!ENTITY lol7 "&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;">
 <!ENTITY lol8 "&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;">
 <!ENTITY lol9 "&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;">
]>
<bml xmlns="{BML_NS}" id="b"><speech id="s"><text>&lol9;</text></speech></bml>
"""

EXTERNAL_ENTITY = f"""<?xml version="1.0"?>
<!DOCTYPE bml [<!ENTITY secret SYSTEM "file:///etc/passwd">]>
<bml xmlns="{BML_NS}" id="b"><speech id="s"><text>&secret;</text></speech></bml>
"""

EXTERNAL_DTD = f"""<?xml version="1.0"?>
<!DOCTYPE bml SYSTEM "http://example.invalid/bml.dtd">
<bml xmlns="{BML_NS}" id="b"/>
"""


@pytest.mark.parametrize(
    "document", [BILLION_LAUGHS, EXTERNAL_ENTITY, EXTERNAL_DTD], ids=["laughs", "xxe", "dtd"]
)
def test_documents_with_a_doctype_are_refused_without_expansion(document: str) -> None:
    with pytest.raises(BmlSecurityError) as caught:
        parse_bml(document)
    assert "DOCTYPE" in caught.value.message
    assert caught.value.warning_type is WarningType.PARSING_FAILURE


def test_external_entity_content_never_appears_in_an_error() -> None:
    with pytest.raises(BmlError) as caught:
        parse_bml(EXTERNAL_ENTITY)
    assert "root:" not in str(caught.value)


def test_undefined_entity_is_a_parse_error() -> None:
    with pytest.raises(BmlError, match="nope"):
        parse_bml(f'<bml xmlns="{BML_NS}" id="b">&nope;</bml>')


def test_document_over_the_size_limit_is_refused_before_parsing() -> None:
    document = f'<bml xmlns="{BML_NS}" id="b">' + " " * 2000 + "</bml>"
    with pytest.raises(BmlSecurityError, match="exceeds the limit of 1000 bytes"):
        parse_bml(document, limits=Limits(max_bytes=1000))
    assert parse_bml(document).block.id == "b"


def test_behaviour_count_limit() -> None:
    body = "".join(f'<head id="h{i}" lexeme="NOD"/>' for i in range(11))
    with pytest.raises(BmlSecurityError, match="more than 10 behaviours"):
        parse_bml(f'<bml xmlns="{BML_NS}" id="b">{body}</bml>', limits=Limits(max_behaviours=10))


def test_nesting_depth_limit() -> None:
    nested = "<x>" * 30 + "</x>" * 30
    document = f'<bml xmlns="{BML_NS}" xmlns:o="urn:o" id="b"><o:wrap>{nested}</o:wrap></bml>'
    with pytest.raises(BmlSecurityError, match="deeper than 20"):
        parse_bml(document.replace("<x>", "<o:x>").replace("</x>", "</o:x>"),
                  limits=Limits(max_depth=20))  # fmt: skip


def test_empty_and_garbage_input_give_parse_errors() -> None:
    for document in ["", "   ", "not xml", "<bml", b"\xff\xfe\x00<"]:
        with pytest.raises(BmlError) as caught:
            parse_bml(document)
        assert caught.value.warning_type is WarningType.PARSING_FAILURE
