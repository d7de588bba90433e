"""Speech: TTS latency and speed per backend, lip-sync cost, and audio/frame offset on the wire.

Per backend (eSpeak NG always; Piper when ``REALIZER_PIPER_MODEL`` names a
voice model, or with the Piper and voice that ``scripts/piper_voice.sh`` puts
into ``.cache/piper``):

- time to first audio for a sentence (wall time from the call to the first
  audio chunk the synthesiser hands back; goal for eSpeak NG < 20 ms);
- real-time factor: seconds of audio per second of synthesis (goal for
  eSpeak NG >= 50x);
- planning a block with that sentence (the TTS runs while planning, so
  this is how long a block waits before it is scheduled).

Lip sync, per character-frame at 60 fps, per backend (the phonemes differ):
the articulation's two animations evaluated and mixed, plus the one-off
sampling of the speech spread over its frames (goal < 50 microseconds).

Audio to frame on the viewer stream, per backend: a real service on a free
loopback port, a real viewer; for a speech the offset
between the first audible sample (audio chunk time plus sample index) and
the first frame whose mouth opens, both on the server clock. Measured: the
sound starts about when the mouth has opened (the mouth starts moving the
visual lead before), within 45 ms of the picture beyond that lead. Timings
are printed, never asserted.
"""

from __future__ import annotations

import asyncio
import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _timing import best_of, figure, skipped

from realizer.bml_parser import BML_NS, parse_bml

SENTENCE = "The quick brown fox jumps over the lazy dog, and then it runs away."
BLOCK = (
    f'<bml xmlns="{BML_NS}" id="b"><speech id="s"><text>{SENTENCE}</text></speech>'
    '<head id="h" lexeme="NOD" start="0"/></bml>'
)
FPS = 60.0


def _speech_text(text: str) -> object:
    block = parse_bml(f'<bml xmlns="{BML_NS}" id="t"><speech id="s"><text>{text}</text>'
                      "</speech></bml>").block  # fmt: skip
    return block.behaviours[0].speech


ROOT = Path(__file__).resolve().parents[1]
#: Where scripts/piper_voice.sh puts Piper (its own venv) and a voice.
PIPER_CACHE = ROOT / ".cache" / "piper"


def _piper_model() -> str:
    """The Piper voice to measure: REALIZER_PIPER_MODEL, else the cached one
    (whose Piper program is then put first on PATH), else ""."""
    model = os.environ.get("REALIZER_PIPER_MODEL", "")
    cached = PIPER_CACHE / "en_US-joe-medium.onnx"
    program = PIPER_CACHE / "venv" / "bin" / "piper"
    if program.is_file():
        os.environ["PATH"] = f"{program.parent}{os.pathsep}{os.environ.get('PATH', '')}"
    if not model and cached.is_file():
        model = str(cached)
    return model


def _backend(name: str, backend: object, quick: bool) -> None:
    speech = _speech_text(SENTENCE)
    repeats = 3 if quick or name != "espeak" else 15  # Piper: a process per segment
    firsts, factors = [], []
    for _ in range(repeats):
        started = time.perf_counter()
        result = backend.synthesize(speech)  # type: ignore[attr-defined]
        spent = time.perf_counter() - started
        firsts.append(result.first_audio if result.first_audio > 0 else spent)
        factors.append(result.duration / spent)
    espeak = name == "espeak"
    figure(f"{name}: time to first audio, one sentence", statistics.median(firsts) * 1e3, "ms",
           goal=20.0 if espeak else None,
           note=f"median of {repeats}; {result.duration:.2f} s of audio")  # fmt: skip
    figure(f"{name}: real-time factor", statistics.median(factors), "x real time",
           goal=50.0 if espeak else None, higher_is_better=True)  # fmt: skip


def _planning(quick: bool) -> None:
    from realizer.engines import EngineRegistry
    from realizer.scheduler.plan import schedule_block

    block = parse_bml(BLOCK).block
    registry = EngineRegistry.standard()

    def plan() -> None:
        for engine in registry.engines:  # a new text each time: no cached synthesis
            cache = getattr(engine, "_cache", None)
            if cache is not None:
                cache.clear()
        schedule_block(block, registry=registry)

    seconds = best_of(plan, repeats=3 if quick else 10)
    figure("espeak: planning a block with one sentence (synthesis included)", seconds * 1e3, "ms")


