"""Regression tests for the parser defects of the hostile-input audit (issue 10).

Each test feeds the input that froze or filled the server. Time bounds are
generous (the fixed code takes milliseconds; the defective one took seconds
to minutes for the same input); the bound grows with the machine's load
average beyond its core count, so a busy machine does not fail them while a
regression (seconds to minutes) still does; the ``timeout`` mark stops a
regression from hanging the suite.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from realizer.bml_parser import (
    BML_NS,
    DRAFT_NS,
    BmlSecurityError,
    Limits,
    SyncRefError,
    WarningType,
    parse_bml,
    parse_sync_ref,
)
from realizer.bml_parser.syncref import MAX_ITERATION, MAX_SECONDS

#: Seconds an input may take on an idle machine; the defective parser took 7 s
#: to minutes. Scaled by how far the load average exceeds the core count.
BOUND = 1.0 * max(1.0, os.getloadavg()[0] / (os.cpu_count() or 1))


def bml(body: str, *, root_attributes: str = "") -> str:
    return f'<bml xmlns="{BML_NS}" id="b1"{root_attributes}>{body}</bml>'


def timed(function, *args, **kwargs):  # type: ignore[no-untyped-def]
    began = time.perf_counter()
    try:
        result = function(*args, **kwargs)
    except Exception as exc:  # the caller inspects what was raised
        result = exc
    return result, time.perf_counter() - began


# -- defect 1: the DOCTYPE pre-check backtracked exponentially ---------------------


@pytest.mark.timeout(30)
@pytest.mark.parametrize(
    "prolog",
    [
        " " * 28,  # the 135-byte message that froze the server 7 s
        "<!-- a comment -->" + "\r\n" * 12,  # an ordinary document: 0.4 s
        " \t\r\n" * 20_000,
        "<!-- c -->  <?pi x?> \n" * 2_000,
    ],
)
def test_whitespace_and_comments_before_the_root_take_linear_time(prolog: str) -> None:
    result, seconds = timed(parse_bml, prolog + bml(""))
    assert not isinstance(result, Exception), result
    assert result.block.id == "b1"
    assert seconds < BOUND


@pytest.mark.timeout(30)
def test_a_doctype_after_a_long_prolog_is_still_refused() -> None:
    document = "\ufeff" + "<!-- x -->\n  " * 1000 + '<!DOCTYPE bml SYSTEM "x.dtd">' + bml("")
    result, seconds = timed(parse_bml, document)
    assert isinstance(result, BmlSecurityError)
    assert "DOCTYPE" in result.message
    assert seconds < BOUND


# -- defect 2: unbounded repetition ---------------------------------------------------


def test_a_repetition_of_1e308_is_refused_without_materialising_strokes() -> None:
    result, seconds = timed(parse_bml, bml('<head id="h1" lexeme="NOD" repetition="1e308"/>'))
    assert not isinstance(result, Exception), result
    assert result.block.behaviours == ()
    assert [w.type for w in result.warnings] == [WarningType.CANNOT_CREATE_BEHAVIOR]
    assert seconds < BOUND


def test_repetition_at_the_limit_is_accepted_and_one_over_is_refused() -> None:
    at_limit = parse_bml(
        bml(f'<head id="h1" lexeme="NOD" repetition="{MAX_ITERATION}"/>')
    ).block.behaviours
    assert len(at_limit) == 1
    assert f"stroke:{MAX_ITERATION}" in at_limit[0].syncs
    over = parse_bml(bml(f'<head id="h1" lexeme="NOD" repetition="{MAX_ITERATION + 1}"/>'))
    assert over.block.behaviours == ()
    assert "over the limit" in over.warnings[0].message


def test_the_drafts_repeats_has_the_same_limit() -> None:
    document = f'<bml xmlns="{DRAFT_NS}" id="d"><head id="h" type="NOD" repeats="3000"/></bml>'
    result = parse_bml(document)
    assert result.block.behaviours == ()
    assert "over the limit" in result.warnings[0].message


@pytest.mark.timeout(60)
def test_many_heads_with_a_large_repetition_cost_little() -> None:
    heads = "".join(f'<head id="h{n}" lexeme="NOD" repetition="3000"/>' for n in range(256))
    result, seconds = timed(parse_bml, bml(heads))
    assert not isinstance(result, Exception), result
    assert result.block.behaviours == ()
    assert seconds < BOUND


# -- defect 3: quadratic sync reference scanning --------------------------------------


@pytest.mark.timeout(60)
@pytest.mark.parametrize(
    "raw",
    [
        "x:" + " " * 51_000 + "y",
        "x:y" + " " * 51_000 + "+" + " " * 51_000 + "x",
        "x:y" + " " * 51_000 + "-" + " " * 51_000 + "1",
        " " * 51_000 + "-" * 51_000,
        "a" * 51_000 + "+",
        ("-" + " " * 10) * 5_000,
    ],
)
def test_sync_references_with_long_runs_take_linear_time(raw: str) -> None:
    result, seconds = timed(parse_sync_ref, raw)
    assert isinstance(result, (SyncRefError, type(parse_sync_ref("a:b"))))
    assert seconds < BOUND


@pytest.mark.timeout(60)
def test_a_51_kB_sync_reference_in_a_document_takes_linear_time() -> None:
    start = "speech1:" + " " * 51_000 + "start + 1"
    result, seconds = timed(
        parse_bml, bml(f'<faceLexeme id="a" lexeme="RAISE_BROWS" start="{start}"/>')
    )
    assert not isinstance(result, Exception), result
    (behaviour,) = result.block.behaviours
    ((_, ref),) = behaviour.sync_refs
    assert (ref.behaviour, ref.sync, ref.offset) == ("speech1", "start", 1.0)
    assert seconds < BOUND


def test_sync_references_give_the_same_answer_through_both_paths() -> None:
    # the scanner (spaces force it) and the fast path agree
    assert parse_sync_ref(" a : b - 1e-1 ") == parse_sync_ref("a:b-1e-1")
    assert parse_sync_ref(" a-b : c ") == parse_sync_ref("a-b:c")


# -- defect 4: quadratic column lookup; attributes per element ---------------------


@pytest.mark.timeout(60)
def test_21000_unknown_attributes_on_one_line_are_refused_by_a_named_limit() -> None:
    attributes = " ".join(f'u{n}="1"' for n in range(21_000))
    document = bml(f'<faceLexeme id="a" lexeme="RAISE_BROWS" {attributes}/>')
    result, seconds = timed(parse_bml, document)
    assert isinstance(result, BmlSecurityError)
    assert "limit is 128" in result.message
    assert seconds < BOUND


def test_attributes_at_the_limit_are_read_and_one_more_is_refused() -> None:
    limits = Limits(max_attributes=10)
    eight = " ".join(f'u{n}="1"' for n in range(8))  # + id and lexeme = 10
    result = parse_bml(bml(f'<faceLexeme id="a" lexeme="X" {eight}/>'), limits=limits)
    assert len(result.block.behaviours) == 1
    with pytest.raises(BmlSecurityError):
        parse_bml(bml(f'<faceLexeme id="a" lexeme="X" {eight} u9="1"/>'), limits=limits)


@pytest.mark.timeout(60)
def test_warnings_on_one_long_line_cost_linear_time_and_have_columns() -> None:
    body = "".join(f'<faceLexeme id="f{n}" lexeme="RAISE_BROWS" odd{n}="1"/>' for n in range(4_200))
    document = bml(body)
    result, seconds = timed(parse_bml, document, limits=Limits(max_behaviours=5_000))
    assert not isinstance(result, Exception), result
    assert seconds < BOUND
    first = result.warnings[0]
    assert document[first.column - 1 :].startswith("odd0=")
    second = result.warnings[1]
    assert document[second.column - 1 :].startswith("odd1=")


# -- defect 5 (parser side): warnings per block are bounded --------------------------


def test_repeated_warnings_about_one_behaviour_are_collapsed_into_a_count() -> None:
    attributes = " ".join(f'u{n}="1"' for n in range(100))
    result = parse_bml(bml(f'<faceLexeme id="a" lexeme="RAISE_BROWS" {attributes}/>'))
    assert len(result.warnings) == 4
    assert result.warnings[-1].message.endswith("(and 96 more like it)")


def test_warnings_over_the_limit_are_counted_in_one_last_warning() -> None:
    body = "".join(f'<faceLexeme id="f{n}" lexeme="X" odd="1"/>' for n in range(200))
    result = parse_bml(bml(body))
    limit = Limits().max_warnings
    assert len(result.warnings) == limit + 1
    assert f"{200 - limit} more warnings" in result.warnings[-1].message


# -- defect 7 (parser side): numbers are range-checked where they are read --------------


@pytest.mark.parametrize(
    "start",
    ["1e308", "bml:start+1e308", "1" * 400, "9e99", "-3601"],
)
def test_times_beyond_the_limit_refuse_the_block_with_the_reason(start: str) -> None:
    with pytest.raises(SyncRefError) as caught:
        parse_bml(bml(f'<faceLexeme id="a" lexeme="RAISE_BROWS" start="{start}"/>'))
    assert "limit" in caught.value.message or "not a number" in caught.value.message


def test_times_at_the_limit_are_read() -> None:
    ref = parse_sync_ref(f"bml:start+{MAX_SECONDS:g}")
    assert ref.offset == MAX_SECONDS
    assert parse_sync_ref(f"-{MAX_SECONDS:g}").offset == -MAX_SECONDS


def test_an_append_block_ending_at_1e308_is_refused() -> None:
    with pytest.raises(SyncRefError):
        parse_bml(
            bml(
                '<faceLexeme id="a" lexeme="RAISE_BROWS" end="1e308"/>',
                root_attributes=' composition="APPEND"',
            )
        )


@pytest.mark.parametrize("amount", ["1e308", "1e7", "-1e7"])
def test_numeric_attributes_beyond_their_magnitude_are_not_created(amount: str) -> None:
    result = parse_bml(bml(f'<faceLexeme id="a" lexeme="RAISE_BROWS" amount="{amount}"/>'))
    assert result.block.behaviours == ()
    assert result.warnings[0].type is WarningType.CANNOT_CREATE_BEHAVIOR


def test_iterations_are_bounded_before_they_are_converted() -> None:
    with pytest.raises(SyncRefError, match="limit"):
        parse_sync_ref("nod1:stroke:" + "9" * 5_000)
    assert parse_sync_ref(f"nod1:stroke:{MAX_ITERATION}").iteration == MAX_ITERATION


@pytest.mark.parametrize(
    "values", ["3=1e308", "3=" + "9" * 400, "99999999=1", "3=" + "1" * 5000 + "x"]
)
def test_fap_values_are_range_checked_in_linear_time(values: str) -> None:
    ns = 'xmlns:r="urn:realizer:bml:face-1.0"'
    result, seconds = timed(
        parse_bml,
        f'<bml xmlns="{BML_NS}" {ns} id="b"><r:fap id="f" values="{values}"/></bml>',
    )
    assert not isinstance(result, Exception), result
    assert result.block.behaviours == ()
    assert seconds < BOUND


def test_description_priorities_of_thousands_of_digits_are_refused() -> None:
    description = f'<description priority="{"9" * 5000}" type="x"/>'
    with pytest.raises(Exception, match="not an integer"):
        parse_bml(bml(f'<faceLexeme id="a" lexeme="X">{description}</faceLexeme>'))


# -- sync references per behaviour ---------------------------------------------------


def test_sync_markers_in_one_speech_are_limited() -> None:
    limits = Limits(max_sync_refs=3)
    three = "".join(f'<sync id="s{n}"/>w' for n in range(3))
    parse_bml(bml(f'<speech id="s"><text>{three}</text></speech>'), limits=limits)
    with pytest.raises(BmlSecurityError, match="more than 3"):
        parse_bml(
            bml(f'<speech id="s"><text>{three}<sync id="s9"/></text></speech>'), limits=limits
        )


def test_sync_references_in_one_relation_are_limited() -> None:
    limits = Limits(max_sync_refs=2)
    syncs = "".join(f'<sync ref="f{n}:start"/>' for n in range(3))
    with pytest.raises(BmlSecurityError, match="more than 2"):
        parse_bml(
            bml(f"<constraint><synchronize>{syncs}</synchronize></constraint>"), limits=limits
        )


@pytest.mark.parametrize("start", ["1e308", "bml:start+1e308", "1" * 400])
def test_realizer_schedule_reports_huge_times_without_a_traceback(
    start: str, tmp_path: Path
) -> None:
    path = tmp_path / "huge.xml"
    path.write_text(bml(f'<faceLexeme id="a" lexeme="RAISE_BROWS" start="{start}"/>'))
    done = subprocess.run(
        [sys.executable, "-m", "realizer", "schedule", str(path)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2
    assert "Traceback" not in done.stderr
    assert "limit" in done.stderr


def test_speech_text_is_limited_in_length() -> None:
    limits = Limits(max_speech_chars=20)
    parse_bml(bml('<speech id="s"><text>twenty characters!!</text></speech>'), limits=limits)
    with pytest.raises(BmlSecurityError, match="the limit is 20"):
        parse_bml(bml('<speech id="s"><text>twenty-one characters</text></speech>'), limits=limits)
