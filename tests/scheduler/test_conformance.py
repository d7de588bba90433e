"""The scheduler against the conformance corpus of saiba/OpenBMLParser, file by file.

Each document's header states its ``Required timing:`` (or ``Expected
timing:``). :data:`REQUIRED` restates every header as checks in a tiny
language (``a:sync[+k] = b:sync[+k] = 4``, ``<``, ``>``, ``<=``, ``>=``), so
that a reader can hold each line beside its header. Timings that depend on
speech are orderings and equalities, never seconds from our speech model.
Where a header contradicts its own document (a copy-paste slip, swapped
ends), the document wins and the comment says what the header said.
Documents whose header asks for a removal or an error are in
:data:`INVALID` with the warnings they must give.
"""

from __future__ import annotations

import itertools
import re

import pytest

from realizer.bml_parser import BmlError, WarningType, parse_bml
from realizer.engines import EngineRegistry
from realizer.scheduler.plan import SchedulingFailed, TimedPlan, schedule_block
from tests.conftest import conformance_files

FILES = {p.name: p for p in conformance_files()}
if not FILES:
    pytest.skip("conformance corpus not available", allow_module_level=True)

#: Seconds; the solver is exact, this only absorbs float round-off.
TOLERANCE = 1e-6

#: Per document: the checks its header's timing section states.
REQUIRED: dict[str, list[str]] = {
    # "Required timing: none"; the <after> constraints must still hold.
    "after.xml": ["speech1:sync4 <= beat1:stroke+2", "speech1:sync4 <= nod1:stroke"],
    "after2.xml": ["speech1:sync4+1 <= beat1:stroke+2", "speech1:sync4+1 <= nod1:stroke"],
    "after_required.xml": ["speech1:sync4 <= beat1:stroke+2", "speech1:sync4 <= nod1:stroke"],
    "afterunify.xml": [
        "speech1:sync4 <= beat1:stroke+2",
        "speech1:sync4 <= nod1:stroke",
        "speech1:sync4 <= beat1:end+5",
        "speech1:sync4 <= nod1:end+6",
    ],
    "afterunify_offset.xml": [
        "speech1:sync4 <= beat1:stroke+2",
        "speech1:sync4 <= nod1:stroke",
        "speech1:sync4+5 <= beat1:end",
        "speech1:sync4+5 <= nod1:end+1",
    ],
    "before.xml": ["beat1:stroke+2 <= speech1:sync4", "nod1:stroke <= speech1:sync4"],
    "empty.xml": [],
    "testabs.xml": ["nod1:start = 1", "g1:start = 1", "speech1:start = 1"],
    # The header says beat1:end = 5; the document (and the header's own
    # Constraints) say end="7", and "stroke-end"/"nod" are strokeEnd/nod1.
    "testbeatandnod.xml": ["beat1:start = 3", "beat1:end = 7", "beat1:strokeEnd = nod1:start"],
    "testbeatreadytimed.xml": ["beat1:start = 1", "beat1:ready = 2"],
    "testgazereadytimed.xml": ["gaze1:ready = 3", "gaze1:end = 10"],
    "testgazeshift.xml": ["shift1:start = 0", "shift1:end = 3"],
    "testhead_selftimed.xml": ["shake1:start = 0", "shake1:end = 1"],
    "testnod.xml": ["nod1:start = 0"],
    # The header says nod1:end = 3; the document starts nod2 at 3.
    "testnod2x_absolute.xml": ["nod1:start = 1", "nod2:start = 3"],
    # The header swapped the two times; the document says start="0" end="2".
    "testnod_absolute.xml": ["nod1:start = 0", "nod1:end = 2"],
    "testnod_offset.xml": ["nod1:start = 0", "nod2:start = 2"],
    "testnodandbeat.xml": ["nod1:start = 3", "nod1:end = 5", "nod1:stroke = beat1:start"],
    "testnodandbeat_switchedorder.xml": [
        "nod1:start = 3",
        "nod1:end = 5",
        "nod1:stroke = beat1:start",
    ],
    "testnods.xml": ["nod1:start = 1", "tilt1:start = nod1:end+1", "nod1:end > nod1:start"],
    "testoffset.xml": [
        "g1:start = 4",
        "g2:end = 4",
        "g2:start = 3",
        "h1:start = g1:end",
        "h1:start > 4",
    ],
    "testoffset2.xml": [
        "g1:start = 4",
        "g2:end = 5",
        "g2:start = 3",
        "h1:start = g1:end",
        "h1:start > 4",
    ],
    "testoffset3.xml": [
        "g1:start = 4",
        "g2:end = 5",
        "g2:start = 3",
        "h1:start = g1:end",
        "h1:start > 4",
        "gaze1:start = 1",
        "gaze1:end = g1:end+3",
        "gaze1:end > 7",
    ],
    "testoffsetchain.xml": ["h1:start = 4", "h2:start = 6", "h3:start = 8", "h4:start = 10"],
    # The header's "h2:end = h1:end" is h2:start = h1:end in the document.
    "testoffsetchainneg.xml": [
        "speech1:start = 0",
        "h1:start = speech1:s1",
        "speech1:s1 > 0",
        "h2:start = h1:end",
        "h1:end > h1:start",
        "h3:start = h2:end",
        "h2:end > h2:start",
        "h4:start = h3:end",
        "h3:end > h3:start",
    ],
    # The header's "h2:end = 6" is h2:start (start="h3:start-2").
    "testoffsetchainreversed.xml": [
        "h1:start = 4",
        "h2:start = 6",
        "h3:start = 8",
        "h4:start = 10",
    ],
    # Speech has no ready; the document ties speech1's start to gaze1:ready.
    "testoffsetgaze.xml": ["speech1:start > 2", "gaze1:start = 2", "gaze1:ready = speech1:start"],
    "testoffsetgaze2.xml": [
        "speech1:start > 2",
        "gaze1:start = 2",
        "gaze1:ready = speech1:start",
    ],
    "testpostureshift.xml": ["shift1:start = 0", "shift1:end = 3"],
    "testrequiredbeh.xml": ["h1:start = 4", "h2:start = 6", "h3:start = 8", "h4:start = 10"],
    "testspeech3x.xml": [
        "speech10:start = 4",
        "speech11:start = speech10:end+4",
        "speech12:start = speech11:end+4",
    ],
    "testspeech_2linked.xml": ["speech1:start = 0", "speech1:end = speech2:start"],
    "testspeech_endtimed.xml": ["speech1:end = 5", "speech1:start < 5"],
    "testspeech_gesturestart.xml": ["g1:start = 0", "g1:stroke = speech1:this"],
    "testspeech_nodtimedtosync.xml": [
        "speech1:start = 6",
        "speech1:syncstart1 = nod1:start",
        "nod1:end = 9",
    ],
    # The header was copied from testspeech_nodtimedtosync.xml; the ids are capitalised.
    "testspeech_nodtimedtosync_capitalization.xml": [
        "speech1WithCapitalizedStuff:start = 6",
        "speech1WithCapitalizedStuff:syncStart_1 = nod1WithCapitalizedStuff:start",
        "nod1WithCapitalizedStuff:end = 9",
    ],
    "testspeech_nodtimedtosyncinverseorder.xml": [
        "speech1:start = 6",
        "speech1:syncstart1 = nod1:start",
        "nod1:end = 9",
    ],
    "testspeech_nodtimedtosyncoffset.xml": [
        "speech1:start = 6",
        "speech1:syncstart1+1 = nod1:start",
        "nod1:end = 9",
    ],
    # The header names the speech "speech1"; the document calls it "welkom".
    "testspeech_syncatstart.xml": ["welkom:start = 0", "welkom:deicticheart1 = welkom:start"],
    "testspeech_syncatstartandtobeat.xml": [
        "welkom:start = 0",
        "g1:start = welkom:deicticheart1",
        "g1:end = welkom:deicticheart1+2",
    ],
    "testspeech_synctimed.xml": ["speech1:s1 = 10", "speech1:start < 10"],
    "testspeech_synctimed2x.xml": [
        "speech1:s1 = 10",
        "speech1:start < 10",
        "speech2:s1 = 20",
        "speech2:start < 20",
    ],
    "testspeech_synctimed2x_required.xml": [
        "speech1:s1 = 10",
        "speech1:start < 10",
        "speech2:s1 = 20",
        "speech2:start < 20",
    ],
    "testspeechandnod_synctimed.xml": [
        "speech1:s1 = 10",
        "speech1:start = nod1:start",
        "speech1:start < 10",
        "speech1:end > 10",
    ],
    "testspeechgestures.xml": [
        "g1:start = welkom:deicticheart1 = transleft:end-1 = 1",
        "g1:end = welkom:deicticheart1+2 = 3",
        "relaxleft:start = g1:end+0.5 = 3.5",
        "relaxleft:end = g1:end+2.8 = 5.8",
        "transleft:start = g1:start-1 = 0",
    ],
    "testspeechrel_offsets.xml": [
        "speech1:start = 4",
        "speech2:start = speech1:end+5",
        "nod2:start = speech1:start-2",
        "nod2:end = speech2:end+3",
    ],
    "testtimeshift.xml": ["speech1:start = nod1:end", "nod1:start = 0"],
    # The header's "w1:stroke" is the wait's end (<wait> has only start and end).
    "waitdoublesync.xml": [
        "w1:start = speech1:start = 0",
        "w1:end = speech1:end = speech2:start",
    ],
}

