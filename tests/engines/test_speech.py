"""Speech with the real eSpeak NG: marker times, stretching, languages, limits, failures."""

from __future__ import annotations

import numpy as np
import pytest

from realizer.bml_parser import BML_NS, Behaviour, parse_bml
from realizer.engines import EngineRegistry
from realizer.engines.speech import SpeechEngine, SpeechLimits, TtsError, load_backend
from realizer.engines.speech.engine import lay_out
from realizer.engines.speech.espeak import EspeakBackend
from realizer.scheduler.plan import schedule_block
from realizer.session import Session

TEXT = (
    'Good <sync id="m1"/>morning, my friend. It is <sync id="m2"/>lovely '
    'to see <sync id="m3"/>you again.<sync id="m4"/>'
)


@pytest.fixture(scope="module")
def espeak() -> EspeakBackend:
    try:
        backend = load_backend("espeak")
    except TtsError as exc:  # pragma: no cover - setup.sh installs it
        pytest.skip(f"eSpeak NG is not installed: {exc}")
    assert isinstance(backend, EspeakBackend)
    return backend


def speech(inner: str, attributes: str = "", block_attributes: str = "") -> Behaviour:
    block = parse_bml(
        f'<bml xmlns="{BML_NS}" id="b" {block_attributes}>'
        f'<speech id="s" {attributes}><text>{inner}</text></speech></bml>'
    ).block
    return block.behaviours[0]


def test_marker_times_are_monotone_inside_the_audio_and_at_word_boundaries(
    espeak: EspeakBackend,
) -> None:
    result = espeak.synthesize(speech(TEXT).speech)  # type: ignore[arg-type]
    times = [result.markers[m] for m in ("m1", "m2", "m3", "m4")]
    assert times == sorted(times) and times[0] > 0
    assert all(0.0 < t <= result.duration for t in times)
    boundaries = [w[1] for w in result.words] + [w[2] for w in result.words]
    for t in times:
        assert min(abs(t - b) for b in boundaries) < 1e-3
    # the words between markers are the words of the text
    assert [w for w, _, _ in result.words][:2] == ["Good", "morning"]
    assert result.audio.dtype == np.int16 and result.sample_rate > 8000
    assert np.abs(result.audio.astype(np.int32)).max() > 1000  # it is not silence


def test_phonemes_tile_the_audio_in_order(espeak: EspeakBackend) -> None:
    result = espeak.synthesize(speech("Peter bought my five vans.").speech)  # type: ignore[arg-type]
    symbols = [p.symbol for p in result.phonemes if p.symbol]
    assert symbols[:2] == ["p", "iː"]
    for earlier, later in zip(result.phonemes, result.phonemes[1:], strict=False):
        assert earlier.end == pytest.approx(later.start)
        assert earlier.start < earlier.end
    assert result.phonemes[-1].end == pytest.approx(result.duration)


def test_synthesis_is_fast_enough_to_plan_with(espeak: EspeakBackend) -> None:
    # Not a timing goal (see realizer bench speech): the first chunk arrives
    # before the whole synthesis returns.
    result = espeak.synthesize(speech(TEXT).speech)  # type: ignore[arg-type]
    assert result.first_audio > 0.0


def test_xml_lang_picks_the_voice_and_an_unknown_language_falls_back_with_a_note() -> None:
    engine = SpeechEngine.default()
    assert engine.backend is not None, engine.unavailable
    english = engine.synthesis(speech("Guten Tag"))
    german = engine.synthesis(speech("Guten Tag", block_attributes='xml:lang="de"'))
    assert english is not None and german is not None
    assert german.voice == "de" and english.voice == "en"
    assert [p.symbol for p in english.phonemes] != [p.symbol for p in german.phonemes]
    unknown = speech("Hello", attributes='xml:lang="tlh"')
    result = engine.synthesis(unknown)
    assert result is not None and result.voice == "en"
    assert any("tlh" in note and "default voice" in note for note in engine.notes(unknown))
    assert engine.notes(speech("Hello")) == ()


