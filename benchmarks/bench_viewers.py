"""Bytes on the wire per viewer format: what a viewer receives per frame.

Plays a 30-second talking block (speech with a smile, brows and head
motion) and 30 seconds of idling in a session on a simulated clock, at 25
and at 60 frames per second, and encodes every frame as the service's stage
does (``realizer.service.stage.FrameEncoder``, encoding once per tick) in
each viewer format: ``fap`` (set FAPs, float32), ``coded`` (MPEG-4 low-delay
FAP coding at FAP_QUANT 10, intra frames once a second), ``arkit`` (52
weights and the head and eye angles), ``int16`` (vertex deltas) and
``float32`` (every vertex). For each it prints the bytes per frame message
and the kbit/s, and for ``coded`` also the coded FAP payload alone (what
MPEG-4's bit-rate figures count: "300 - 2000 bits/s", "Face and 2-D mesh
animation in MPEG-4", section 2.2). The face's deformation model, sent
once per subscription (``model=true``), is printed too.

Goal: the coded payload of the talking block at 25 fps under 2 kbit/s.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import NamedTuple

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _timing import figure

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

NS = "http://www.bml-initiative.org/bml/bml-1.0"
SENTENCE = "Hello there, I am really glad to see you today, and I hope we can talk a while. "
TALK = (
    f'<bml xmlns="{NS}" id="talk"><speech id="s"><text>{SENTENCE * 7}</text></speech>'
    '<faceLexeme id="f" lexeme="RAISE_MOUTH_CORNERS" amount="0.7" start="1" end="9"/>'
    '<faceLexeme id="b" lexeme="RAISE_BROWS" start="12" end="15"/>'
    '<head id="h" lexeme="NOD" start="2" repetition="2"/>'
    '<head id="h2" lexeme="SHAKE" start="20"/></bml>'
)
IDLE = f'<bml xmlns="{NS}" id="idle"><wait id="w" duration="30"/></bml>'
FORMATS = ("fap", "coded", "arkit", "int16", "float32")


class Frame(NamedTuple):
    values: np.ndarray
    mask: np.ndarray


def options(fmt: str) -> object:
    from realizer.service.messages import ViewOptions

    if fmt == "coded":
        return ViewOptions(fap=False, coded=True)
    if fmt == "arkit":
        return ViewOptions(fap=False, arkit=True)
    if fmt in ("int16", "float32"):
        return ViewOptions(fap=False, vertices=fmt)  # type: ignore[arg-type]
    return ViewOptions()


def measure(bml: str, fps: float, seconds: float, fmt: str, face: object) -> tuple[float, float]:
    """(mean bytes per frame message, mean coded payload bytes per frame)."""
    import msgpack

    from realizer.commands.faps import record_block
    from realizer.face.deform import deform
    from realizer.service.stage import FrameEncoder

    recording = record_block(bml, fps, seconds)
    encoder = FrameEncoder("default", face, deform, fps)  # type: ignore[arg-type]
    wanted = options(fmt)
    total = payload = 0
    count = 0
    for number, (values, mask) in enumerate(zip(recording.values, recording.mask, strict=True)):
        data = encoder.encode(number, number / fps, Frame(values, mask), [wanted])[wanted]  # type: ignore[list-item]
        total += len(data)
        if fmt == "coded":
            payload += len(msgpack.unpackb(data)["coded"])
        count += 1
    return total / count, payload / count


def run(quick: bool = False) -> None:
    from realizer.face.default import load_default_face
    from realizer.service.stage import FrameEncoder

    face = load_default_face()
    seconds = 10.0 if quick else 30.0
    print(f"viewer formats, {seconds:g} s of talking and of idling (message bytes per frame)")
    columns = ("format", 8), ("fps", 4), ("talking B/frame", 16), ("kbit/s", 9)
    columns += ("idle B/frame", 13), ("kbit/s", 9)
    print(" ".join(f"{name:>{width}}" for name, width in columns))
    for fmt in FORMATS:
        for fps in (25.0, 60.0):
            if quick and fmt == "float32" and fps == 60.0:
                continue
            talk, talk_payload = measure(TALK, fps, seconds, fmt, face)
            idle, idle_payload = measure(IDLE, fps, seconds, fmt, face)
            print(
                f"{fmt:>8} {fps:>4.0f} {talk:>16.1f} {talk * 8 * fps / 1000:>9.2f} "
                f"{idle:>13.1f} {idle * 8 * fps / 1000:>9.2f}"
            )
            figure(
                f"viewers {fmt} talking {fps:.0f} fps", talk * 8 * fps / 1000, "kbit/s", quiet=True
            )
            if fmt == "coded":
                rate = talk_payload * 8 * fps / 1000
                print(
                    f"{'':>8} {'':>4} coded payload alone: talking {talk_payload:.2f} B/frame "
                    f"({rate:.3f} kbit/s), idle {idle_payload:.2f} B/frame "
                    f"({idle_payload * 8 * fps / 1000:.3f} kbit/s)"
                )
                if fps == 25.0:
                    figure(
                        "coded FAP payload, talking, 25 fps, FAP_QUANT 10", rate, "kbit/s", goal=2.0
                    )
    model = len(FrameEncoder("default", face, lambda f, v: f.vertices, 25.0).model_bytes)  # type: ignore[arg-type]
    print(f"the deformation model (model=true), once per subscription: {model / 1000:.0f} kB")


if __name__ == "__main__":
    run(quick="--quick" in sys.argv)
