"""MPEG-4 FAP coding (realizer.face.fapcoding): low-delay arithmetic coding
and DCT coding of FAP streams."""

from __future__ import annotations

import contextlib
from functools import cache

import numpy as np
import pytest

from realizer.commands.faps import BlockRecording, record_block
from realizer.face.fapcoding import (
    FapCodingError,
    FapStreamDecoder,
    FapStreamEncoder,
    decode_dct_file,
    encode_dct_file,
    is_intra,
    quant_steps,
)

NS = "http://www.bml-initiative.org/bml/bml-1.0"
SENTENCE = "Hello there, I am really glad to see you today, and I hope we can talk a while. "


def talking_bml(seconds: float) -> str:
    """A block that talks for about ``seconds`` with a smile, brows and nods."""
    text = SENTENCE * max(1, round(seconds / 4.5))
    return (
        f'<bml xmlns="{NS}" id="talk"><speech id="s"><text>{text}</text></speech>'
        '<faceLexeme id="f" lexeme="RAISE_MOUTH_CORNERS" amount="0.7" start="1" end="9"/>'
        '<faceLexeme id="b" lexeme="RAISE_BROWS" start="12" end="15"/>'
        '<head id="h" lexeme="NOD" start="2" repetition="2"/>'
        '<head id="h2" lexeme="SHAKE" start="20"/></bml>'
    )


@cache
def talking(seconds: float = 30.0, fps: float = 25.0) -> BlockRecording:
    return record_block(talking_bml(seconds), fps, seconds)


def test_decoded_frames_are_within_each_faps_quantisation_step() -> None:
    recording = talking(10.0)
    for quant in (1, 10, 31):
        encoder, decoder = FapStreamEncoder(quant, 25), FapStreamDecoder()
        step = quant_steps() * quant
        for n, (values, mask) in enumerate(zip(recording.values, recording.mask, strict=True)):
            decoded = decoder.decode(encoder.encode(values, mask), n)
            assert decoded is not None
            got, got_mask = decoded
            assert np.array_equal(got_mask, mask)
            assert np.all(np.abs(got - values)[mask] <= step[mask] / 2 + 1e-9)
            assert not got[~mask].any()


def test_escaped_values_and_every_fap_survive_coding() -> None:
    rng = np.random.default_rng(3)
    encoder, decoder = FapStreamEncoder(1, 10), FapStreamDecoder()
    for _ in range(30):
        values = rng.uniform(-20000, 20000, 68)
        mask = rng.random(68) < 0.7
        got = decoder.decode(encoder.encode(values, mask))
        assert got is not None
        assert np.array_equal(got[1], mask)
        assert np.all(np.abs(got[0] - values)[mask] <= quant_steps()[mask] / 2 + 1e-9)


def test_a_viewer_joining_mid_stream_decodes_from_the_next_intra_frame() -> None:
    recording = talking(10.0)
    encoder = FapStreamEncoder(10, 25)
    frames = [encoder.encode(v, m) for v, m in zip(recording.values, recording.mask, strict=True)]
    assert [n for n, f in enumerate(frames) if is_intra(f)][:3] == [0, 25, 50]
    late = FapStreamDecoder()
    results = [late.decode(frame, n, n - 1) for n, frame in enumerate(frames) if n >= 7]
    assert all(r is None for r in results[: 25 - 7])
    assert all(r is not None for r in results[25 - 7 :])
    # a frame it never received: it waits for the next intra frame again
    gap = FapStreamDecoder()
    assert gap.decode(frames[0], 0) is not None
    assert gap.decode(frames[2], 2, 1) is None
    assert gap.decode(frames[3], 3, 2) is None
    assert gap.decode(frames[25], 25, None) is not None


def test_a_30_second_talking_block_codes_under_2_kbit_per_second() -> None:
    recording = talking()
    encoder = FapStreamEncoder(10, 25)
    total = sum(
        len(encoder.encode(v, m)) for v, m in zip(recording.values, recording.mask, strict=True)
    )
    seconds = len(recording.values) / 25.0
    assert seconds >= 29.0
    assert recording.mask.any(axis=0).sum() >= 6  # it is not silent: many FAPs move
    assert total * 8 / seconds < 2000


