"""The deterministic speech timing model and the hook a real TTS engine plugs into."""

from __future__ import annotations

import pytest

from realizer.bml_parser import BML_NS, SpeechText, parse_bml
from realizer.engines import EngineRegistry
from realizer.engines.speech import SpeechEngine
from realizer.engines.speech.timing import RateSpeechTiming, syllables
from realizer.scheduler.plan import schedule_block


def speech_text(inner: str) -> SpeechText:
    block = parse_bml(
        f'<bml xmlns="{BML_NS}" id="b"><speech id="s"><text>{inner}</text></speech></bml>'
    ).block
    (behaviour,) = block.behaviours
    assert behaviour.speech is not None
    return behaviour.speech


TEXT = 'Welcome <sync id="a"/>ladies and <sync id="b"/>gentlemen, <sync id="c"/>to the show.'


def test_every_marker_gets_a_time_in_text_order() -> None:
    plan = RateSpeechTiming().plan(speech_text(TEXT))
    assert list(plan.markers) == ["a", "b", "c"]
    times = list(plan.markers.values())
    assert 0 < times[0] < times[1] < times[2] < plan.duration


def test_a_marker_sits_where_its_word_starts() -> None:
    plan = RateSpeechTiming().plan(speech_text(TEXT))
    starts = {word: start for word, start, _ in plan.words}
    assert plan.markers["a"] == pytest.approx(starts["ladies"])
    assert plan.markers["b"] == pytest.approx(starts["gentlemen,"])
    assert plan.markers["c"] == pytest.approx(starts["to"])


def test_words_follow_each_other_without_gaps() -> None:
    plan = RateSpeechTiming().plan(speech_text(TEXT))
    assert [w for w, _, _ in plan.words] == TEXT_WORDS
    assert plan.words[0][1] == 0.0
    for (_, _, end), (_, start, _) in zip(plan.words, plan.words[1:], strict=False):
        assert start == pytest.approx(end)
    assert plan.words[-1][2] == pytest.approx(plan.duration)


TEXT_WORDS = ["Welcome", "ladies", "and", "gentlemen,", "to", "the", "show."]


def test_a_marker_at_the_start_is_at_zero() -> None:
    plan = RateSpeechTiming().plan(speech_text('<sync id="first"/>Hello there.'))
    assert plan.markers["first"] == 0.0


def test_the_speaking_rate_scales_every_time() -> None:
    text = speech_text(TEXT)
    slow = RateSpeechTiming(syllables_per_second=3.0, comma_pause=0.0, stop_pause=0.0).plan(text)
    fast = RateSpeechTiming(syllables_per_second=6.0, comma_pause=0.0, stop_pause=0.0).plan(text)
    assert fast.duration == pytest.approx(slow.duration / 2)
    for name in slow.markers:
        assert fast.markers[name] == pytest.approx(slow.markers[name] / 2)


def test_punctuation_adds_its_pause() -> None:
    model = RateSpeechTiming(syllables_per_second=4.0, comma_pause=0.25, stop_pause=0.5)
    assert model.word_duration("yes") == pytest.approx(0.25)
    assert model.word_duration("yes,") == pytest.approx(0.5)
    assert model.word_duration("yes.") == pytest.approx(0.75)


def test_syllables_are_vowel_groups_and_at_least_one() -> None:
    assert syllables("gentlemen") == 3
    assert syllables("show") == 1
    assert syllables("hmm") == 1


def test_the_model_is_deterministic() -> None:
    text = speech_text(TEXT)
    assert RateSpeechTiming().plan(text) == RateSpeechTiming().plan(text)


def test_the_real_tts_times_the_markers_through_the_engine() -> None:
    block = parse_bml(
        f'<bml xmlns="{BML_NS}" id="b"><speech id="s"><text>{TEXT}</text></speech>'
        '<head id="nod1" lexeme="NOD" stroke="s:c"/></bml>'
    ).block
    engine = SpeechEngine.default()
    assert engine.backend is not None, engine.unavailable
    plan = schedule_block(block, registry=EngineRegistry([engine]))
    synthesis = engine.synthesis(block.behaviours[0])
    assert synthesis is not None
    for marker in ("a", "b", "c"):
        assert plan.time_of("s", marker) == pytest.approx(synthesis.markers[marker], abs=1e-6)
    assert plan.time_of("s", "end") == pytest.approx(synthesis.duration, abs=1e-6)
    assert plan.time_of("nod1", "stroke") == pytest.approx(synthesis.markers["c"], abs=1e-6)