#: Per document: (warning type, behaviour removed or None, text the message names).
INVALID: dict[str, tuple[WarningType, str | None, str]] = {
    "testnod_invalidtime.xml": (WarningType.IMPOSSIBLE_TO_SCHEDULE, "nod1", "nod1"),
    "testspeech_invalidtime.xml": (WarningType.IMPOSSIBLE_TO_SCHEDULE, "speech1", "speech1"),
    # end="0.1": far too short for the sentence.
    "testspeech_endtimed2.xml": (WarningType.IMPOSSIBLE_TO_SCHEDULE, "speech1", "speech1"),
    # "Hello" cannot be squeezed into 0.01 s, nor stretched to 10 s.
    "testspeech_invalidtimesync.xml": (WarningType.IMPOSSIBLE_TO_SCHEDULE, "speech1", "speech1"),
    "testspeech_invalidtimesync2.xml": (WarningType.IMPOSSIBLE_TO_SCHEDULE, "speech1", "speech1"),
    # "Error: unknownbeh not found": the reference goes, the speech stays.
    "testspeech_unknownbehavior.xml": (WarningType.NO_SUCH_TARGET, None, "unknownbeh"),
    # nod1:start = speech1:unknown cannot hold: there is no such sync point.
    "testspeech_unknownsync.xml": (WarningType.NO_SUCH_TARGET, None, "unknown"),
}

