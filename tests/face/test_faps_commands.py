"""``realizer faps`` and ``realizer plot-faps``: recording a block through a session.

These tests stand in a small session that honours the Session contract of
docs/interfaces.md (receive_bml, tick, take_feedback, frame), so they check
the commands' own work: the simulated clock, the feedback they read (sync
points, the block's end), the .fap file and the plot.
"""

from __future__ import annotations

import sys
import types
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from realizer.cli import main
from realizer.face.convert.lexemes import lexeme_faps
from realizer.face.fapfile import read_fap_file
from realizer.face.frame import FapFrame
from realizer.face.tracks import Envelope, FapAnimation, mix


@dataclass(frozen=True)
class Feedback:
    kind: str
    block_id: str
    time: float
    xml: str


class ContractSession:
    """Plays one smile from 0 to 1 s; reports its attackPeak and the block end."""

    def __init__(self, character_id: str, face: object = None) -> None:
        self.animation = FapAnimation(
            lexeme_faps("RAISE_MOUTH_CORNERS", 1.0), Envelope(0.0, 0.2, 0.8, 1.0)
        )
        self.pending = [
            Feedback("syncPointProgress", "b", 0.2, '<syncPointProgress id="b:smile:attackPeak"/>'),
            Feedback("blockProgress", "b", 1.0, '<blockProgress id="b:end"/>'),
        ]
        self.ready: list[Feedback] = []
        self.received = ""

    def receive_bml(self, text: str | bytes, now: float) -> None:
        self.received = text.decode() if isinstance(text, bytes) else text

    def tick(self, now: float) -> None:
        due = [f for f in self.pending if f.time <= now]
        self.pending = [f for f in self.pending if f.time > now]
        self.ready += due

    def take_feedback(self) -> list[Feedback]:
        out, self.ready = self.ready, []
        return out

    def frame(self, now: float) -> FapFrame:
        values, mask = mix([self.animation], now)
        return FapFrame(values, mask, now)


@pytest.fixture
def session_module(monkeypatch: pytest.MonkeyPatch) -> None:
    module = types.ModuleType("realizer.session")
    module.Session = ContractSession  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "realizer.session", module)


BML = Path(__file__).parents[2] / "examples" / "bml" / "01_smile.xml"


def test_faps_writes_every_frame_until_the_block_ends(
    session_module: None, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "smile.fap"
    assert main(["faps", str(BML), "--fps", "10", "-o", str(out)]) == 0
    fap = read_fap_file(out)
    assert fap.fps == 10 and fap.frames == 11  # 0.0 .. 1.0 s
    assert fap.name == "01_smile"
    expected = lexeme_faps("RAISE_MOUTH_CORNERS", 1.0).values
    assert np.allclose(fap.values[5], np.rint(expected))  # 0.5 s, in the sustain
    assert not fap.mask[10].any()  # the block has ended
    assert "11 frames" in capsys.readouterr().out


def test_plot_faps_draws_the_curves_and_the_reported_sync_points(
    session_module: None, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "smile.png"
    assert main(["plot-faps", str(BML), "-o", str(out)]) == 0
    assert "8 FAPs, 1 sync points" in capsys.readouterr().out
    with Image.open(out) as image:
        assert image.format == "PNG"


def test_a_missing_file_is_an_error(session_module: None, tmp_path: Path) -> None:
    assert main(["faps", str(tmp_path / "none.bml"), "-o", str(tmp_path / "x.fap")]) == 2
