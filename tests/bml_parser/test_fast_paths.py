"""The parser's fast paths give what the general ones give.

``nodes.builder`` constructors (slots set directly) against the dataclasses'
own constructors, and ``fast_sync_ref`` (a few string methods for the
common shapes) against the full scanner of :mod:`realizer.bml_parser.syncref`.
"""

from __future__ import annotations

import dataclasses
import pickle

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


def test_a_builder_of_every_field_sets_the_fields_outside_the_constructor_too() -> None:
    fields = dataclasses.fields(Block)
    values = [f"v{index}" for index, _ in enumerate(fields)]
    built = builder(Block, every_field=True)(*values)
    assert type(built) is Block
    assert built.source == values[-1]
    assert [getattr(built, f.name) for f in fields] == values
    with pytest.raises(dataclasses.FrozenInstanceError):
        built.source = "changed"  # type: ignore[misc]


def test_what_a_builder_makes_pickles_and_copies_as_its_class() -> None:
    ref = builder(SyncRef)("h1:stroke+0.2", "h1", "stroke", None, None, 0.2)
    again = pickle.loads(pickle.dumps(ref))
    assert type(again) is SyncRef and again == ref and again.raw == ref.raw
    assert dataclasses.replace(ref, offset=1.0).offset == 1.0


@pytest.mark.parametrize(
    ("raw", "expected"),
    [
        ("h1:stroke+0.2", SyncRef("h1:stroke+0.2", "h1", "stroke", offset=0.2)),
        ("nod1:start", SyncRef("nod1:start", "nod1", "start")),
        ("g_2:end-1.", SyncRef("g_2:end-1.", "g_2", "end", offset=-1.0)),
        ("2.5", SyncRef("2.5", None, None, offset=2.5)),
        (".5", SyncRef(".5", None, None, offset=0.5)),
    ],
)
def test_the_common_shapes_take_the_fast_path(raw: str, expected: SyncRef) -> None:
    assert fast_sync_ref(raw) == expected


@pytest.mark.parametrize(
    "raw",
    ["-1", " 2", "1e3", "b1:h1:start", "h1:stroke:2", "my-nod:start", "h1:sync.1", "é:start",
     "h1:start+", "h1:start+1e2", "h1:start+3601", "3601", "h1:", ":start", "1.2.3", "h1:start+²"],
)  # fmt: skip
def test_anything_else_is_left_to_the_full_parser(raw: str) -> None:
    assert fast_sync_ref(raw) is None


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
