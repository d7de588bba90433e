"""Lip sync from the real eSpeak NG's phonemes, in a session's FAP frames."""

from __future__ import annotations

import numpy as np
import pytest

from realizer.bml_parser import BML_NS
from realizer.engines import EngineRegistry
from realizer.engines.speech import SpeechEngine
from realizer.engines.speech.lipsync import load_lip_model, mouth_opening
from realizer.session import Session

RF = (
    'xmlns:rf="urn:realizer:bml:face-1.0" '
    'xmlns:ext="http://www.bml-initiative.org/bml/coreextensions-1.0"'
)
SENTENCE = "Peter bought my five vans and a big map."


def speaking(
    extra: str = "", text: str = SENTENCE, registry: EngineRegistry | None = None
) -> tuple[Session, SpeechEngine]:
    session = Session("a", registry=registry)
    engine = next(e for e in session.registry.engines if isinstance(e, SpeechEngine))
    assert engine.backend is not None, engine.unavailable
    session.receive_bml(
        f'<bml xmlns="{BML_NS}" {RF} id="b"><speech id="s" start="0"><text>{text}</text></speech>'
        f"{extra}</bml>",
        now=0.0,
    )
    return session, engine


def realized_phonemes(session: Session) -> list[tuple[str, float, float]]:
    plan = session.plan("b")
    assert plan is not None
    engine = next(e for e in session.registry.engines if isinstance(e, SpeechEngine))
    realization = engine.realize(plan.behaviours[0].behaviour, plan.behaviours[0].times)
    return list(realization.phonemes)


def opening_at(session: Session, t: float) -> float:
    return float(mouth_opening(session.frame(t).values))


def test_the_lips_close_on_p_b_m_and_open_on_vowels() -> None:
    session, _ = speaking()
    lead = load_lip_model().lead
    phonemes = realized_phonemes(session)
    closures = [p for p in phonemes if p[0] in ("p", "b", "m")]
    vowels = [p for p in phonemes if p[0] in ("iː", "ɔː", "aɪ", "a", "ɪ")]
    assert len(closures) >= 5 and len(vowels) >= 5
    for symbol, start, end in closures:
        centre = (start + end) / 2 - lead
        assert opening_at(session, centre) <= 0.0, symbol
    for symbol, start, end in vowels:
        centre = (start + end) / 2 - lead
        assert opening_at(session, centre) > 150.0, symbol


def test_the_lower_lip_goes_under_the_upper_teeth_on_f_and_v_and_lips_round_on_o_and_u() -> None:
    session, _ = speaking(text="five vans, who owns boots")
    lead = load_lip_model().lead
    phonemes = realized_phonemes(session)
    for symbol, start, end in phonemes:
        values = session.frame((start + end) / 2 - lead).values
        if symbol in ("f", "v"):
            assert values[15] < -50  # FAP 16 push_b_lip: the lower lip pulled in
        if symbol in ("uː", "əʊ"):
            assert values[16] > 50  # FAP 17 push_t_lip: lips forward (rounded)


def test_the_mouth_leads_the_audio_by_the_configured_lead() -> None:
    session, _ = speaking(text="a map")
    phonemes = realized_phonemes(session)
    _, start, end = next(p for p in phonemes if p[0] == "m")
    times = np.linspace(start - 0.15, end + 0.15, 301)
    openings = [opening_at(session, t) for t in times]
    closest = float(times[int(np.argmin(openings))])
    assert closest == pytest.approx((start + end) / 2 - load_lip_model().lead, abs=0.02)


def test_fast_neighbours_blend_instead_of_flickering() -> None:
    session, _ = speaking(text="papapapapapa")
    plan = session.plan("b")
    assert plan is not None
    times = np.arange(plan.start, plan.end, 0.005)
    openings = np.array([opening_at(session, t) for t in times])
    # no frame-to-frame jump larger than a fifth of the whole range
    assert np.abs(np.diff(openings)).max() < 0.2 * (openings.max() - openings.min())


def test_a_smile_while_speaking_keeps_both() -> None:
    registry = EngineRegistry.standard()
    session, _ = speaking(
        '<faceLexeme id="smile" lexeme="RAISE_MOUTH_CORNERS" start="0" end="4"/>',
        registry=registry,
    )
    alone, _ = speaking(registry=registry)
    phonemes = realized_phonemes(session)
    lead = load_lip_model().lead
    vowel = next(p for p in phonemes if p[0] == "aɪ")
    t = (vowel[1] + vowel[2]) / 2 - lead
    with_smile, speech_only = session.frame(t).values, alone.frame(t).values
    assert with_smile[11] > speech_only[11] + 20  # FAP 12 raise_l_cornerlip: the smile
    assert opening_at(session, t) > 150  # and the mouth still speaks
    closure = next(p for p in phonemes if p[0] == "b")
    assert opening_at(session, (closure[1] + closure[2]) / 2 - lead) <= 0.0


