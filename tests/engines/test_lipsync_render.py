"""The mouth in rendered frames: closed at each p, b, m and open on vowels.

A real eSpeak NG utterance goes through what ``realizer render`` runs: the
service's stage and session driven offline at a frame rate
(:func:`realizer.service.offline.run_offline`), each frame's FAPs deformed
onto the default face and drawn by realizer's own offscreen OpenGL renderer
(OSMesa or EGL). The frames nearest the middle of each p, b, m and of each
vowel (where the mouth shows it, the visual lead before the sound) are
rendered and the opening is measured in the image: the dark pixels of the
mouth cavity in the middle of the mouth, between the deformed outer lip
midpoints (feature points 8.1 and 8.2 of Tekalp and Ostermann 2000, Table 6).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from realizer.bml_parser import BML_NS

SENTENCE = "Peter bought my five vans and a big map."
FPS = 200.0  # a frame every 5 ms: the nearest frame is within 2.5 ms of the middle
SIZE = 256
CLOSING = ("p", "b", "m")
VOWELS = ("iː", "ɔː", "aɪ", "a", "ɪ")  # the FAP-stream test's vowels (test_lipsync.py)
WIDE = ("ɔː", "aɪ", "a")  # open vowels: the jaw drops


def cavity_height(renderer: Any, face: Any, vertices: np.ndarray, image: np.ndarray) -> float:
    """Mean height in pixels of the dark mouth cavity over the middle 60 % of the mouth.

    The region: columns between the mouth corners (8.3, 8.4), its middle
    60 %; rows strictly between the upper and lower outer lip midpoints (8.1,
    8.2), all as deformed in this frame. A cavity pixel is darker than 0.7
    of the cheek's brightness (feature point 5.1 in the neutral framing): the
    renderer draws the mouth's inside dark (realizer.face.render), the lips'
    and chin's shading stays above that.
    """
    points = [face.feature_vertex(n) for n in ("8.1", "8.2", "8.3", "8.4")]
    (_, upper), (_, lower), (corner_a, _), (corner_b, _) = renderer.project(vertices[points])
    left, right = sorted((corner_a, corner_b))
    middle, half = (left + right) / 2, (right - left) * 0.3
    columns = slice(int(np.ceil(middle - half)), int(np.floor(middle + half)) + 1)
    rows = slice(int(np.ceil(upper)) + 1, int(np.floor(lower)) - 1)
    brightness = image.astype(np.int64).sum(axis=2)
    column, row = np.round(renderer.project(face.feature_position("5.1")[None])[0]).astype(int)
    cheek = brightness[row - 1 : row + 2, column - 1 : column + 2].mean()
    region = brightness[rows, columns]
    assert region.size > 50  # the mouth is in the picture, at a useful size
    return float((region < 0.7 * cheek).sum() / region.shape[1])


@pytest.mark.opengl
@pytest.mark.slow
def test_rendered_frames_close_the_mouth_at_p_b_m_and_open_it_on_vowels() -> None:
    from realizer.engines.speech import SpeechEngine
    from realizer.engines.speech.lipsync import load_lip_model
    from realizer.face.deform import deform
    from realizer.face.render import FaceRenderer, RenderUnavailableError
    from realizer.service.assets import load_face, session_factory
    from realizer.service.offline import run_offline
    from realizer.service.stage import Stage

    face = load_face()
    try:
        renderer = FaceRenderer(face, SIZE, SIZE)
    except RenderUnavailableError as error:
        pytest.skip(f"no OpenGL offscreen context here: {error}")
    # as `realizer render` does (idle motion on: blinks, breathing, head motion)
    stage = Stage(session_factory(face, idle=True, seed=0))
    bml = (
        f'<bml xmlns="{BML_NS}" id="b"><speech id="s" start="0"><text>{SENTENCE}</text>'
        "</speech></bml>"
    )
    offline = run_offline(stage, bml, FPS, tail=0.1)
    assert offline.accepted
    session = stage.characters[offline.character].session
    engine = next(e for e in session.registry.engines if isinstance(e, SpeechEngine))
    assert engine.backend is not None, engine.unavailable
    plan = session.plan(offline.block_id)
    assert plan is not None
    scheduled = plan.behaviours[0]
    phonemes = engine.realize(scheduled.behaviour, scheduled.times).phonemes
    lead = load_lip_model().lead
    wanted: dict[int, str] = {}
    for symbol, start, end in phonemes:
        if symbol in CLOSING or symbol in VOWELS:
            wanted[round(((start + end) / 2 - lead) * FPS)] = symbol
    assert sum(s in CLOSING for s in wanted.values()) >= 5
    assert sum(s in VOWELS for s in wanted.values()) >= 5

    seen: dict[int, float] = {}
    with renderer:
        neutral = cavity_height(renderer, face, face.vertices, renderer.render())
        for frame in offline.frames:
            if frame.number not in wanted:
                continue
            vector = np.where(frame.frame.mask, frame.frame.values, 0.0)  # as render does
            vertices = deform(face, vector)
            seen[frame.number] = cavity_height(renderer, face, vertices, renderer.render(vertices))
    assert sorted(seen) == sorted(wanted)
    report = {f"{wanted[n]}@{n / FPS:.3f}s": round(h, 2) for n, h in sorted(seen.items())}
    assert neutral == 0.0, report  # the face at rest shows no mouth cavity
    for number, height in seen.items():
        symbol = wanted[number]
        if symbol in CLOSING:
            assert height == 0.0, (symbol, number / FPS, report)  # lips together
        else:
            assert height >= 1.0, (symbol, number / FPS, report)  # the cavity shows
            if symbol in WIDE:
                assert height >= 4.0, (symbol, number / FPS, report)
