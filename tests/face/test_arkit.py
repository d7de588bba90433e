"""ARKit weights from FAP frames (realizer.face.arkit)."""

from __future__ import annotations

import numpy as np
import pytest

from realizer.face.arkit import (
    ARKIT_NAMES,
    ArkitFit,
    decode_payload,
    fit_error,
    has_targets,
    oculus_visemes,
    payload,
)
from realizer.face.default import load_default_face

pytestmark = pytest.mark.skipif(not has_targets(), reason="ARKit targets not extracted")


@pytest.fixture(scope="module")
def fit() -> ArkitFit:
    return ArkitFit(load_default_face())


def expression(**faps: float) -> np.ndarray:
    v = np.zeros(68)
    for key, value in faps.items():
        v[int(key[1:]) - 1] = value
    return v


def test_an_open_jaw_is_mostly_jaw_open_and_a_smile_smiles(fit: ArkitFit) -> None:
    jaw = fit.frame(expression(f3=500)).weights
    # the default face opens its jaw as jawOpen plus the joint's forward
    # glide (jawForward), which keeps the chin from swinging back
    # (scripts/extract_default_face.py, jaw_tables)
    assert {ARKIT_NAMES[int(i)] for i in np.argsort(-jaw)[:2]} == {"jawOpen", "jawForward"}
    assert jaw[ARKIT_NAMES.index("jawOpen")] > 0.2
    smile = fit.frame(expression(f12=250, f13=250, f53=200, f54=200)).weights
    assert smile[ARKIT_NAMES.index("mouthSmileLeft")] > 0.1
    assert smile[ARKIT_NAMES.index("jawOpen")] < smile[ARKIT_NAMES.index("mouthSmileLeft")]
    neutral = fit.frame(np.zeros(68))
    assert not neutral.weights.any() and not neutral.pose.any()


def test_the_fit_explains_most_of_the_deformation(fit: ArkitFit) -> None:
    vectors = [
        expression(f3=400),
        expression(f12=250, f13=250, f53=200, f54=200),
        expression(f31=150, f32=150, f33=150, f34=150),
        expression(f19=800, f20=800),
    ]
    worst, relative = fit_error(fit, vectors)
    # against doing nothing (weights 0): relative error 1
    assert relative < 0.5
    assert worst < 0.01


def test_eye_looks_and_the_pose_come_from_the_angles(fit: ArkitFit) -> None:
    frame = fit.frame(expression(f23=25000, f25=-25000, f49=10000))
    w = dict(zip(ARKIT_NAMES, frame.weights, strict=True))
    assert w["eyeLookOutLeft"] == pytest.approx(0.5)
    assert w["eyeLookUpLeft"] == pytest.approx(0.5)
    assert w["eyeLookInLeft"] == 0.0
    back = decode_payload(payload(frame))
    assert back.pose[1] == pytest.approx(0.1, abs=1e-4)  # head yaw, radians
    assert np.allclose(back.weights, frame.weights, atol=1 / 255)


def test_oculus_visemes_cover_mpeg4s_fourteen_and_silence() -> None:
    table = oculus_visemes()
    assert len(table) == 15 and len(set(table)) == 15
    assert table[0] == "sil" and table[1] == "PP" and table[2] == "FF"
