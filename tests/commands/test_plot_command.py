"""``realizer plot``: a Gantt chart PNG of a scheduled block, and its exit codes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from realizer.cli import main
from realizer.commands.plot import label_lanes
from tests.conftest import EXAMPLES

BML = 'xmlns="http://www.bml-initiative.org/bml/bml-1.0"'
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("name", ["08_constraints.xml", "05_speech_sync.xml"])
def test_plot_writes_a_coloured_png(
    name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    output = tmp_path / "timeline.png"
    assert main(["plot", str(EXAMPLES / name), "-o", str(output)]) == 0
    data = output.read_bytes()
    assert data.startswith(PNG_SIGNATURE)
    assert len(data) > 20_000
    with Image.open(output) as image:
        assert image.width >= 800
        pixels = np.asarray(image.convert("RGB")).reshape(-1, 3)
    colours = np.unique(pixels, axis=0)
    assert len(colours) > 20
    # Not just greys: the bars are coloured by behaviour type.
    spread = pixels.max(axis=1).astype(int) - pixels.min(axis=1).astype(int)
    assert (spread > 60).sum() > 1000
    assert str(output) in capsys.readouterr().out


def test_plot_reports_the_ties_and_orderings_it_drew(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    output = tmp_path / "timeline.png"
    assert main(["plot", str(EXAMPLES / "08_constraints.xml"), "-o", str(output)]) == 0
    # One <synchronize> pair, one <after> and one <before>.
    assert "4 behaviours, 22 sync points, 1 ties, 2 orderings" in capsys.readouterr().out


def test_plot_of_an_unparsable_document_exits_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "broken.xml"
    path.write_text(f'<bml {BML} id="b"><head id="h"</bml>', encoding="utf-8")
    output = tmp_path / "timeline.png"
    assert main(["plot", str(path), "-o", str(output)]) == 2
    assert ": error: " in capsys.readouterr().err
    assert not output.exists()


def test_plot_of_an_impossible_block_exits_1(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "impossible.xml"
    path.write_text(
        f'<bml {BML} id="impossible"><required>'
        '<faceLexeme id="a" lexeme="RAISE_BROWS" start="0" end="2"/>'
        '<faceLexeme id="b" lexeme="WIDEN_EYES" start="a:end" end="a:start"/>'
        "</required></bml>",
        encoding="utf-8",
    )
    output = tmp_path / "timeline.png"
    assert main(["plot", str(path), "-o", str(output)]) == 1
    assert "IMPOSSIBLE_TO_SCHEDULE" in capsys.readouterr().err
    assert not output.exists()


def test_close_sync_labels_get_different_lanes() -> None:
    # At 0.02 s per point every label is wider than 0.15 s: the first four overlap.
    times = {"start": 0.0, "ready": 0.05, "strokeStart": 0.1, "stroke": 0.15, "end": 2.0}
    lanes = {name: lane for name, _, lane in label_lanes(times, seconds_per_point=0.02)}
    assert len({lanes["start"], lanes["ready"], lanes["strokeStart"], lanes["stroke"]}) == 4
    assert lanes["end"] == 0  # far from the others: back in the first lane


def test_labels_far_apart_share_the_first_lane() -> None:
    times = {"start": 0.0, "relax": 1.0, "end": 2.0}
    assert [lane for _, _, lane in label_lanes(times, seconds_per_point=0.005)] == [0, 0, 0]
