"""Sync references: the full grammar and precise errors for malformed ones."""

from __future__ import annotations

import pytest

from realizer.bml_parser import SyncRef, SyncRefError, parse_sync_ref


@pytest.mark.parametrize(
    ("raw", "block", "behaviour", "sync", "iteration", "offset"),
    [
        ("2.5", None, None, None, None, 2.5),
        ("0", None, None, None, None, 0.0),
        (" 10 ", None, None, None, None, 10.0),
        ("nod1:stroke", None, "nod1", "stroke", None, 0.0),
        ("nod1:stroke:2", None, "nod1", "stroke", 2, 0.0),
        ("bml2:nod1:end", "bml2", "nod1", "end", None, 0.0),
        ("bml2:nod1:stroke:3", "bml2", "nod1", "stroke", 3, 0.0),
        ("g1:start-1", None, "g1", "start", None, -1.0),
        ("g1:end+0.5", None, "g1", "end", None, 0.5),
        ("bml2:nod1:stroke:3+1.25", "bml2", "nod1", "stroke", 3, 1.25),
        ("  speech1 : s1  +  2 ", None, "speech1", "s1", None, 2.0),
        ("bml:start", None, "bml", "start", None, 0.0),
        ("my-nod:start", None, "my-nod", "start", None, 0.0),
        ("a:b+1e1", None, "a", "b", None, 10.0),
    ],
)
def test_sync_reference_parses_into_its_parts(
    raw: str,
    block: str | None,
    behaviour: str | None,
    sync: str | None,
    iteration: int | None,
    offset: float,
) -> None:
    ref = parse_sync_ref(raw)
    assert (ref.block, ref.behaviour, ref.sync, ref.iteration, ref.offset) == (
        block,
        behaviour,
        sync,
        iteration,
        offset,
    )
    assert ref.raw == raw  # the text as written is kept
    assert ref.is_time == (behaviour is None)


@pytest.mark.parametrize(
    ("raw", "complaint"),
    [
        (":nod1:start", "starts with a colon"),
        ("nod1:start:", "ends with a colon"),
        ("a:b:c:d:e", "too many parts"),
        ("nod1:start+x", "not a number"),
        ("nod1:start+", "not a number"),
        ("nod1:start-", "not a number"),
        ("nod1:relax:2", "only allowed on 'stroke'"),
        ("bml1:nod1:end:2", "only allowed on 'stroke'"),
        ("b:nod1:stroke:x", "not a positive integer"),
        ("nod1:stroke:0", "1 or more"),
        ("nod1", "expected behaviour:sync"),
        ("", "empty"),
        ("   ", "empty"),
        ("a b:start", "not a valid name"),
        ("nod1:start+inf", "not a number"),
    ],
)
def test_malformed_sync_reference_is_refused_with_its_reason(raw: str, complaint: str) -> None:
    with pytest.raises(SyncRefError) as caught:
        parse_sync_ref(raw)
    assert complaint in caught.value.message


def test_sync_name_for_an_iteration_names_the_repetition() -> None:
    assert parse_sync_ref("nod1:stroke:2").sync_name == "stroke:2"
    assert parse_sync_ref("nod1:stroke").sync_name == "stroke"


def test_draft_sync_names_are_read_as_bml_1_0_names() -> None:
    ref = parse_sync_ref("f1:attack_peak", sync_aliases=(("attack_peak", "attackPeak"),))
    assert ref.sync == "attackPeak"
    assert ref.raw == "f1:attack_peak"


def test_equal_references_compare_equal_whatever_their_spacing() -> None:
    assert parse_sync_ref("a:b+1") == parse_sync_ref(" a : b + 1 ")
    assert parse_sync_ref("a:b+1") != parse_sync_ref("a:b+2")
    assert isinstance(parse_sync_ref("1"), SyncRef)