def test_a_stretched_phase_inserts_a_pause_before_the_marker_heard_at_the_solved_time() -> None:
    block = parse_bml(
        f'<bml xmlns="{BML_NS}" id="b">'
        f'<speech id="s" start="0"><text>{TEXT}</text></speech>'
        '<head id="h" lexeme="NOD" stroke="3.0"/>'
        '<constraint id="c"><synchronize ref="h:stroke"><sync ref="s:m2"/></synchronize>'
        "</constraint></bml>"
    ).block
    engine = SpeechEngine.default()
    assert engine.backend is not None, engine.unavailable
    plan = schedule_block(block, registry=EngineRegistry([engine]))
    synthesis = engine.synthesis(block.behaviours[0])
    assert synthesis is not None
    times = plan.behaviours[0].times
    # the head forces m2 a second later than the TTS says it: phases grew
    assert times["m2"] == pytest.approx(3.0, abs=1e-6)
    assert times["m2"] > synthesis.markers["m2"] + 0.9
    clip, phonemes, heard = lay_out(synthesis, block.behaviours[0].syncs, times)
    frame = 1.0 / synthesis.sample_rate
    for marker in ("m1", "m2", "m3", "m4"):
        assert heard[marker] == pytest.approx(times[marker], abs=frame)
    # after the pause, the audio is the TTS's audio from m2 on, sample for sample
    rate = synthesis.sample_rate
    here = round((heard["m2"] - clip.start) * rate)
    there = round(synthesis.markers["m2"] * rate)
    assert np.array_equal(clip.samples[here : here + 2000], synthesis.audio[there : there + 2000])
    # and silence just before it
    assert not clip.samples[here - 2000 : here].any()
    assert clip.end == pytest.approx(times["end"], abs=frame)
    assert [p[0] for p in phonemes] == [p.symbol for p in synthesis.phonemes]


def test_speech_is_never_squeezed_below_its_audio() -> None:
    block = parse_bml(
        f'<bml xmlns="{BML_NS}" id="b">'
        f'<speech id="s" start="0"><text>{TEXT}</text></speech>'
        '<head id="h" lexeme="NOD" start="0" stroke="0.1"/>'
        '<constraint id="c"><synchronize ref="h:stroke"><sync ref="s:m2"/></synchronize>'
        "</constraint></bml>"
    ).block
    engine = SpeechEngine.default()
    plan = schedule_block(block, registry=EngineRegistry([engine]))
    synthesis = engine.synthesis(block.behaviours[0])
    assert synthesis is not None
    times = plan.behaviours[0].times
    assert times["m2"] >= synthesis.markers["m2"] - 1e-9
    assert times["end"] - times["start"] >= synthesis.duration - 1e-9


def test_a_text_over_the_limit_is_refused_with_a_warning_not_truncated() -> None:
    engine = SpeechEngine.default()
    engine.limits = SpeechLimits(max_characters=20)
    session = Session("a", registry=EngineRegistry([engine]))
    session.receive_bml(
        f'<bml xmlns="{BML_NS}" id="b"><speech id="s"><text>{"word " * 10}</text></speech>'
        '<head id="h" lexeme="NOD"/></bml>',
        now=0.0,
    )
    warnings = [f.xml for f in session.take_feedback() if f.kind == "warning"]
    assert any("max_characters" in w and "refused" in w for w in warnings)
    assert session.audio(0.0, 5.0) is None
    plan = session.plan("b")
    assert plan is not None and plan.time_of("h", "end") is not None  # the rest runs


def test_a_failing_tts_warns_and_the_block_still_runs_on_the_estimate() -> None:
    engine = SpeechEngine(EspeakBackend(voice="no-such-voice-xx"))
    session = Session("a", registry=EngineRegistry([engine]))
    plan = session.receive_bml(
        f'<bml xmlns="{BML_NS}" id="b"><speech id="s"><text>{TEXT}</text></speech>'
        '<head id="h" lexeme="NOD" stroke="s:m2"/></bml>',
        now=0.0,
    )
    assert plan is not None
    warnings = [f.xml for f in session.take_feedback() if f.kind == "warning"]
    assert any("no-such-voice-xx" in w and "syllable estimate" in w for w in warnings)
    assert plan.time_of("h", "stroke") == pytest.approx(plan.time_of("s", "m2"))
    assert session.audio(0.0, 5.0) is None


def test_no_tts_at_all_is_announced_and_speech_falls_back_to_the_estimate() -> None:
    engine = SpeechEngine(None, unavailable="eSpeak NG is not installed")
    session = Session("a", registry=EngineRegistry([engine]))
    plan = session.receive_bml(
        f'<bml xmlns="{BML_NS}" id="b"><speech id="s"><text>{TEXT}</text></speech></bml>', now=0.0
    )
    assert plan is not None and plan.end > 1.0
    warnings = [f.xml for f in session.take_feedback() if f.kind == "warning"]
    assert any("not installed" in w and "estimate" in w for w in warnings)


def test_the_engine_is_safe_from_worker_threads() -> None:
    from concurrent.futures import ThreadPoolExecutor

    engine = SpeechEngine.default()
    texts = [f"Number {n} is spoken <sync id='x'/>now." for n in range(8)]
    behaviours = [speech(t) for t in texts]
    with ThreadPoolExecutor(4) as pool:
        models = list(pool.map(engine.plan, behaviours))
    alone = [SpeechEngine.default().plan(b) for b in behaviours]
    # eSpeak NG carries a little state between calls: lengths agree to a few samples
    for threaded, single in zip(models, alone, strict=True):
        assert threaded.syncs == single.syncs
        for a, b in zip(threaded.phases, single.phases, strict=True):
            assert a.preferred == pytest.approx(b.preferred, abs=1e-3)
