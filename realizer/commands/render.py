"""``realizer render FILE.bml -o out.mp4``: render a block offscreen.

Runs the block through the same stage and session as the server, frame by
frame at ``--fps``, deforms the face and renders each frame offscreen
(OSMesa or EGL), writing a video through ffmpeg (``.mp4``, ``.mkv``,
``.webm``, ``.mov``) or numbered PNG files into a folder (a name without a
suffix); any other suffix is refused. Prints the BML feedback on stdout as
the block plays, like ``realizer send``, and a progress bar on stderr when
it is a terminal. Speech is heard: a video gets it as its audio track
(AAC; Opus in WebM), in sync with the frames; a PNG folder gets a WAV beside
it (``FOLDER.wav``). Exit 0 when done, 1 when the block was refused, 2 when
rendering or writing failed.

``FILE`` may also be a FAP file: the text ``.fap`` format or an MPEG-4
coded one (``realizer faps --coded dct|lowdelay``), rendered at its own
frame rate.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

from realizer.commands import add_idle_options, error_line, plain_text

VIDEO_SUFFIXES = (".mp4", ".mkv", ".webm", ".mov")


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "render",
        help="render a BML block offscreen to a video or PNG files",
        description=plain_text(__doc__.split("\n\n")[1]) if __doc__ else None,
    )
    parser.add_argument("file", type=Path, metavar="FILE.bml")
    parser.add_argument(
        "-o", "--output", type=Path, required=True, help="a video file or a folder for PNGs"
    )
    parser.add_argument("--size", default="512x512", help="WIDTHxHEIGHT in pixels (512x512)")
    parser.add_argument("--fps", type=float, default=30.0, help="frames per second (30)")
    parser.add_argument("--face", default=None, metavar="PATH", help="face parameter file")
    parser.add_argument("--character", default=None, help="character id (default: the block's)")
    parser.add_argument("--view", choices=("front", "left", "right"), default="front")
    parser.add_argument("--tail", type=float, default=0.5, help="seconds after the block ends")
    parser.add_argument(
        "--max-duration", type=float, default=120.0, help="stop after this many seconds (120)"
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    add_idle_options(parser)
    parser.set_defaults(run=run)


def _size(text: str) -> tuple[int, int]:
    width, _, height = text.lower().partition("x")
    if not (width.isdigit() and height.isdigit()) or not (16 <= int(width) <= 8192):
        raise ValueError(f"--size {text!r}: expected WIDTHxHEIGHT, e.g. 640x480")
    if not 16 <= int(height) <= 8192:
        raise ValueError(f"--size {text!r}: height out of range")
    return int(width), int(height)


def check_output(path: Path) -> None:
    """Refuse an output this command cannot write (``-o x.avi`` is not a folder of PNGs)."""
    suffix = path.suffix.lower()
    if suffix in VIDEO_SUFFIXES or not suffix or path.is_dir():
        return
    raise ValueError(
        f"{path}: cannot write {suffix} files; use {', '.join(VIDEO_SUFFIXES)}, "
        "or a folder name without a suffix for PNG frames"
    )


def _fap_input(path: Path) -> Any:
    """The frames of a FAP file (text ``.fap``, or MPEG-4 coded by ``realizer faps
    --coded``), or None when ``path`` is something else (BML)."""
    from realizer.face.fapcoding import DCT_MAGIC, STREAM_MAGIC, read_any_fap_file

    with open(path, "rb") as handle:
        head = handle.read(8)
    if head in (DCT_MAGIC, STREAM_MAGIC) or path.suffix.lower() == ".fap":
        return read_any_fap_file(path)
    return None


def _replay(recorded: Any) -> Any:
    """A recorded FAP stream in the shape of :func:`run_offline`'s result."""
    from types import SimpleNamespace

    frames = [
        SimpleNamespace(
            number=n,
            time=n / recorded.fps,
            frame=SimpleNamespace(values=recorded.values[n], mask=recorded.mask[n]),
            feedback=(),
        )
        for n in range(recorded.values.shape[0])
    ]
    end = (len(frames) - 1) / recorded.fps if frames else 0.0
    return SimpleNamespace(
        frames=frames, first_feedback=(), accepted=True, block_id="", predicted_end=end
    )


