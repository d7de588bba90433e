"""``realizer face`` and ``realizer fap-sheet`` (seed 000 section 4.4.2, figure 4.20)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from realizer.cli import main
from realizer.commands.face import parse_fap_assignments
from realizer.commands.fap_sheet import (
    UNDERLAY_INTENSITY,
    difference_over_underlay,
    load_sheet_entries,
)
from realizer.face.render import FaceRenderer, RenderUnavailableError


def opengl_or_skip() -> None:
    from realizer.face.default import load_default_face

    try:
        FaceRenderer(load_default_face(), 8, 8).close()
    except RenderUnavailableError as error:
        pytest.skip(f"no OpenGL offscreen context here: {error}")


def test_fap_assignments_take_numbers_and_names() -> None:
    vector = parse_fap_assignments("3=400 raise_l_i_eyebrow=200, 48=-1500")
    assert vector.shape == (68,)
    assert vector[2] == 400 and vector[30] == 200 and vector[47] == -1500
    assert np.count_nonzero(vector) == 3


@pytest.mark.parametrize("text", ["3", "99=1", "smile=3", "3=big"])
def test_bad_fap_assignments_are_refused(text: str) -> None:
    with pytest.raises(ValueError):
        parse_fap_assignments(text)


def test_the_sheet_shows_every_fap_from_3_to_68_once() -> None:
    entries = load_sheet_entries()
    assert [e.fap for e in entries] == list(range(3, 69))
    assert all(entry.value > 0 for entry in entries)
    # depth motions are shown from the side the feature point is on
    views = {e.fap: e.view for e in entries}
    assert views[27] == "left" and views[28] == "right"


def test_the_difference_image_is_the_dimmed_blurred_neutral_where_nothing_moved() -> None:
    neutral = np.zeros((40, 40, 3), dtype=np.uint8)
    neutral[10:30, 10:30] = 200
    same = difference_over_underlay(neutral, neutral)
    assert same.max() <= round(200 * UNDERLAY_INTENSITY) + 1
    assert same[20, 20, 0] == pytest.approx(200 * UNDERLAY_INTENSITY, abs=1)
    assert same[0, 0].sum() == 0  # the background stays black
    moved = neutral.copy()
    moved[10:30, 12:32] = 200
    diff = difference_over_underlay(neutral, moved)
    assert diff[20, 31].min() == 255  # where the face moved, bright
    assert diff[20, 20, 0] == same[20, 20, 0]  # where it did not, the underlay


@pytest.mark.opengl
def test_realizer_face_renders_a_pose_to_png(tmp_path: Path) -> None:
    opengl_or_skip()
    out = tmp_path / "face.png"
    neutral = tmp_path / "neutral.png"
    assert main(["face", "--faps", "3=600", "--size", "96", "-o", str(out)]) == 0
    assert main(["face", "--faps", "", "--size", "96", "-o", str(neutral)]) == 0
    a = np.asarray(Image.open(out)).astype(int)
    b = np.asarray(Image.open(neutral)).astype(int)
    assert a.shape == (96, 96, 3)
    changed = np.abs(a - b).sum(axis=2) > 30
    rows = np.nonzero(changed)[0]
    assert rows.size > 0
    assert rows.min() > 48  # opening the jaw changes the lower half only


@pytest.mark.opengl
def test_realizer_fap_sheet_writes_one_row_per_fap(tmp_path: Path) -> None:
    opengl_or_skip()
    out = tmp_path / "sheet.png"
    assert main(["fap-sheet", "--tile", "32", "-o", str(out)]) == 0
    sheet = np.asarray(Image.open(out))
    rows = (len(load_sheet_entries()) + 1) // 2
    assert sheet.shape == (28 + rows * 32, 2 * (150 + 5 * 32), 3)


@pytest.mark.opengl
def test_realizer_face_reads_a_frame_of_a_fap_file(tmp_path: Path) -> None:
    opengl_or_skip()
    from realizer.face.fapfile import fap_file_from_frames, write_fap_file

    values = np.zeros(68)
    mask = np.zeros(68, dtype=bool)
    values[[2, 30]] = (500, 300)
    mask[[2, 30]] = True
    write_fap_file(
        tmp_path / "pose.fap",
        fap_file_from_frames(
            "pose", 25.0, [(np.zeros(68), np.zeros(68, dtype=bool)), (values, mask)]
        ),
    )
    from_file = tmp_path / "from_file.png"
    from_faps = tmp_path / "from_faps.png"
    args = ["--size", "64", "-o"]
    assert main(["face", str(tmp_path / "pose.fap"), "--frame", "1", *args, str(from_file)]) == 0
    assert main(["face", "--faps", "3=500 31=300", *args, str(from_faps)]) == 0
    assert np.array_equal(np.asarray(Image.open(from_file)), np.asarray(Image.open(from_faps)))
    assert main(["face", str(tmp_path / "pose.fap"), "--frame", "2", *args, str(from_file)]) == 2


def test_close_ups_frame_each_fap_on_its_region() -> None:
    from realizer.commands.fap_sheet import face_framing, region_framing, region_of
    from realizer.face.default import load_default_face

    assert [region_of(f) for f in (3, 8, 19, 32, 23, 39, 61, 65, 48)] == [
        "mouth", "mouth", "left eye", "right eye", "left eye", "cheeks", "nose", "ears", "face",
    ]  # fmt: skip
    face = load_default_face()
    whole = face_framing(face).height
    for region in ("mouth", "cheeks", "nose"):
        assert region_framing(face, region).height < 0.75 * whole, region
    for region in ("left eye", "right eye"):
        assert region_framing(face, region).height < 0.5 * whole, region


@pytest.mark.opengl
def test_fap_sheet_close_ups_with_profiles(tmp_path: Path) -> None:
    opengl_or_skip()
    out = tmp_path / "close.png"
    assert main(["fap-sheet", "--tile", "32", "--close-up", "--profile", "-o", str(out)]) == 0
    sheet = np.asarray(Image.open(out).convert("RGB")).astype(np.int32)
    rows = (len(load_sheet_entries()) + 1) // 2
    assert sheet.shape == (28 + rows * 32, 2 * (150 + 8 * 32), 3)
    # FAP 3 (first row): the profile of the open jaw differs from the profile at rest
    side = [sheet[28:60, 150 + t * 32 : 150 + (t + 1) * 32] for t in (5, 6)]
    assert np.abs(side[1] - side[0]).mean() > 1.0
