"""Viewer formats end to end: a real service, real sessions and the default
face; the Python client decodes the MPEG-4 coded FAP stream and the ARKit
weights, and they match what the server computed."""

from __future__ import annotations

from realizer.client import SubmitClient, ViewClient
from realizer.face.arkit import ARKIT_NAMES
from realizer.face.fapcoding import DEFAULT_FAP_QUANT, quant_steps
from tests.service.browser import service_in_thread
from tests.service.conftest import UNIT
from tests.service.test_end_to_end import real_assets, real_sessions, smile


def test_coded_and_arkit_streams_decode_to_the_servers_faps() -> None:
    steps = quant_steps() * DEFAULT_FAP_QUANT
    with service_in_thread(real_sessions(), real_assets(), fps=25.0) as service:
        url = f"ws://127.0.0.1:{service.port}"
        with (
            ViewClient(url, character="Ann", coded=True, arkit=True) as coded,
            ViewClient(url, character="Ann") as plain,
            SubmitClient(url, character="Ann") as submitter,
        ):
            assert len(coded.mesh["fapSteps"]) == 2 * 68
            # One frame of the resting face first: the viewer's first ARKit frame
            # must come before the smile is submitted, or it may already smile.
            smiles = []
            for frame in coded.frames(1, timeout=10 * UNIT):
                weights = coded.arkit(frame)
                assert weights is not None
                smiles.append(weights.weights[ARKIT_NAMES.index("mouthSmileLeft")])
            submitter.submit(smile("codedsmile", 0.0, 3.0))
            reference: dict[int, dict[int, float]] = {}
            for frame in plain.frames(40, timeout=10 * UNIT):
                reference[frame["n"]] = plain.faps(frame)
            decoded: dict[int, dict[int, float]] = {}
            for frame in coded.frames(40, timeout=10 * UNIT):
                assert "fap" in frame  # fap=true stays the default
                faps = coded.decoded_faps(frame)
                if faps is not None:
                    decoded[frame["n"]] = faps
                weights = coded.arkit(frame)
                assert weights is not None and weights.weights.shape == (52,)
                smiles.append(weights.weights[ARKIT_NAMES.index("mouthSmileLeft")])
    common = sorted(set(reference) & set(decoded))
    assert len(common) > 10
    moving = 0
    for n in common:
        assert set(decoded[n]) == set(reference[n])
        for fap, value in reference[n].items():
            assert abs(decoded[n][fap] - value) <= steps[fap - 1] / 2 + 1e-3
        moving += bool(reference[n])
    assert moving > 5  # the smile was on
    assert smiles[0] < 0.02 and max(smiles) > 0.08  # at rest, then the ARKit weights smiled


def test_coded_and_arkit_messages_match_the_protocol_schemas() -> None:
    import pytest

    pytest.importorskip("jsonschema", reason="jsonschema comes with the dev extra")
    from tests.service.test_protocol_schemas import as_json, check

    with service_in_thread(real_sessions(), real_assets(), fps=25.0) as service:
        url = f"ws://127.0.0.1:{service.port}"
        # every tick a whole frame (same=False), so predicted coded frames come
        with ViewClient(url, character="Sch", coded=True, arkit=True, same=False) as view:
            check("mesh", as_json(view.mesh))
            frames = list(view.frames(30, timeout=10 * UNIT))
            view.subscribe(coded=False, arkit=True)
    for frame in frames:
        assert "coded" in frame and "arkit" in frame
        check("frame", as_json(frame))
    assert any("codedRef" in frame for frame in frames)
    check("subscribe-request", {"type": "subscribe", "coded": False, "arkit": True})