def run(args: argparse.Namespace) -> int:
    from realizer.extras import require

    require("render", "realizer render")
    import numpy as np
    from tqdm import tqdm

    from realizer.errors import RealizerError
    from realizer.face.deform import deform
    from realizer.face.render import FaceRenderer, save_png
    from realizer.service.assets import load_face, session_factory
    from realizer.service.offline import run_offline
    from realizer.service.stage import Stage

    try:
        width, height = _size(args.size)
        if not 1 <= args.fps <= 240:
            raise ValueError("--fps must be between 1 and 240")
        check_output(args.output)
        recorded = _fap_input(args.file)  # a .fap or MPEG-4 coded FAP file, not BML
        text = "" if recorded is not None else args.file.read_text(encoding="utf-8")
        face = load_face(args.face)
    except (ValueError, OSError, UnicodeDecodeError, RealizerError) as exc:
        print(error_line("render", exc), file=sys.stderr)
        return 2
    if recorded is None:
        from realizer.bml_parser import BmlError, parse_bml

        try:  # a block that does not parse is refused: said as every command says it
            parse_bml(text, source=str(args.file))
        except BmlError as exc:
            print(str(exc), file=sys.stderr)
            return 1
    video = args.output.suffix.lower() in VIDEO_SUFFIXES
    if video and shutil.which("ffmpeg") is None:
        print("realizer render: ffmpeg is not installed (scripts/setup.sh)", file=sys.stderr)
        return 2

    session: Any = None  # the character's session, for its speech audio
    if recorded is not None:
        offline = _replay(recorded)
        args.fps = recorded.fps
    else:
        stage = Stage(session_factory(face, idle=args.idle, seed=args.seed))
        offline = run_offline(
            stage,
            text,
            args.fps,
            character=args.character,
            tail=args.tail,
            max_duration=args.max_duration,
        )
    for fb in offline.first_feedback:  # feedback on stdout, as `realizer send` prints it
        print(" ".join(fb.xml.split()), flush=True)
    if not offline.accepted:
        print(f"realizer render: block {offline.block_id!r} was refused", file=sys.stderr)
        return 1
    expected = None
    if offline.predicted_end is not None:
        expected = int(min(offline.predicted_end + args.tail, args.max_duration) * args.fps) + 1

    try:
        renderer = FaceRenderer(face, width, height)
    except RealizerError as exc:
        print(f"realizer render: {exc}", file=sys.stderr)
        return 2
    encoder: subprocess.Popen[bytes] | None = None
    if recorded is None:
        found = stage.characters.get(offline.character)
        session = found.session if found is not None else None
    soundtrack = Soundtrack(session, args.fps)
    silent_video = args.output.with_name(f".{args.output.stem}.video{args.output.suffix}")
    if video:
        args.output.parent.mkdir(parents=True, exist_ok=True)
        encoder = subprocess.Popen(
            [
                "ffmpeg", "-loglevel", "error", "-y",
                "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{width}x{height}",
                "-r", f"{args.fps:g}", "-i", "-",
                "-c:v", "libx264", "-pix_fmt", "yuv420p", "-movflags", "+faststart",
                str(silent_video),
            ],
            stdin=subprocess.PIPE,
        )  # fmt: skip
    else:
        args.output.mkdir(parents=True, exist_ok=True)
    # tqdm draws on stderr only when it is a terminal (disable=None)
    progress = tqdm(
        total=expected,
        unit="frame",
        desc="render",
        file=sys.stderr,
        disable=True if args.quiet else None,
        leave=False,
    )
    count = 0
    try:
        with renderer:
            for frame in offline.frames:
                vector = np.where(frame.frame.mask, frame.frame.values, 0.0)
                image = renderer.render(deform(face, vector), view=args.view)
                if encoder is not None:
                    assert encoder.stdin is not None
                    encoder.stdin.write(np.ascontiguousarray(image).tobytes())
                else:
                    save_png(image, args.output / f"frame_{frame.number:05d}.png")
                count += 1
                soundtrack.take(frame.number)
                for fb in frame.feedback:  # the feedback as the block plays
                    progress.write(" ".join(fb.xml.split()), file=sys.stdout)
                progress.update()
    except (BrokenPipeError, OSError) as exc:
        progress.close()
        print(f"realizer render: writing failed: {exc}", file=sys.stderr)
        return 2
    finally:
        if encoder is not None and encoder.stdin is not None:
            encoder.stdin.close()
    progress.close()
    if encoder is not None and encoder.wait() != 0:
        silent_video.unlink(missing_ok=True)
        print("realizer render: ffmpeg failed", file=sys.stderr)
        return 2
    try:
        if video:
            soundtrack.mux(silent_video, args.output, count)
        elif soundtrack.heard:
            wav = args.output.with_name(args.output.name + ".wav")
            soundtrack.write_wav(wav, count)
            print(f"realizer render: speech -> {wav}", file=sys.stderr)
    except (OSError, subprocess.SubprocessError) as exc:
        print(f"realizer render: writing the audio failed: {exc}", file=sys.stderr)
        return 2
    finally:
        silent_video.unlink(missing_ok=True)
    print(f"realizer render: {count} frames at {args.fps:g} fps -> {args.output}", file=sys.stderr)
    return 0


