"""FAP track plots (realizer.face.plotting)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

from realizer.face.convert.lexemes import lexeme_faps
from realizer.face.plotting import plot_fap_tracks
from realizer.face.tracks import Envelope, FapAnimation, KeyframeAnimation, sample


def test_a_plot_shows_every_fap_set_and_is_a_png(tmp_path: Path) -> None:
    brows = FapAnimation(lexeme_faps("RAISE_BROWS", 1.0), Envelope(0.2, 0.5, 1.5, 2.0))
    nod = KeyframeAnimation((48,), np.array([0.5, 1.0, 1.5]), np.array([[0.0], [3e4], [0.0]]))
    times = np.arange(0, 2.5, 0.04)
    values, mask = sample([brows, nod], times)
    path = tmp_path / "faps.png"
    drawn = plot_fap_tracks(times, values, mask, [("brows:start", 0.2), ("nod:stroke", 1.0)], path)
    assert drawn == (31, 32, 33, 34, 35, 36, 48)
    with Image.open(path) as image:
        assert image.format == "PNG" and image.size[0] > 600
