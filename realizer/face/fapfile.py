"""``.fap`` files: FAP streams in the text format of Xface and Greta.

The format (MPEG-4 FAP text files as Xface and Greta read and write them)::

    2.1 my face 25 3           <- version, name, frames per second, frame count
    0 0 1 0 ... 0              <- frame 0: mask, one 0/1 per FAP 1..68
    0 400 -80 ...              <- frame 0: frame number, then the value of each
                                  FAP whose mask is 1, in FAP order (integers)
    0 0 1 0 ...
    1 380 -76 ...

Reading is tolerant of what such files contain in the wild:

- a name with spaces: the version is the first field of the header and the
  fps and frame count its last two; the name is everything between;
- mask lines of 69 columns: writers that index FAPs from 0 write an unused
  column for FAP 0 first; it is dropped (68 columns are read as they are);
- fewer frames than the header announces (a truncated file): the frames
  present are read and the count is corrected.

Values are FAPU-scaled integers; they are kept as float64 (docs/interfaces.md).
FAP 1 and FAP 2 are written as unset: this realizer expands them into
FAPs 3..68 (:mod:`realizer.face.convert.visemes`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from realizer.face.convert.config import FAP_COUNT
from realizer.face.convert.errors import DataFileError
from realizer.face.frame import FapFrame

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

#: The version written in headers (the Xface / Greta FAP file version).
FAP_FILE_VERSION = "2.1"


@dataclass(frozen=True, slots=True, eq=False)
class FapFile:
    """A FAP stream: ``values`` (n, 68) float64 and ``mask`` (n, 68) bool per frame."""

    name: str
    fps: float
    values: FloatArray
    mask: BoolArray
    version: str = FAP_FILE_VERSION

    def __post_init__(self) -> None:
        if self.values.ndim != 2 or self.values.shape[1] != FAP_COUNT:
            raise DataFileError("FAP file values must have shape (frames, 68)")
        if self.mask.shape != self.values.shape:
            raise DataFileError("FAP file mask must have the shape of its values")
        if not self.fps > 0:
            raise DataFileError(f"fps must be positive, not {self.fps}")

    @property
    def frames(self) -> int:
        return int(self.values.shape[0])

    def times(self) -> FloatArray:
        """Each frame's time in seconds from the start."""
        return np.arange(self.frames) / self.fps

    def fap_frames(self) -> list[FapFrame]:
        """The stream as :class:`realizer.face.frame.FapFrame` objects."""
        times = self.times()
        return [
            FapFrame(self.values[i], self.mask[i], float(times[i]), i) for i in range(self.frames)
        ]

    @classmethod
    def from_fap_frames(cls, name: str, fps: float, frames: Sequence[FapFrame]) -> FapFile:
        """A stream from FapFrames (their own times are not kept: the file has fps)."""
        return fap_file_from_frames(name, fps, [(f.values, f.mask) for f in frames])


def _fps_text(fps: float) -> str:
    return str(int(fps)) if fps == int(fps) else repr(fps)


def format_fap_file(fap: FapFile) -> str:
    """The text of a ``.fap`` file; values are rounded to integers."""
    name = fap.name.strip() or "realizer"
    lines = [f"{fap.version} {name} {_fps_text(fap.fps)} {fap.frames}"]
    mask = fap.mask.copy()
    mask[:, :2] = False  # FAPs 1 and 2 are expanded, never streamed
    rounded = np.rint(fap.values).astype(np.int64)
    for number in range(fap.frames):
        lines.append(" ".join("1" if bit else "0" for bit in mask[number]))
        lines.append(" ".join([str(number), *map(str, rounded[number][mask[number]])]))
    return "\n".join(lines) + "\n"


def parse_fap_file(text: str, *, source: str = "<fap>") -> FapFile:
    """Read a ``.fap`` file (see the module docstring); raise DataFileError."""
    lines = [(n, line.split()) for n, line in enumerate(text.splitlines(), start=1) if line.strip()]
    if not lines:
        raise DataFileError("empty FAP file", source=source)
    header_line, header = lines[0]
    if len(header) < 4:
        raise DataFileError(
            "header must be 'version name fps frames'", source=source, line=header_line
        )
    try:
        fps = float(header[-2])
        announced = int(header[-1])
    except ValueError:
        raise DataFileError(
            "header must end with fps and a frame count", source=source, line=header_line
        ) from None
    body = lines[1:]
    if len(body) % 2:
        body = body[:-1]  # a truncated last frame: its mask without values
    frames = min(announced, len(body) // 2)
    values = np.zeros((frames, FAP_COUNT))
    mask = np.zeros((frames, FAP_COUNT), dtype=bool)
    for frame in range(frames):
        mask_line, mask_fields = body[2 * frame]
        value_line, value_fields = body[2 * frame + 1]
        if len(mask_fields) == FAP_COUNT + 1:
            mask_fields = mask_fields[1:]  # the unused FAP 0 column
        if len(mask_fields) != FAP_COUNT or any(f not in ("0", "1") for f in mask_fields):
            raise DataFileError(
                f"a mask line needs 68 (or 69) fields of 0 or 1, got {len(mask_fields)} fields",
                source=source,
                line=mask_line,
            )
        bits = np.array([f == "1" for f in mask_fields])
        try:
            numbers = [float(f) for f in value_fields[1:]]
        except ValueError:
            raise DataFileError("a value is not a number", source=source, line=value_line) from None
        if len(numbers) != int(bits.sum()):
            raise DataFileError(
                f"the mask sets {int(bits.sum())} FAPs but the line has {len(numbers)} values",
                source=source,
                line=value_line,
            )
        mask[frame] = bits
        values[frame, bits] = numbers
    return FapFile(" ".join(header[1:-2]), fps, values, mask, header[0])


def write_fap_file(path: str | Path, fap: FapFile) -> None:
    Path(path).write_text(format_fap_file(fap), encoding="ascii")


def read_fap_file(path: str | Path) -> FapFile:
    p = Path(path)
    return parse_fap_file(p.read_text(encoding="ascii", errors="replace"), source=str(p))


def fap_file_from_frames(
    name: str, fps: float, frames: Sequence[tuple[FloatArray, BoolArray]]
) -> FapFile:
    """Build from per-frame ``(values (68,), mask (68,))`` pairs."""
    if not frames:
        return FapFile(name, fps, np.zeros((0, FAP_COUNT)), np.zeros((0, FAP_COUNT), dtype=bool))
    return FapFile(
        name, fps, np.stack([v for v, _ in frames]), np.stack([m for _, m in frames]).astype(bool)
    )
