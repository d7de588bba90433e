"""The Piper backend, run as a separate program; skipped without Piper or a voice model.

Set ``REALIZER_PIPER_MODEL`` to a voice's ``.onnx`` file (docs/speech.md says
how to download one) to run these.
"""

from __future__ import annotations

import os

import pytest

from realizer.bml_parser import BML_NS, parse_bml
from realizer.engines.speech import TtsError, load_backend
from realizer.engines.speech.piper import piper_command

MODEL = os.environ.get("REALIZER_PIPER_MODEL", "")

pytestmark = [
    pytest.mark.skipif(piper_command() is None, reason="Piper is not installed (realizer[piper])"),
    pytest.mark.skipif(
        not MODEL or not os.path.isfile(MODEL),
        reason="no Piper voice model: set REALIZER_PIPER_MODEL to a voice's .onnx file",
    ),
]


def test_piper_speaks_with_markers_on_segment_boundaries() -> None:
    backend = load_backend("piper", model=MODEL)
    speech = (
        parse_bml(
            f'<bml xmlns="{BML_NS}" id="b"><speech id="s"><text>Hello <sync id="m"/>world, '
            'how <sync id="n"/>are you?</text></speech></bml>'
        )
        .block.behaviours[0]
        .speech
    )
    assert speech is not None
    result = backend.synthesize(speech)
    assert 0 < result.markers["m"] < result.markers["n"] < result.duration
    assert result.audio.any() and result.phonemes


def test_a_missing_model_is_a_tts_error() -> None:
    with pytest.raises(TtsError, match="no Piper voice model"):
        load_backend("piper", model=MODEL + ".missing")