#: Broken documents: refused before scheduling with PARSING_FAILURE.
UNPARSABLE = {"testinvalidxml.xml", "testinvalidxml2.xml", "testnod_unknownattributes.xml"}

_TERM = re.compile(
    r"^(?:(?P<behaviour>[\w.]+):(?P<sync>[\w.]+(?::\d+)?))?\s*(?P<offset>[+-]?\s*[\d.]+)?$"
)
_RELATION = re.compile(r"(<=|>=|=|<|>)")


def schedule(name: str) -> TimedPlan:
    result = parse_bml(FILES[name].read_bytes(), source=name)
    return schedule_block(
        result.block,
        registry=EngineRegistry.standard(),
        dropped=result.dropped,
        warnings=result.warnings,
    )


def value(plan: TimedPlan, term: str) -> float:
    match = _TERM.match(term.strip())
    assert match is not None, f"cannot read {term!r}"
    offset = float(match["offset"].replace(" ", "")) if match["offset"] else 0.0
    if match["behaviour"] is None:
        return offset
    time = plan.time_of(match["behaviour"], match["sync"])
    assert time is not None, f"{match['behaviour']}:{match['sync']} is not in the schedule"
    return time + offset


def check(plan: TimedPlan, line: str) -> None:
    parts = _RELATION.split(line)
    values = [value(plan, term) for term in parts[::2]]
    for (left, right), op in zip(itertools.pairwise(values), parts[1::2], strict=True):
        held = {
            "=": abs(left - right) <= TOLERANCE,
            "<": left < right - TOLERANCE,
            ">": left > right + TOLERANCE,
            "<=": left <= right + TOLERANCE,
            ">=": left >= right - TOLERANCE,
        }[op]
        assert held, f"{line!r}: {left:.6f} {op} {right:.6f} does not hold"


def test_every_document_of_the_corpus_is_covered() -> None:
    assert set(FILES) == set(REQUIRED) | set(INVALID) | UNPARSABLE


@pytest.mark.parametrize("name", sorted(REQUIRED))
def test_document_meets_its_required_timing(name: str) -> None:
    plan = schedule(name)
    assert plan.dropped == frozenset()
    # Only "scheduled but not shown" may be said (testhead_selftimed's head
    # lexeme "Y" is not one the face engine animates).
    assert [w for w in plan.warnings if w.type is not WarningType.CANNOT_CREATE_BEHAVIOR] == []
    for line in REQUIRED[name]:
        check(plan, line)