def test_malformed_frames_raise_instead_of_looping() -> None:
    decoder = FapStreamDecoder()
    with pytest.raises(FapCodingError):
        decoder.decode(b"")
    with pytest.raises(FapCodingError):
        decoder.decode(bytes([0x80]) + b"\xff" * 5000)
    for seed in range(20):
        junk = bytes([0x8A]) + np.random.default_rng(seed).bytes(40)
        with contextlib.suppress(FapCodingError):
            FapStreamDecoder().decode(junk)


def test_dct_files_round_trip_within_the_quantisation() -> None:
    recording = talking(10.0)
    data = encode_dct_file(recording.values, recording.mask, 25.0, 10)
    back = decode_dct_file(data)
    assert back.fps == 25.0
    assert np.array_equal(back.mask, recording.mask)
    expected = np.where(recording.mask, recording.values, 0.0)
    # 16 coefficients each off by at most half an AC step (the DC a quarter of it)
    bound = quant_steps() * 10 * 0.5 * np.sqrt(2 / 16) * 16
    assert np.all(np.abs(back.values - expected) <= bound + 1e-9)
    assert len(data) * 8 / (len(recording.values) / 25.0) < 2000
    with pytest.raises(FapCodingError):
        decode_dct_file(data[:-40])


def test_faps_coded_files_are_read_back_by_face(tmp_path) -> None:  # type: ignore[no-untyped-def]
    import subprocess
    import sys
    from pathlib import Path

    from realizer.commands.face import fap_file_frame
    from realizer.face.fapcoding import read_any_fap_file

    root = Path(__file__).resolve().parents[2]
    example = root / "examples/bml/01_smile.xml"
    plain = tmp_path / "smile.fap"
    subprocess.run(
        [sys.executable, "-m", "realizer", "faps", str(example), "-o", str(plain)],
        cwd=root, check=True, capture_output=True, timeout=120,
    )  # fmt: skip
    reference = read_any_fap_file(plain)
    for kind in ("dct", "lowdelay"):
        coded = tmp_path / f"smile.{kind}"
        done = subprocess.run(
            [sys.executable, "-m", "realizer", "faps", str(example), "--coded", kind,
             "-o", str(coded)],
            cwd=root, check=True, capture_output=True, text=True, timeout=120,
        )  # fmt: skip
        assert "kbit/s" in done.stdout
        back = read_any_fap_file(coded)
        assert np.array_equal(back.mask, reference.mask)
        frame = int(np.argmax(reference.mask.sum(axis=1)))
        got = fap_file_frame(str(coded), frame)
        want = np.where(reference.mask[frame], reference.values[frame], 0.0)
        assert np.abs(got - want).max() <= 4 * quant_steps().max() * 10
        assert np.abs(got - want).max() < np.abs(want).max()  # close, not just anything
    csv = tmp_path / "smile.csv"
    subprocess.run(
        [sys.executable, "-m", "realizer", "faps", str(example), "--arkit", "-o", str(csv)],
        cwd=root, check=True, capture_output=True, timeout=120,
    )  # fmt: skip
    rows = csv.read_text().splitlines()
    assert rows[0].startswith("time,eyeBlinkLeft,") and len(rows) == reference.values.shape[0] + 1


@pytest.mark.opengl
@pytest.mark.slow
def test_render_plays_a_coded_file_back(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from pathlib import Path

    from PIL import Image

    from realizer.cli import main
    from realizer.face.default import load_default_face
    from realizer.face.render import FaceRenderer, RenderUnavailableError

    try:
        FaceRenderer(load_default_face(), 8, 8).close()
    except RenderUnavailableError as error:
        pytest.skip(f"no OpenGL offscreen context here: {error}")
    root = Path(__file__).resolve().parents[2]
    coded = tmp_path / "smile.dct"
    assert main(["faps", str(root / "examples/bml/01_smile.xml"), "--coded", "dct",
                 "-o", str(coded)]) == 0  # fmt: skip
    frames = read_any_fap_file_frames(coded)
    out = tmp_path / "frames"
    assert main(["render", str(coded), "-o", str(out), "--size", "96x96", "--quiet"]) == 0
    images = sorted(out.glob("frame_*.png"))
    assert len(images) == frames
    first = np.asarray(Image.open(images[0]), dtype=np.int16)
    busiest = np.asarray(Image.open(images[len(images) // 2]), dtype=np.int16)
    assert np.abs(busiest - first).sum() > 0  # the smile plays


def read_any_fap_file_frames(path) -> int:  # type: ignore[no-untyped-def]
    from realizer.face.fapcoding import read_any_fap_file

    return int(read_any_fap_file(path).values.shape[0])
