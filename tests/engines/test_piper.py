"""The Piper backend, run as a separate program, with a real voice.

The voice: ``REALIZER_PIPER_MODEL`` (a voice's ``.onnx`` file), else the one
``scripts/piper_voice.sh`` (run by ``scripts/setup.sh``) puts into
``.cache/piper`` with Piper's own virtual environment (Piper is GPL: it is
run, never imported). Without Piper or a voice these skip, saying which is
missing.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from realizer.bml_parser import BML_NS, parse_bml
from realizer.engines import EngineRegistry
from realizer.engines.face import FaceEngine
from realizer.engines.speech import SpeechEngine, TtsError, load_backend
from realizer.engines.speech.lipsync import load_lip_model, mouth_opening
from realizer.engines.speech.piper import PiperBackend, piper_command
from realizer.session import Session

CACHE = Path(__file__).resolve().parents[2] / ".cache" / "piper"
CACHED_MODEL = CACHE / "en_US-joe-medium.onnx"
CACHED_BIN = CACHE / "venv" / "bin"
MODEL = os.environ.get("REALIZER_PIPER_MODEL", "") or (
    str(CACHED_MODEL) if CACHED_MODEL.is_file() else ""
)
HAVE_PIPER = piper_command() is not None or (CACHED_BIN / "piper").is_file()

pytestmark = [
    pytest.mark.skipif(
        not HAVE_PIPER,
        reason="Piper is not installed (realizer[piper], or bash scripts/piper_voice.sh)",
    ),
    pytest.mark.skipif(
        not MODEL or not os.path.isfile(MODEL),
        reason="no Piper voice model: set REALIZER_PIPER_MODEL to a voice's .onnx file "
        "or run bash scripts/piper_voice.sh",
    ),
]


@pytest.fixture(autouse=True)
def cached_piper_on_path(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """The cached Piper program first on PATH (where the set-up put one)."""
    if (CACHED_BIN / "piper").is_file():
        monkeypatch.setenv("PATH", f"{CACHED_BIN}{os.pathsep}{os.environ.get('PATH', '')}")
    yield


@pytest.fixture(scope="module")
def engine() -> SpeechEngine:
    """One engine for the module: each synthesis is cached, Piper runs once per text."""
    path = os.environ.get("PATH", "")
    if (CACHED_BIN / "piper").is_file():  # module scope: set it for the load as well
        os.environ["PATH"] = f"{CACHED_BIN}{os.pathsep}{path}"
    try:
        backend = load_backend("piper", model=MODEL)
    finally:
        os.environ["PATH"] = path
    return SpeechEngine(backend)


def speech_of(text: str) -> object:
    block = parse_bml(
        f'<bml xmlns="{BML_NS}" id="b"><speech id="s"><text>{text}</text></speech></bml>'
    ).block
    return block.behaviours[0].speech


def test_piper_speaks_with_markers_on_segment_boundaries() -> None:
    backend = load_backend("piper", model=MODEL)
    speech = speech_of('Hello <sync id="m"/>world, how <sync id="n"/>are you?')
    assert speech is not None
    result = backend.synthesize(speech)  # type: ignore[arg-type]
    assert 0 < result.markers["m"] < result.markers["n"] < result.duration
    assert result.audio.any() and result.phonemes
    assert result.backend == "piper" and result.sample_rate == 22050
    # the phonemes tile the audio in order, and the words' times lie inside it
    for earlier, later in zip(result.phonemes, result.phonemes[1:], strict=False):
        assert earlier.start <= earlier.end <= later.start + 1e-6
    assert result.phonemes[-1].end <= result.duration + 1e-6
    words = [w for w, _, _ in result.words]
    assert words[:2] == ["Hello", "world"]
    # a marker is heard where a segment's audio ends: at a word boundary
    starts = [s for _, s, _ in result.words]
    assert min(abs(result.markers["m"] - s) for s in starts) < 1e-6
    # real speech, not silence
    samples = np.abs(result.audio.astype(np.int32))
    assert samples.max() > 3000


def test_piper_knows_its_voice_language() -> None:
    backend = load_backend("piper", model=MODEL)
    assert isinstance(backend, PiperBackend)
    assert backend.language().startswith("en")
    assert backend.has_language("en-US") and not backend.has_language("de")


def test_a_missing_model_is_a_tts_error() -> None:
    with pytest.raises(TtsError, match="no Piper voice model"):
        load_backend("piper", model=MODEL + ".missing")


@pytest.mark.slow
def test_a_session_speaking_through_piper_moves_the_lips_and_plays_the_audio(
    engine: SpeechEngine,
) -> None:
    """Piper's phonemes (eSpeak NG's symbols, scaled to Piper's audio) drive
    the lips: closed at p, b, m, open on vowels; the audio is Piper's."""
    session = Session("a", registry=EngineRegistry([FaceEngine.default(), engine]))
    session.receive_bml(
        f'<bml xmlns="{BML_NS}" id="b"><speech id="s" start="0"><text>Peter bought '
        'my <sync id="m"/>big map.</text></speech></bml>',
        now=0.0,
    )
    plan = session.plan("b")
    assert plan is not None
    scheduled = plan.behaviours[0]
    realization = engine.realize(scheduled.behaviour, scheduled.times)
    assert realization.audio is not None and realization.audio.samples.any()
    heard = session.audio(0.0, plan.end)
    assert heard is not None and np.abs(heard.samples.astype(np.int32)).max() > 3000
    assert 0.0 < realization.markers["m"] == pytest.approx(scheduled.times["m"], abs=1e-3)
    lead = load_lip_model().lead
    closing = [p for p in realization.phonemes if p[0] in ("p", "b", "m")]
    vowels = [p for p in realization.phonemes if p[0] in ("iː", "ɔː", "aɪ", "a", "ɪ")]
    assert len(closing) >= 4 and len(vowels) >= 4
    for symbol, start, end in closing:
        assert mouth_opening(session.frame((start + end) / 2 - lead).values) <= 0.0, symbol
    for symbol, start, end in vowels:
        assert mouth_opening(session.frame((start + end) / 2 - lead).values) > 100.0, symbol
