"""``realizer say "text" -o out.wav``: try a voice, see its phonemes and their times.

Speaks the text with the TTS backend the realizer uses for ``<speech>``
(eSpeak NG by default, docs/speech.md), writes the audio to a WAV file and
prints each word, each phoneme (IPA) with its MPEG-4 viseme (FAP 1), and
each marker, with start and end times in seconds. The text may contain
``<sync id="m"/>`` markers as in a BML ``<text>``. Exit 0 when done, 2 when
the TTS is missing or fails.
"""

from __future__ import annotations

import argparse
import sys
import wave
from pathlib import Path
from typing import Any
from xml.sax.saxutils import quoteattr

from realizer.commands import plain_text

BML_NS = "http://www.bml-initiative.org/bml/bml-1.0"


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "say",
        help="speak a text with the TTS to a WAV and print its phonemes and times",
        description=plain_text(__doc__.split("\n\n")[1]) if __doc__ else None,
    )
    parser.add_argument("text", help='the words; <sync id="m"/> markers are allowed')
    parser.add_argument("-o", "--output", type=Path, default=None, help="a WAV file to write")
    parser.add_argument("--lang", default=None, help="language (BCP 47, as xml:lang), e.g. de")
    parser.add_argument("--tts", choices=("espeak", "piper"), default="espeak")
    parser.add_argument("--piper-model", default=None, metavar="PATH.onnx")
    parser.add_argument("--rate", type=int, default=175, help="eSpeak NG words per minute")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from realizer.bml_parser import BmlError, parse_bml
    from realizer.engines.speech import TtsError, load_backend
    from realizer.engines.speech.espeak import EspeakBackend
    from realizer.engines.speech.lipsync import load_lip_model

    lang = f" xml:lang={quoteattr(args.lang)}" if args.lang else ""
    try:
        block = parse_bml(
            f'<bml xmlns="{BML_NS}" id="say"><speech id="s"{lang}><text>{args.text}</text>'
            "</speech></bml>"
        ).block
    except BmlError as exc:
        print(f"realizer say: the text is not valid BML text: {exc}", file=sys.stderr)
        return 2
    speech = block.behaviours[0].speech if block.behaviours else None
    if speech is None:
        print("realizer say: nothing to say", file=sys.stderr)
        return 2
    try:
        options = {"model": args.piper_model} if args.piper_model else {}
        backend = load_backend(args.tts, **options)
        if isinstance(backend, EspeakBackend):
            backend.rate = args.rate
        if args.lang and not backend.has_language(args.lang):
            print(f"realizer say: no voice for {args.lang!r}; the default voice speaks",
                  file=sys.stderr)  # fmt: skip
        result = backend.synthesize(speech, args.lang)
    except TtsError as exc:
        print(f"realizer say: {exc}", file=sys.stderr)
        return 2
    model = load_lip_model()
    print(f"voice {result.voice} ({result.backend}), {result.duration:.3f} s, "
          f"{result.sample_rate} Hz")  # fmt: skip
    print("words:")
    for word, start, end in result.words:
        print(f"  {start:7.3f} {end:7.3f}  {word}")
    if result.markers:
        print("markers:")
        for name, time in sorted(result.markers.items(), key=lambda item: item[1]):
            print(f"  {time:7.3f}          {name}")
    print("phonemes (IPA, viseme):")
    for phoneme in result.phonemes:
        visemes, _ = model.lookup(phoneme.symbol)
        shown = phoneme.symbol or "(pause)"
        names = "+".join(str(v) for v in visemes)
        print(f"  {phoneme.start:7.3f} {phoneme.end:7.3f}  {shown:<8} {names}")
    if args.output is not None:
        try:
            args.output.parent.mkdir(parents=True, exist_ok=True)
            with wave.open(str(args.output), "wb") as wav:
                wav.setnchannels(1)
                wav.setsampwidth(2)
                wav.setframerate(result.sample_rate)
                wav.writeframes(result.audio.astype("<i2").tobytes())
        except OSError as exc:
            print(f"realizer say: writing {args.output} failed: {exc}", file=sys.stderr)
            return 2
        print(f"realizer say: {result.duration:.3f} s -> {args.output}", file=sys.stderr)
    return 0