def test_a_jaw_drop_and_the_speech_jaw_add_up_without_a_jump() -> None:
    registry = EngineRegistry.standard()  # one engine: the same synthesis for both
    session, _ = speaking(
        '<ext:faceFacs id="jaw" au="26" amount="0.5" start="0" end="5"/>', registry=registry
    )
    alone, _ = speaking(registry=registry)
    plan = session.plan("b")
    assert plan is not None
    times = np.arange(0.0, plan.end, 0.01)
    jaw = np.array([session.frame(t).values[2] for t in times])
    speech_jaw = np.array([alone.frame(t).values[2] for t in times])
    drop = Session("c")
    drop.receive_bml(
        f'<bml xmlns="{BML_NS}" {RF} id="d">'
        '<ext:faceFacs id="jaw" au="26" amount="0.5" start="0" end="5"/></bml>',
        now=0.0,
    )
    drop_jaw = np.array([drop.frame(t).values[2] for t in times])
    # the two add up: the drop is there on top of speech ...
    assert np.allclose(jaw, speech_jaw + drop_jaw, atol=1e-6)
    assert drop_jaw.max() > 100
    # ... and the sum moves no faster than its parts together (no jump)
    steps = np.abs(np.diff(jaw))
    assert steps.max() <= np.abs(np.diff(speech_jaw)).max() + np.abs(np.diff(drop_jaw)).max() + 1


def test_an_emotion_mouth_yields_to_articulation() -> None:
    # surprise opens the lips; while speaking, p, b and m still close them
    session, _ = speaking('<rf:emotion id="e" word="surprised" start="0" end="5"/>')
    lead = load_lip_model().lead
    phonemes = realized_phonemes(session)
    for symbol, start, end in phonemes:
        if symbol in ("p", "b", "m"):
            assert opening_at(session, (start + end) / 2 - lead) <= 5.0, symbol


def test_interrupting_cuts_the_audio_and_closes_the_mouth_smoothly() -> None:
    session, _ = speaking()
    plan = session.plan("b")
    assert plan is not None
    phonemes = realized_phonemes(session)
    vowel = next(p for p in phonemes if p[0] == "aɪ")
    at = (vowel[1] + vowel[2]) / 2 - load_lip_model().lead
    before = session.audio(0.0, at)
    assert before is not None and np.abs(before.samples[-2000:].astype(int)).max() > 500
    session.tick(at)
    assert opening_at(session, at) > 150
    session.interrupt("b", at)
    after = session.audio(at, plan.end)
    assert after is None or not after.samples.any()
    release = session.limits.release
    times = np.arange(at, at + release + 0.1, 0.01)
    openings = np.array([opening_at(session, t) for t in times])
    assert abs(openings[-1]) < 1.0  # closed (neutral) after the release
    assert np.abs(np.diff(openings)).max() < 0.3 * openings[0]  # and smoothly


def test_sync_point_progress_of_each_marker_comes_when_it_is_heard() -> None:
    session, engine = speaking(text='Hello <sync id="m"/>world, <sync id="n"/>again.')
    plan = session.plan("b")
    assert plan is not None
    realization = engine.realize(plan.behaviours[0].behaviour, plan.behaviours[0].times)
    session.take_feedback()
    for marker in ("m", "n"):
        heard = realization.markers[marker]
        session.tick(heard - 0.002)
        assert not any(f'id="b:s:{marker}"' in f.xml for f in session.take_feedback())
        session.tick(heard + 0.002)
        assert any(f'id="b:s:{marker}"' in f.xml for f in session.take_feedback())


def test_audio_chunks_join_back_to_back_on_the_session_clock() -> None:
    session, _ = speaking()
    plan = session.plan("b")
    assert plan is not None
    whole = session.audio(0.0, plan.end)
    assert whole is not None
    pieces = []
    t = 0.0
    while t < plan.end:
        chunk = session.audio(t, t + 0.04)
        if chunk is not None:
            pieces.append(chunk)
        t += 0.04
    joined = np.concatenate([c.samples for c in pieces])
    assert pieces[0].start == 0.0
    assert np.array_equal(joined[: len(whole.samples)], whole.samples)
