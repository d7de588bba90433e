"""The parser's fast paths give what the general ones give.

``nodes.builder`` constructors (slots set directly) against the dataclasses'
own constructors, and ``fast_sync_ref`` (one match for the common shapes)
against the full scanner of :mod:`realizer.bml_parser.syncref`.
"""

from __future__ import annotations

import dataclasses

import pytest
from hypothesis import given
from hypothesis import strategies as st

from realizer.bml_parser import SyncRefError
from realizer.bml_parser.nodes import XmlElement, builder
from realizer.bml_parser.syncref import SyncRef, _parse, fast_sync_ref
from realizer.bml_parser.tree import Behaviour, Block, Constraint, Relation, SpeechText, TextSync


@pytest.mark.parametrize(
    "cls", [XmlElement, Behaviour, Constraint, Relation, SpeechText, TextSync, SyncRef]
)
def test_a_builder_makes_what_the_constructor_makes(cls: type) -> None:
    fields = dataclasses.fields(cls)
    values = [f"v{index}" for index, _ in enumerate(fields)]
    built = builder(cls)(*values)
    assert type(built) is cls
    assert built == cls(*values)
    assert [getattr(built, f.name) for f in fields] == values
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(built, fields[0].name, "changed")
    assert getattr(dataclasses.replace(built, **{fields[0].name: "x"}), fields[0].name) == "x"


def test_no_builder_for_a_class_with_fields_outside_its_constructor() -> None:
    with pytest.raises(TypeError):
        builder(Block)  # Block.source is set by the parser, not passed


REFS = st.one_of(
    st.from_regex(
        r"\s?[A-Za-z_][\w.\-]{0,4}:[A-Za-z_][\w.]{0,5}([+-][0-9.eE+-]{1,6})?\s?", fullmatch=True
    ),
    st.from_regex(r"\s?[+-]?[0-9.]{1,6}([eE][+-]?[0-9]{1,4})?\s?", fullmatch=True),
    st.text(alphabet=" :+-.e0123456789abS_", max_size=14),
)


@given(REFS)
def test_the_fast_sync_reference_path_agrees_with_the_scanner(raw: str) -> None:
    fast = fast_sync_ref(raw)
    try:
        full = _parse(raw, ())
    except SyncRefError:
        assert fast is None
        return
    if fast is not None:
        assert fast == full and fast.raw == raw