class Soundtrack:
    """The speech audio of a render, taken from the session frame by frame.

    Frame ``n`` shows time ``n / fps``; the audio of ``[n / fps, (n + 1) / fps)``
    is taken at that frame (before the session forgets finished speech), so
    the track starts at the video's time 0 and stays in sync with it.
    """

    RATE = 22050

    def __init__(self, session: Any, fps: float) -> None:
        self.session = session
        self.fps = fps
        self.chunks: list[Any] = []
        self.heard = False

    def take(self, number: int) -> None:
        audio = getattr(self.session, "audio", None)
        if audio is None:
            return
        chunk = audio(number / self.fps, (number + 1) / self.fps, self.RATE)
        if chunk is not None:
            self.chunks.append(chunk)
            self.heard = self.heard or bool(chunk.samples.any())

    def samples(self, frames: int) -> Any:
        import numpy as np

        total = round(frames / self.fps * self.RATE)
        out = np.zeros(total, dtype=np.int16)
        for chunk in self.chunks:
            first = round(chunk.start * self.RATE)
            piece = chunk.samples[: max(0, total - first)]
            out[first : first + len(piece)] = piece
        return out

    def write_wav(self, path: Path, frames: int) -> None:
        import wave

        with wave.open(str(path), "wb") as wav:
            wav.setnchannels(1)
            wav.setsampwidth(2)
            wav.setframerate(self.RATE)
            wav.writeframes(self.samples(frames).astype("<i2").tobytes())

    def mux(self, video: Path, output: Path, frames: int) -> None:
        """The video with the speech as its audio track (AAC; Opus in WebM)."""
        if not self.heard:
            video.replace(output)
            return
        wav = output.with_name(f".{output.stem}.speech.wav")
        try:
            self.write_wav(wav, frames)
            codec = ["-c:a", "libopus"] if output.suffix.lower() == ".webm" else ["-c:a", "aac"]
            subprocess.run(
                ["ffmpeg", "-loglevel", "error", "-y", "-i", str(video), "-i", str(wav),
                 "-map", "0:v", "-map", "1:a", "-c:v", "copy", *codec, "-b:a", "96k",
                 "-movflags", "+faststart", str(output)],
                check=True,
            )  # fmt: skip
        finally:
            wav.unlink(missing_ok=True)
