"""The face engine: timing preferences and animations of face, head and gaze behaviours."""

from __future__ import annotations

import math

import numpy as np
import pytest

from realizer.bml_parser import Behaviour, parse_bml
from realizer.engines.face import FaceEngine, parse_profile_choices
from realizer.face.convert.emotion import load_default_converter
from realizer.face.convert.errors import ConversionError
from realizer.face.convert.facs import facs_to_faps
from realizer.face.convert.lexemes import lexeme_faps
from realizer.face.convert.visemes import expression_faps, viseme_faps
from realizer.face.tracks import Envelope, FapAnimation, mix

HEAD = ("start", "ready", "strokeStart", "stroke", "strokeEnd", "relax", "end")


def behaviours(body: str) -> dict[str, Behaviour]:
    text = (
        '<bml xmlns="http://www.bml-initiative.org/bml/bml-1.0" '
        'xmlns:ext="http://www.bml-initiative.org/bml/coreextensions-1.0" '
        'xmlns:rf="urn:realizer:bml:face-1.0" id="b">' + body + "</bml>"
    )
    return {b.id: b for b in parse_bml(text).block.behaviours}


def face_times(start: float = 0.0) -> dict[str, float]:
    return {"start": start, "attackPeak": start + 0.5, "relax": start + 2.0, "end": start + 2.5}


ENGINE = FaceEngine.default()


def test_the_engine_handles_face_head_and_gaze_but_not_speech() -> None:
    found = behaviours(
        '<faceLexeme id="a" lexeme="RAISE_BROWS"/><head id="h" lexeme="NOD"/>'
        '<gaze id="g" target="camera"/><speech id="s"><text>hi</text></speech>'
    )
    assert [ENGINE.handles(found[k]) for k in "ahgs"] == [True, True, True, False]
    assert ENGINE.realize(found["s"], {"start": 0.0, "end": 1.0}) is None


def test_a_face_lexeme_follows_its_sync_points_and_amount() -> None:
    smile = behaviours('<faceLexeme id="a" lexeme="RAISE_MOUTH_CORNERS" amount="0.8"/>')["a"]
    animation = ENGINE.realize(smile, face_times(1.0))
    assert animation is not None and animation.priority == 2
    expected = lexeme_faps("RAISE_MOUTH_CORNERS", 0.8)
    assert mix([animation], 2.0)[0] == pytest.approx(expected.values)
    assert mix([animation], 1.25)[0] == pytest.approx(expected.values / 2)
    assert not mix([animation], 3.6)[1].any()


def test_face_facs_and_the_draft_face_form_use_the_facs_mapping() -> None:
    ext = behaviours('<ext:faceFacs id="f" au="12" side="LEFT" amount="0.8"/>')["f"]
    assert ENGINE.configuration(ext) == facs_to_faps(["12L:0.8"])
    draft = parse_bml(
        '<bml id="d"><face id="f" type="FACS" au="12" side="LEFT" amount="0.8"/></bml>'
    ).block.behaviours[0]
    assert ENGINE.configuration(draft) == facs_to_faps(["12L:0.8"])


def test_emotion_fap_viseme_and_expression_extensions() -> None:
    found = behaviours(
        '<rf:emotion id="e" word="guilty"/>'
        '<rf:emotion id="w" angle="146.7" activation="4" profile="surprise=1"/>'
        '<rf:fap id="f" values="3=400 53=150,54=150" amount="0.5" curve="hermite"/>'
        '<rf:viseme id="v" viseme1="10" viseme2="p" blend="21"/>'
        '<rf:expression id="x" expression1="joy" intensity1="42" expression2="6" intensity2="21"/>'
    )
    converter = load_default_converter()
    assert ENGINE.configuration(found["e"]) == converter.for_word("guilty").configuration()
    wheel = converter.for_point(146.7, 4.0, choices={"surprise": 1}).configuration()
    assert ENGINE.configuration(found["w"]) == wheel
    assert ENGINE.configuration(found["f"]).as_dict() == {3: 200.0, 53: 75.0, 54: 75.0}
    assert ENGINE.configuration(found["v"]) == viseme_faps(10, 1, 21)
    assert ENGINE.configuration(found["x"]) == expression_faps(1, 42, 6, 21)
    fap = ENGINE.realize(found["f"], face_times())
    assert fap is not None and fap.priority == 3 and fap.blend == "replace"


def test_bad_parameters_are_conversion_errors_naming_the_behaviour() -> None:
    found = behaviours(
        '<faceLexeme id="a" lexeme="SMIRK"/><rf:emotion id="e" word="boredom"/>'
        '<rf:fap id="f" values="3:400"/>'
        '<head id="h" lexeme="WOBBLE"/>'
    )
    for key in "aef":
        with pytest.raises(ConversionError, match=repr(key)):
            ENGINE.configuration(found[key])
    with pytest.raises(ConversionError, match="WOBBLE"):
        ENGINE.realize(found["h"], dict(zip(HEAD, range(7), strict=True)))


def test_a_nod_goes_down_at_each_stroke_on_fap_48() -> None:
    nod = behaviours('<head id="n" lexeme="NOD" repetition="3" amount="1"/>')["n"]
    assert nod.syncs[3:6] == ("stroke", "stroke:2", "stroke:3")
    times = {
        "start": 0.0, "ready": 0.1, "strokeStart": 0.2, "stroke": 0.4, "stroke:2": 0.8,
        "stroke:3": 1.2, "strokeEnd": 1.4, "relax": 1.5, "end": 1.7,
    }  # fmt: skip
    animation = ENGINE.realize(nod, times)
    assert animation is not None
    for t in (0.4, 0.8, 1.2):
        values, mask = mix([animation], t)
        assert values[47] == pytest.approx(30000) and mask.sum() == 1
    assert mix([animation], 0.6)[0][47] < 0  # back up between strokes
    assert mix([animation], 1.7)[0][47] == pytest.approx(0)


