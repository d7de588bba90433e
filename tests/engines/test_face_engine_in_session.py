"""The face engine inside a real session (scheduler + engine + mixer), end to end."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from realizer.cli import main
from realizer.face.convert.emotion import load_default_converter
from realizer.face.convert.facs import facs_to_faps
from realizer.face.fapfile import read_fap_file
from realizer.session import Session

EXAMPLES = Path(__file__).parents[2] / "examples" / "bml"

HEADER = (
    '<bml xmlns="http://www.bml-initiative.org/bml/bml-1.0" '
    'xmlns:ext="http://www.bml-initiative.org/bml/coreextensions-1.0" '
    'xmlns:rf="urn:realizer:bml:face-1.0" id="{id}">'
)


def test_the_head_nod_example_reaches_its_amounts_on_fap_48_and_50(tmp_path: Path) -> None:
    out = tmp_path / "nods.fap"
    assert main(["faps", str(EXAMPLES / "06_head_nods.xml"), "-o", str(out)]) == 0
    fap = read_fap_file(out)
    assert fap.values[:, 47].max() == pytest.approx(0.6 * 30000, abs=1)  # NOD amount 0.6
    assert fap.values[:, 49].max() == pytest.approx(0.4 * 30000, abs=1)  # TILT amount 0.4
    assert fap.values[:, 48].min() < -0.4 * 40000  # SHAKE turns right too
    assert not fap.mask[-1].any()  # all over at the block's end


def test_an_emotion_under_a_facs_wink_in_one_block_as_in_seed_000_figure_7_2() -> None:
    session = Session("doctor")
    block = HEADER.format(id="b") + (
        '<rf:emotion id="calm" word="delighted" start="0" attackPeak="0.5" relax="4" end="4.5"/>'
        '<ext:faceFacs id="wink" au="46" side="LEFT" amount="1" start="1" attackPeak="1.2" '
        'relax="1.4" end="1.6"/></bml>'
    )
    session.receive_bml(block, 0.0)
    session.tick(1.3)
    frame = session.frame(1.3)
    delighted = load_default_converter().for_word("delighted").configuration()
    emotion = delighted.values
    wink = facs_to_faps(["46L"]).values
    assert frame.values[18] == pytest.approx(min(1080.0, emotion[18] + wink[18]))  # left lid
    assert frame.values[19] == pytest.approx(emotion[19])  # the right eye keeps the emotion
    session.tick(2.0)
    after = session.frame(2.0)  # the wink is over: the emotion alone
    assert np.array_equal(after.mask, delighted.mask)
    assert np.allclose(after.values[delighted.mask], emotion[delighted.mask])


def test_a_replace_block_eases_the_old_face_out() -> None:
    session = Session("doctor")
    smile = HEADER.format(id="a") + (
        '<faceLexeme id="s" lexeme="RAISE_MOUTH_CORNERS" amount="1" start="0" '
        'attackPeak="0.2" relax="5" end="5.5"/></bml>'
    )
    session.receive_bml(smile, 0.0)
    session.tick(1.0)
    before = session.frame(1.0).values[58]
    replace = (
        HEADER.format(id="b").replace('id="b">', 'id="b" composition="REPLACE">')
        + '<faceLexeme id="f" lexeme="LOWER_BROWS" amount="1" start="0" end="2"/></bml>'
    )
    session.receive_bml(replace, 1.0)
    session.tick(1.1)
    easing = session.frame(1.1).values[58]
    session.tick(1.5)
    after = session.frame(1.5).values[58]
    assert before > easing > 0 and after == 0  # no jump: the smile fades over 0.2 s


def test_behaviours_the_engine_cannot_realize_become_warnings_and_the_rest_plays() -> None:
    session = Session("doctor")
    block = HEADER.format(id="b") + (
        '<faceLexeme id="a" lexeme="SMIRK" start="0" end="1"/>'
        '<head id="h" lexeme="WOBBLE"/>'
        '<rf:emotion id="e" word="boredom"/>'
        '<faceLexeme id="c" lexeme="RAISE_BROWS" start="0" end="1"/></bml>'
    )
    assert session.receive_bml(block, 0.0) is not None
    session.tick(0.5)
    warnings = [f for f in session.take_feedback() if f.kind == "warning"]
    assert sorted(f.xml.split('id="')[1].split('"')[0] for f in warnings) == ["b:a", "b:e", "b:h"]
    assert all("CANNOT_CREATE_BEHAVIOR" in f.xml for f in warnings)
    assert session.frame(0.5).mask[30]  # the brows still rise