def _lip_sync(quick: bool, name: str = "espeak", engine: object = None) -> None:
    from realizer.engines.speech import SpeechEngine
    from realizer.engines.speech.lipsync import lip_animations
    from realizer.face.tracks import mix

    engine = engine or SpeechEngine.default()
    assert isinstance(engine, SpeechEngine)
    behaviour = parse_bml(BLOCK).block.behaviours[0]
    synthesis = engine.synthesis(behaviour)
    assert synthesis is not None
    phonemes = [(p.symbol, p.start, p.end) for p in synthesis.phonemes]
    frames = int(synthesis.duration * FPS)
    sampling = best_of(lambda: lip_animations(phonemes), repeats=3 if quick else 10)
    parts = lip_animations(phonemes)
    times = [i / FPS for i in range(frames)]

    def every_frame() -> None:
        for t in times:
            mix(parts, t)

    per_frame = best_of(every_frame, repeats=3 if quick else 10) / frames
    total = per_frame + sampling / frames
    figure(f"{name}: lip sync per character-frame (mix of the articulation + sampling share)",
           total * 1e6, "us", goal=50.0,
           note=f"mix {per_frame * 1e6:.1f} us + sampling {sampling * 1e3:.2f} ms "
                f"over {frames} frames")  # fmt: skip


async def _viewer_offset(
    speech: dict[str, str] | None = None, wait: float = 4.0
) -> tuple[float, float] | None:
    import numpy as np
    from websockets.asyncio.client import connect

    from realizer.engines.speech.lipsync import load_lip_model, mouth_opening
    from realizer.service import codec
    from realizer.service.assets import face_assets, load_face, session_factory
    from realizer.service.server import RealizerService, ServiceConfig
    from realizer.service.stage import Stage

    face = load_face()
    service = RealizerService(
        ServiceConfig(host="127.0.0.1", port=0, fps=FPS),
        Stage(session_factory(face, speech=speech)),
        face_assets(face),
    )
    await service.start()
    try:
        viewer = await connect(f"ws://127.0.0.1:{service.port}/view")
        await viewer.recv()
        submitter = await connect(f"ws://127.0.0.1:{service.port}/bml?format=json")
        await submitter.recv()
        await submitter.send(BLOCK)
        audio_onset = mouth_onset = None
        loop = asyncio.get_running_loop()
        until = loop.time() + wait  # the block is scheduled once its speech is synthesised
        while loop.time() < until and (audio_onset is None or mouth_onset is None):
            try:
                message = codec.unpack(await asyncio.wait_for(viewer.recv(), 1.0))  # type: ignore[arg-type]
            except TimeoutError:
                continue
            if message["type"] == "audio" and audio_onset is None:
                samples = np.frombuffer(message["samples"], dtype="<i2")
                loud = np.flatnonzero(np.abs(samples.astype(np.int32)) > 1000)
                if loud.size:
                    audio_onset = message["t"] + loud[0] / message["rate"]
            elif message["type"] == "frame" and mouth_onset is None and "fap" in message:
                ids = np.frombuffer(message["fap"]["ids"], dtype=np.uint8)
                values = np.frombuffer(message["fap"]["values"], dtype="<f4")
                vector = np.zeros(68)
                vector[ids.astype(int) - 1] = values
                if mouth_opening(vector) > 50.0:
                    mouth_onset = message["t"]
        await viewer.close()
        await submitter.close()
        if audio_onset is None or mouth_onset is None:
            return None
        return audio_onset - mouth_onset, load_lip_model().lead
    finally:
        await service.shutdown()


def run(quick: bool = False) -> None:
    from realizer.engines.speech import TtsError, load_backend

    print(f"speech: one sentence ({len(SENTENCE)} characters)")
    try:
        _backend("espeak", load_backend("espeak"), quick)
    except TtsError as exc:
        skipped("espeak", str(exc))
        return
    model = _piper_model()
    piper = None
    try:
        if not model:
            raise TtsError(
                "set REALIZER_PIPER_MODEL to a Piper voice model or run scripts/piper_voice.sh"
            )
        piper = load_backend("piper", model=model)
        _backend("piper", piper, quick)
    except TtsError as exc:
        skipped("piper", str(exc))
    _planning(quick)
    _lip_sync(quick)
    if piper is not None:
        from realizer.engines.speech import SpeechEngine

        _lip_sync(quick, "piper", SpeechEngine(piper))
    _offset("espeak", None, 4.0)
    if piper is not None:
        _offset("piper", {"tts": "piper", "model": model}, 60.0)


def _offset(name: str, speech: dict[str, str] | None, wait: float) -> None:
    try:
        measured = asyncio.run(asyncio.wait_for(_viewer_offset(speech, wait), wait + 30.0))
    except TimeoutError:
        measured = None
    if measured is None:
        skipped(f"{name}: audio to frame offset on the viewer stream",
                "no audio or mouth seen in time")  # fmt: skip
        return
    offset, lead = measured
    note = f"the visual lead is {lead * 1e3:.0f} ms; one frame is {1e3 / FPS:.1f} ms"
    figure(f"{name}: viewer stream: first sound minus first mouth opening", offset * 1e3, "ms",
           note=note)  # fmt: skip
    figure(f"{name}: viewer stream: |sound - picture| beyond the visual lead",
           abs(offset - lead) * 1e3, "ms", goal=45.0)  # fmt: skip


if __name__ == "__main__":
    run(quick="--quick" in sys.argv)