def test_shake_turns_both_ways_and_tilt_holds_until_relax() -> None:
    found = behaviours(
        '<head id="s" lexeme="SHAKE" amount="0.5"/><head id="t" lexeme="TILT" amount="-1"/>'
    )
    times = dict(zip(HEAD, [0.0, 0.1, 0.2, 0.4, 0.8, 1.5, 2.0], strict=True))
    shake = ENGINE.realize(found["s"], times)
    tilt = ENGINE.realize(found["t"], times)
    assert shake is not None and tilt is not None
    assert mix([shake], 0.4)[0][48] == pytest.approx(20000)  # yaw left at the stroke
    assert mix([shake], 0.6)[0][48] == pytest.approx(-20000)  # then right
    assert mix([tilt], 1.0)[0][49] == pytest.approx(-30000)  # negative amount: other side
    assert mix([tilt], 1.5)[0][49] == pytest.approx(-30000)


def test_gaze_turns_the_eyes_and_by_influence_the_head() -> None:
    found = behaviours(
        '<gaze id="e" target="camera" influence="EYES" offsetAngle="10" offsetDirection="LEFT"/>'
        '<gazeShift id="n" target="x" influence="NECK" offsetAngle="40" offsetDirection="UPRIGHT"/>'
    )
    look = ENGINE.realize(found["e"], {"start": 0.0, "ready": 0.2, "relax": 1.0, "end": 1.2})
    assert look is not None
    values, mask = mix([look], 0.5)
    assert values[22] == pytest.approx(10 * math.pi / 180 * 1e5)  # yaw_l_eyeball, left
    assert set(np.flatnonzero(mask) + 1) == {23, 24, 25, 26}
    shift = ENGINE.realize(found["n"], {"start": 0.0, "end": 0.5})
    assert shift is not None and shift.end == math.inf  # a gaze shift holds
    values, mask = mix([shift], 100.0)
    assert values[48] < 0 and values[47] < 0  # head yaw right, pitch up
    assert abs(values[22]) <= 15 * math.pi / 180 * 1e5 + 1e-6  # eyes up to their share


def test_face_shift_holds_after_its_end() -> None:
    shift = behaviours('<faceShift id="s" lexeme="RAISE_MOUTH_CORNERS" amount="0.3"/>')["s"]
    animation = ENGINE.realize(shift, {"start": 0.0, "end": 0.4})
    assert animation is not None
    assert mix([animation], 50.0)[0] == pytest.approx(
        lexeme_faps("RAISE_MOUTH_CORNERS", 0.3).values
    )


def test_timing_preferences_cover_every_phase_including_repetitions() -> None:
    found = behaviours(
        '<faceLexeme id="a" lexeme="RAISE_BROWS"/><head id="n" lexeme="NOD" repetition="3"/>'
        '<gaze id="g" target="camera"/><gazeShift id="s" target="camera"/>'
        '<rf:viseme id="v" viseme1="1"/>'
    )
    for behaviour in found.values():
        timing = ENGINE.timing(behaviour)
        assert len(timing.phases) == len(timing.syncs) - 1
        assert all(p.preferred >= 0 and p.weight > 0 for p in timing.phases)
    nod = ENGINE.timing(found["n"])
    assert nod.syncs.index("stroke:3") - nod.syncs.index("stroke") == 2
    repeat = nod.phases[3]  # stroke -> stroke:2 and stroke:2 -> stroke:3 are repeats
    assert nod.phases[4] == repeat and repeat.preferred > nod.phases[2].preferred
    assert (
        ENGINE.timing(found["v"]).phases[0].preferred
        < ENGINE.timing(found["a"]).phases[0].preferred
    )


def test_profile_choices_parse() -> None:
    assert parse_profile_choices("fear=8, joy=1") == {"fear": 8, "joy": 1}
    with pytest.raises(ConversionError):
        parse_profile_choices("boredom=2")


def test_default_limits_come_from_the_fap_table_of_seed_002() -> None:
    from realizer.engines.face import default_limits

    limits = default_limits()
    assert (limits.lower[2], limits.upper[2]) == (0.0, 4320.0)  # open_jaw: U, 1080 * QP 4
    assert (limits.lower[18], limits.upper[18]) == (-1080.0, 1080.0)  # close_t_l_eyelid
    # two full eye closures clamp at the eyelid's range instead of doubling
    closing = FapAnimation(facs_to_faps(["43"]), Envelope(0, 0, 1, 1))
    values, _ = mix([closing, closing], 0.5, limits)
    assert values[18] == 1080.0


def test_planning_refuses_what_cannot_be_realized_with_a_timing_model_error() -> None:
    from realizer.scheduler.timing import TimingModelError

    found = behaviours('<faceLexeme id="a" lexeme="SMIRK"/><faceLexeme id="b" lexeme="OPEN_LIPS"/>')
    with pytest.raises(TimingModelError, match="SMIRK"):
        ENGINE.plan(found["a"])
    model = ENGINE.plan(found["b"])
    assert model.syncs == ("start", "attackPeak", "relax", "end") and len(model.phases) == 3


def test_the_draft_gaze_names_its_offset_angle_and_direction() -> None:
    draft = parse_bml(
        '<bml id="d"><gaze id="g" target="x" angle="20" direction="LEFT" influence="EYES"/></bml>'
    ).block.behaviours[0]
    look = ENGINE.realize(draft, {"start": 0.0, "ready": 0.2, "relax": 1.0, "end": 1.2})
    assert look is not None
    assert mix([look], 0.5)[0][22] == pytest.approx(20 * math.pi / 180 * 1e5)
