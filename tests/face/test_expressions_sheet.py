"""``realizer expressions``: the sheet of emotions, FAP 2 expressions, visemes and AUs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest
from PIL import Image

from realizer.cli import main
from realizer.commands.expressions import ACTION_UNITS, sheet_rows, tile_origin
from realizer.commands.fap_sheet import face_framing
from realizer.face.default import load_default_face
from realizer.face.render import FaceRenderer, RenderUnavailableError

TILE = 64


def test_the_sheet_has_the_six_emotions_six_expressions_fifteen_visemes_and_the_aus() -> None:
    rows = {row.kind: row for row in sheet_rows()}
    assert [len(rows[k].poses) for k in ("emotion", "fap2", "viseme", "au")] == [
        6,
        6,
        15,
        len(ACTION_UNITS),
    ]
    # every pose but viseme 0 (silence: the neutral mouth) sets some FAP
    for row in rows.values():
        for pose in row.poses:
            assert pose.values.shape == (68,)
            assert np.any(pose.values) != pose.label.startswith("v0 "), pose.label


def _regions(tile: int) -> dict[str, tuple[slice, slice]]:
    """Pixel boxes (rows, columns) of the mouth and of the brows in a tile."""
    face = load_default_face()
    points = face.params.feature_points
    with FaceRenderer(face, tile, tile, framing=face_framing(face)) as renderer:

        def px(name: str) -> npt.NDArray[np.float64]:
            return renderer.project(np.asarray([points[name]]))[0]

        left, right = px("8.4"), px("8.3")  # lip corners
        top, bottom = px("8.1"), px("2.10")  # upper lip, chin
        brow_l, brow_r = px("4.5"), px("4.6")  # outer brows
        eye = px("3.5")
    x0, x1 = sorted((int(left[0]), int(right[0])))
    mouth = (slice(int(top[1]) - 3, int(bottom[1]) + 1), slice(x0 - 3, x1 + 4))
    bx0, bx1 = sorted((int(brow_l[0]), int(brow_r[0])))
    brow_bottom = int(eye[1]) - 2
    brows = (slice(max(brow_bottom - tile // 6, 0), brow_bottom), slice(bx0, bx1 + 1))
    return {"mouth": mouth, "brows": brows}


@pytest.mark.opengl
def test_realizer_expressions_moves_the_regions_each_pose_should(tmp_path: Path) -> None:
    try:
        FaceRenderer(load_default_face(), 8, 8).close()
    except RenderUnavailableError as error:
        pytest.skip(f"no OpenGL offscreen context here: {error}")
    out = tmp_path / "expressions.png"
    assert main(["expressions", "--tile", str(TILE), "-o", str(out)]) == 0
    sheet = np.asarray(Image.open(out).convert("RGB")).astype(np.int32)
    rows = sheet_rows()
    assert sheet.shape[1] == TILE * (1 + max(len(r.poses) for r in rows))

    def tile_at(r: int, c: int) -> npt.NDArray[np.int32]:
        x, y = tile_origin(r, c, TILE)
        return sheet[y : y + TILE, x : x + TILE]

    regions = _regions(TILE)

    def change(r: int, c: int, region: str) -> float:
        rs, cs = regions[region]
        diff = np.abs(tile_at(r, c + 1) - tile_at(r, 0))[rs, cs]
        return float(diff.sum(axis=2).mean())

    for r, row in enumerate(rows):
        neutral = tile_at(r, 0)
        assert neutral.std() > 10  # a face, not an empty tile
        for c, pose in enumerate(row.poses):
            whole = float(np.abs(tile_at(r, c + 1) - neutral).sum(axis=2).mean())
            if pose.label.startswith("v0 "):
                assert whole < 0.5, "viseme 0 (silence) is the neutral face"
                continue
            assert whole > 0.2, f"{pose.label} looks like the neutral face"
            if row.kind == "viseme":
                assert change(r, c, "mouth") > 5.0, pose.label
                assert change(r, c, "brows") < 1.0, pose.label
            if row.kind == "emotion" and pose.label in ("sad", "angry", "afraid", "surprised"):
                assert change(r, c, "brows") > 4.0, pose.label  # brows move in these
            if row.kind == "emotion" and pose.label in ("joyful", "afraid", "surprised"):
                assert change(r, c, "mouth") > 5.0, pose.label
    au_row = next(i for i, row in enumerate(rows) if row.kind == "au")
    for c, pose in enumerate(rows[au_row].poses):
        if pose.label in ("AU 1", "AU 2", "AU 4"):
            assert change(au_row, c, "brows") > 2.0, pose.label
        if pose.label in ("AU 12", "AU 15", "AU 20", "AU 25", "AU 26"):
            assert change(au_row, c, "mouth") > 3.0, pose.label
            assert change(au_row, c, "brows") < 1.0, pose.label
