"""The schedule of every corpus document meets its ``Required timing`` header.

Headers state equalities and orderings such as
``g1:start = welkom:deicticheart1 = transleft:end-1 = 1`` or
``gaze1:end = g1:end+3 > 7``; speech-dependent times are checked as the
orderings and equalities the header states, whatever the speech timing.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from realizer.bml_parser import WarningType, parse_bml
from realizer.engines import EngineRegistry
from realizer.scheduler.plan import schedule_block
from tests.bml_parser.test_conformance import REJECTED, header, header_section
from tests.conftest import conformance_files

REGISTRY = EngineRegistry.standard()
FILES = [p for p in conformance_files() if p.name not in REJECTED]
if not FILES:
    pytest.skip("conformance corpus not available", allow_module_level=True)

#: Header typos, corrected against the documents (each checked by hand).
ERRATA: dict[str, dict[str, str]] = {
    # The document says end="7" (and its own Constraints section says 7).
    "testbeatandnod.xml": {"beat1:end = 5": "beat1:end = 7",
                           "beat1:stroke-end = nod:start": "beat1:strokeEnd = nod1:start"},
    "testspeech_syncatstartandtobeat.xml": {"welcom:": "welkom:"},
    # nod2 starts at 3; nothing ties nod1's end to 3.
    "testnod2x_absolute.xml": {"nod1:end = 3": "nod2:start = 3"},
    # The document says start="0" end="2"; the header was copied from
    # testnod_invalidtime.xml.
    "testnod_absolute.xml": {"nod1:start = 2": "nod1:start = 0", "nod1:end = 0": "nod1:end = 2"},
    # h2 starts (start="h1:end") where h1 ends, as in the sibling documents.
    "testoffsetchainneg.xml": {"h2:end   = h1:end": "h2:start = h1:end"},
    "testoffsetchainreversed.xml": {"h2:end   = 6": "h2:start = 6"},
    # Speech has no ready; the document says speech1 start="gaze1:ready".
    "testoffsetgaze.xml": {"speech1:ready": "speech1:start"},
    "testoffsetgaze2.xml": {"speech1:ready": "speech1:start"},
    # The document's speech is "welkom".
    "testspeech_syncatstart.xml": {"speech1:start": "welkom:start"},
    "testspeechrel_offsets.xml": {";": ""},
    "testspeech_nodtimedtosync_capitalization.xml": {
        "speech1:syncstart1": "speech1WithCapitalizedStuff:syncStart_1",
        "speech1:start": "speech1WithCapitalizedStuff:start",
        "nod1:start": "nod1WithCapitalizedStuff:start",
        "nod1:end": "nod1WithCapitalizedStuff:end",
    },
}  # fmt: skip

_TERM = re.compile(r"^(?:(?P<ref>[\w.]+:[\w.]+)\s*(?P<off>[+-]\s*[0-9.]+)?|(?P<num>[0-9.]+))$")


def timing_lines(path: Path) -> list[str]:
    text = header(path)
    lines = header_section(text, "Required timing") or header_section(text, "Expected timing")
    fixes = ERRATA.get(path.name, {})
    out = []
    for line in lines:
        for wrong, right in fixes.items():
            line = line.replace(wrong, right)
        if line.lower() in ("none", "-") or line.startswith(("Error", "Warning")):
            continue
        out.append(line.replace(",", " "))
    return out


def relations(line: str) -> list[tuple[str, str, str]]:
    """``a = b > c`` -> [(a, '=', b), (b, '>', c)]."""
    parts = re.split(r"\s*([=<>])\s*", line.strip())
    terms, ops = parts[0::2], parts[1::2]
    return [(terms[i].strip(), ops[i], terms[i + 1].strip()) for i in range(len(ops))]


def value(term: str, times: dict[tuple[str, str], float]) -> float | None:
    match = _TERM.match(term.replace(" ", ""))
    assert match is not None, f"cannot read header term {term!r}"
    if match.group("num"):
        return float(match.group("num"))
    behaviour, sync = match.group("ref").split(":")
    if (behaviour, sync) not in times:
        return None
    offset = float(match.group("off").replace(" ", "")) if match.group("off") else 0.0
    return times[(behaviour, sync)] + offset


REMOVES = {p.name for p in FILES if "behaviour should be removed" in header(p)
           or "should be omitted" in header(p)}  # fmt: skip
TIMED = [p for p in FILES if timing_lines(p) and p.name not in REMOVES]


def test_the_corpus_has_many_documents_with_required_timing() -> None:
    assert len(TIMED) >= 35


@pytest.mark.parametrize("path", TIMED, ids=lambda p: p.name)
def test_schedule_meets_the_required_timing(path: Path) -> None:
    result = parse_bml(path.read_bytes(), source=path.name)
    plan = schedule_block(
        result.block, registry=REGISTRY, dropped=result.dropped, warnings=result.warnings
    )
    times = {(s.id, sync): t for s in plan.behaviours for sync, t in s.times.items()}
    checked = 0
    for line in timing_lines(path):
        for left, op, right in relations(line):
            a, b = value(left, times), value(right, times)
            if a is None or b is None:
                # only the corpus's deliberately unknown sync point may be missing
                assert path.name == "testspeech_unknownsync.xml", (left, right)
                continue
            if op == "=":
                assert a == pytest.approx(b, abs=1e-6), f"{line}: {left}={a} {right}={b}"
            elif op == ">":
                assert a > b - 1e-9, f"{line}: {left}={a} not > {right}={b}"
            else:
                assert a < b + 1e-9, f"{line}: {left}={a} not < {right}={b}"
            checked += 1
    assert checked or path.name == "testspeech_unknownsync.xml"


@pytest.mark.parametrize("name", sorted(REMOVES))
def test_behaviours_whose_timing_is_impossible_are_removed_with_a_warning(name: str) -> None:
    path = next(p for p in FILES if p.name == name)
    result = parse_bml(path.read_bytes(), source=name)
    plan = schedule_block(
        result.block, registry=REGISTRY, dropped=result.dropped, warnings=result.warnings
    )
    assert plan.behaviours == ()
    assert plan.dropped == {"speech1"} or plan.dropped == {"nod1"}
    assert [w.type for w in plan.warnings] == [WarningType.IMPOSSIBLE_TO_SCHEDULE]


def test_the_corpus_names_its_impossible_timings() -> None:
    assert {
        "testnod_invalidtime.xml",
        "testspeech_invalidtime.xml",
        "testspeech_invalidtimesync.xml",
        "testspeech_invalidtimesync2.xml",
        "testspeech_endtimed2.xml",
    } == REMOVES


@pytest.mark.parametrize(
    ("name", "missing"),
    [("testspeech_unknownbehavior.xml", "unknownbeh"), ("testspeech_unknownsync.xml", "unknown")],
)
def test_references_to_unknown_targets_are_warned_about(name: str, missing: str) -> None:
    path = next(p for p in FILES if p.name == name)
    result = parse_bml(path.read_bytes(), source=name)
    plan = schedule_block(result.block, registry=REGISTRY)
    (note,) = plan.warnings
    assert note.type is WarningType.NO_SUCH_TARGET
    assert missing in note.message
    assert plan.behaviours  # the rest of the block still runs


def test_required_timing_is_met_in_the_required_variant_too() -> None:
    path = next(p for p in FILES if p.name == "testspeech_synctimed2x_required.xml")
    result = parse_bml(path.read_bytes())
    plan = schedule_block(result.block, registry=REGISTRY)
    assert plan.time_of("speech1", "s1") == pytest.approx(10.0, abs=1e-6)
    assert plan.time_of("speech2", "s1") == pytest.approx(20.0, abs=1e-6)
