"""headDirectionShift turns the head to its target and keeps it there (the
face engine, realizer.engines.face), with the scene's targets."""

from __future__ import annotations

import pytest

from realizer.bml_parser import BML_NS
from realizer.service.stage import Stage
from realizer.session import Session

#: FAP 48 head_pitch and FAP 49 head_yaw (positive: to the left), indices of a FAP vector
HEAD_PITCH, HEAD_YAW = 47, 48
#: 20 degrees in FAPU angle units (1e-5 rad)
TWENTY_DEGREES = 20 * 3.141592653589793 / 180 * 1e5


def values(session: Session, t: float) -> tuple[float, float]:
    session.tick(t)
    frame = session.frame(t).values
    return float(frame[HEAD_PITCH]), float(frame[HEAD_YAW])


def test_the_head_turns_by_the_stroke_and_stays_turned() -> None:
    session = Session("x")
    plan = session.receive_bml(
        f'<bml xmlns="{BML_NS}" id="b"><headDirectionShift id="h" target="LEFT"/></bml>', 0.0
    )
    assert plan is not None and plan.warnings == ()
    times = plan.behaviours[0].times
    assert values(session, 0.0) == (0.0, 0.0)
    assert values(session, times["stroke"])[1] == pytest.approx(TWENTY_DEGREES)
    assert values(session, times["end"] + 5.0) == (0.0, pytest.approx(TWENTY_DEGREES))


def test_a_gaze_turns_the_head_its_way_while_it_lasts_and_a_nod_adds() -> None:
    session = Session("x")
    session.receive_bml(
        f'<bml xmlns="{BML_NS}" id="b"><headDirectionShift id="h" target="LEFT"/>'
        '<gaze id="g" target="RIGHT" influence="HEAD" start="1" ready="1.2" relax="1.8" end="2"/>'
        '<head id="n" lexeme="NOD" start="3"/></bml>',
        0.0,
    )
    assert values(session, 1.5)[1] < 0  # the gaze, to the right
    assert values(session, 2.5)[1] == pytest.approx(TWENTY_DEGREES)  # back to the rest
    pitch, yaw = values(session, 3.3)
    assert pitch != 0 and yaw == pytest.approx(TWENTY_DEGREES)


def test_the_head_turns_towards_a_character_of_the_scene() -> None:
    stage = Stage(lambda character: Session(character))
    stage.character("Ann")
    stage.character("Bob")  # beside Ann, on her left (protocols/scene.md)
    stage.submit_bml(
        f'<bml xmlns="{BML_NS}" id="b" characterId="Ann">'
        '<headDirectionShift id="h" target="Bob"/></bml>',
        0.0,
    )
    stage.tick(2.0)
    yaw = stage.characters["Ann"].session.frame(2.0).values[HEAD_YAW]
    assert yaw > 0