@pytest.mark.parametrize("name", sorted(REQUIRED))
def test_document_keeps_canonical_order_and_the_block_start(name: str) -> None:
    plan = schedule(name)
    for scheduled in plan.behaviours:
        model = plan.models[scheduled.id]
        times = [scheduled.times[sync] for sync in model.syncs]
        assert all(b >= a - TOLERANCE for a, b in itertools.pairwise(times)), scheduled.id
        assert min(times) >= plan.start - TOLERANCE
        for (sync_a, sync_b), phase in zip(
            itertools.pairwise(model.syncs), model.phases, strict=True
        ):
            duration = scheduled.times[sync_b] - scheduled.times[sync_a]
            assert phase.minimum - TOLERANCE <= duration <= phase.maximum + TOLERANCE


@pytest.mark.parametrize("name", sorted(INVALID))
def test_invalid_document_gives_the_warning_its_header_names(name: str) -> None:
    kind, removed, named = INVALID[name]
    plan = schedule(name)
    assert [w.type for w in plan.warnings] == [kind]
    assert named in plan.warnings[0].message
    if removed is None:
        assert plan.dropped == frozenset()
        assert len(plan.behaviours) == len(plan.block.behaviours)
    else:
        assert plan.dropped == {removed}
        assert removed not in {b.id for b in plan.behaviours}


def test_an_unknown_reference_leaves_the_behaviour_untied() -> None:
    # testspeech_unknownsync: nod1 keeps its own timing, from the block start.
    plan = schedule("testspeech_unknownsync.xml")
    assert plan.time_of("nod1", "start") == pytest.approx(0.0, abs=TOLERANCE)


@pytest.mark.parametrize("name", sorted(UNPARSABLE))
def test_broken_document_never_reaches_the_scheduler(name: str) -> None:
    with pytest.raises(BmlError) as caught:
        parse_bml(FILES[name].read_bytes(), source=name)
    assert caught.value.warning_type is WarningType.PARSING_FAILURE


def test_a_behaviour_a_required_constraint_refers_to_is_not_removed_the_block_fails() -> None:
    # after_required.xml plus a required <before>: nod1's stroke must come
    # after speech1:sync4 and before speech1's start, which only the speech's
    # own (not required) timing prevents. Removing the speech would run the
    # required constraints with their references to it dropped, so the block
    # fails instead, naming what conflicts.
    text = (
        FILES["after_required.xml"]
        .read_text()
        .replace(
            "</bml>",
            '<required><constraint id="early"><before ref="speech1:start">'
            '<sync ref="nod1:stroke"/></before></constraint></required></bml>',
        )
    )
    with pytest.raises(SchedulingFailed) as caught:
        schedule_block(parse_bml(text).block, registry=EngineRegistry.standard())
    [warning] = caught.value.warnings
    assert warning.type is WarningType.IMPOSSIBLE_TO_SCHEDULE and warning.id == "bml1"
    assert "<before> of constraint 'early'" in warning.message
    assert "'speech1' cannot be removed because a required part refers to it" in warning.message


def pin(constraint_id: str, seconds: float) -> str:
    """A constraint that ties nod1's start to an absolute time."""
    return (
        f'<constraint id="{constraint_id}"><synchronize><sync ref="nod1:start"/>'
        f'<sync ref="{seconds:g}"/></synchronize></constraint>'
    )


def test_required_constraints_that_contradict_each_other_fail_the_block() -> None:
    nod = FILES["testnod.xml"].read_text()
    text = nod.replace("</bml>", f"<required>{pin('one', 1)}{pin('two', 2)}</required></bml>")
    with pytest.raises(SchedulingFailed) as caught:
        schedule_block(parse_bml(text).block, registry=EngineRegistry.standard())
    assert caught.value.warning_type is WarningType.IMPOSSIBLE_TO_SCHEDULE
    assert caught.value.block_id == "bml1"
    assert [w.type for w in caught.value.warnings] == [WarningType.IMPOSSIBLE_TO_SCHEDULE]
    assert "one" in caught.value.message and "two" in caught.value.message


def test_a_contradicting_constraint_that_is_not_required_is_dropped_by_name() -> None:
    nod = FILES["testnod.xml"].read_text()
    text = nod.replace("</bml>", f"<required>{pin('one', 1)}</required>{pin('two', 2)}</bml>")
    plan = schedule_block(parse_bml(text).block, registry=EngineRegistry.standard())
    assert plan.time_of("nod1", "start") == pytest.approx(1.0, abs=TOLERANCE)
    assert [(w.type, w.id) for w in plan.warnings] == [
        (WarningType.IMPOSSIBLE_TO_SCHEDULE, "bml1:two")
    ]
    assert "'two'" in plan.warnings[0].message
