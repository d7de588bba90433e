"""MPEG-4 coding of FAP streams: low-delay arithmetic coding and DCT coding.

"Face and 2-D mesh animation in MPEG-4" (Tekalp and Ostermann), section 2.2:

* **Low-delay coding** (section 2.2.1, Figure 9, :class:`FapStreamEncoder`):
  each FAP's value is predicted from its previously *decoded* value, the
  prediction error is quantised with the FAP's step QP from Table 7 times
  FAP_QUANT (1..31, one value for all FAPs of a frame), and the quantised
  error is coded by an adaptive arithmetic coder with a separate
  probability model per FAP. Intra frames (no prediction, every model reset)
  come at a settable interval, so a decoder can start at any intra frame.
  Which FAPs a frame carries is a mask per FAP group (Table 2): a mask type
  per group (none, some with one bit per FAP, all), as the standard
  structures it.
* **DCT coding** (section 2.2.2, Figure 10, :func:`encode_dct_file`): for
  recordings. 16 consecutive values of one FAP are transformed (DCT-II);
  the DC coefficient is coded predictively from the previous segment's DC,
  the AC coefficients directly, both linearly quantised, the DC step a
  quarter of the AC step; each non-zero AC coefficient is one code word for
  the run of zeros before it and one for its amplitude.

Where the paper does not give the bitstream (it names the tools, not the
tables), this module fixes its own and documents it in
``protocols/viewer.md`` ("coded" layout 1) and ``docs/fap-coding.md``:
the arithmetic coder is the integer coder of Witten, Neal and Cleary with
32-bit registers; the DCT mode's variable-length codes are signed
Exp-Golomb codes. Frames carry only the FAPs that are set; a FAP left out
of a frame is not set in it (the realizer's frames are complete, see the
viewer protocol), so "retaining" values is not needed.

Complexity: encoding and decoding a frame is O(68) symbols; a decoder
reading peer bytes stops at :data:`MAX_FRAME_BYTES` and raises
:class:`FapCodingError` for anything malformed (never loops).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from realizer.face.errors import FaceError
from realizer.face.faps import FAP_COUNT, FAP_TABLE

#: Version of the coded frame layout (protocols/viewer.md).
CODED_LAYOUT = 1
#: The paper recommends FAP_QUANT <= 15 for good quality; 1..31 are legal.
DEFAULT_FAP_QUANT = 10
#: Frames between intra frames (a late viewer waits at most this long).
DEFAULT_INTRA_INTERVAL = 50
#: A coded frame longer than this is refused (68 FAPs never need 1 kB).
MAX_FRAME_BYTES = 4096

#: Quantised errors within +-RESIDUAL_RANGE have a symbol; others escape.
RESIDUAL_RANGE = 15
ESCAPE = 2 * RESIDUAL_RANGE + 1
#: Escaped values: sign and ESCAPE_BITS bits of magnitude, equiprobable.
ESCAPE_BITS = 17
MAX_QUANTISED = (1 << ESCAPE_BITS) - 1

# Adaptive models: counts start at 1, grow by INCREMENT, halve above MAX_TOTAL.
INCREMENT = 24
MAX_TOTAL = 1 << 13

# mask types per group (the standard's fap_mask_type)
MASK_NONE, MASK_SOME, MASK_ALL = 0, 1, 3

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


class FapCodingError(FaceError):
    """A coded FAP frame or file that cannot be decoded."""


def quant_steps() -> FloatArray:
    """(68,) Table 7 step sizes QP (FAPU-scaled units per step at FAP_QUANT 1)."""
    return np.array([float(FAP_TABLE[n].quant_step) for n in range(1, FAP_COUNT + 1)])


def fap_groups() -> tuple[tuple[int, ...], ...]:
    """FAP indices (0..67) of each group 1..10 of Table 2, in FAP order."""
    groups: dict[int, list[int]] = {}
    for n in range(1, FAP_COUNT + 1):
        groups.setdefault(FAP_TABLE[n].group, []).append(n - 1)
    return tuple(tuple(groups[g]) for g in sorted(groups))


_STEPS = quant_steps()
_GROUPS = fap_groups()

# -- the arithmetic coder (integer, 32-bit; Witten, Neal and Cleary 1987) -----

_TOP = (1 << 32) - 1
_HALF = 1 << 31
_QUARTER = 1 << 30


class _Encoder:
    __slots__ = ("bits", "high", "low", "pending")

    def __init__(self) -> None:
        self.low, self.high, self.pending = 0, _TOP, 0
        self.bits: list[int] = []

    def _emit(self, bit: int) -> None:
        self.bits.append(bit)
        if self.pending:
            self.bits.extend([1 - bit] * self.pending)
            self.pending = 0

    def encode(self, cum_low: int, cum_high: int, total: int) -> None:
        span = self.high - self.low + 1
        self.high = self.low + span * cum_high // total - 1
        self.low = self.low + span * cum_low // total
        while True:
            if self.high < _HALF:
                self._emit(0)
            elif self.low >= _HALF:
                self._emit(1)
                self.low -= _HALF
                self.high -= _HALF
            elif self.low >= _QUARTER and self.high < 3 * _QUARTER:
                self.pending += 1
                self.low -= _QUARTER
                self.high -= _QUARTER
            else:
                break
            self.low = 2 * self.low
            self.high = 2 * self.high + 1

    def finish(self) -> bytes:
        self.pending += 1
        self._emit(0 if self.low < _QUARTER else 1)
        bits = self.bits
        out = bytearray((len(bits) + 7) // 8)
        for i, bit in enumerate(bits):
            if bit:
                out[i >> 3] |= 0x80 >> (i & 7)
        return bytes(out)


class _Decoder:
    __slots__ = ("at", "data", "high", "low", "value")

    def __init__(self, data: bytes) -> None:
        self.data = data
        self.at = 0
        self.low, self.high = 0, _TOP
        self.value = 0
        for _ in range(32):
            self.value = 2 * self.value + self._bit()

    def _bit(self) -> int:
        i = self.at
        self.at += 1
        if i >> 3 >= len(self.data):
            if i > 8 * len(self.data) + 64:
                raise FapCodingError("coded FAP frame ends too early")
            return 0
        return (self.data[i >> 3] >> (7 - (i & 7))) & 1

    def target(self, total: int) -> int:
        span = self.high - self.low + 1
        return ((self.value - self.low + 1) * total - 1) // span

    def consume(self, cum_low: int, cum_high: int, total: int) -> None:
        span = self.high - self.low + 1
        self.high = self.low + span * cum_high // total - 1
        self.low = self.low + span * cum_low // total
        while True:
            if self.high < _HALF:
                pass
            elif self.low >= _HALF:
                self.value -= _HALF
                self.low -= _HALF
                self.high -= _HALF
            elif self.low >= _QUARTER and self.high < 3 * _QUARTER:
                self.value -= _QUARTER
                self.low -= _QUARTER
                self.high -= _QUARTER
            else:
                break
            self.low = 2 * self.low
            self.high = 2 * self.high + 1
            self.value = 2 * self.value + self._bit()


class _Model:
    """Adaptive frequencies of ``size`` symbols."""

    __slots__ = ("counts", "total")

    def __init__(self, size: int) -> None:
        self.counts = [1] * size
        self.total = size

    def _update(self, symbol: int) -> None:
        self.counts[symbol] += INCREMENT
        self.total += INCREMENT
        if self.total > MAX_TOTAL:
            self.counts = [(c + 1) >> 1 for c in self.counts]
            self.total = sum(self.counts)

    def encode(self, coder: _Encoder, symbol: int) -> None:
        low = sum(self.counts[:symbol])
        coder.encode(low, low + self.counts[symbol], self.total)
        self._update(symbol)

    def decode(self, coder: _Decoder) -> int:
        target = coder.target(self.total)
        low = 0
        for symbol, count in enumerate(self.counts):
            if target < low + count:
                coder.consume(low, low + count, self.total)
                self._update(symbol)
                return symbol
            low += count
        raise FapCodingError("corrupt coded FAP frame")


def _put_bits(coder: _Encoder, value: int, bits: int) -> None:
    for k in range(bits - 1, -1, -1):
        bit = (value >> k) & 1
        coder.encode(bit, bit + 1, 2)


def _get_bits(coder: _Decoder, bits: int) -> int:
    value = 0
    for _ in range(bits):
        bit = 1 if coder.target(2) >= 1 else 0
        coder.consume(bit, bit + 1, 2)
        value = 2 * value + bit
    return value


@dataclass(slots=True)
class _Models:
    residual: list[_Model] = field(default_factory=lambda: [_Model(ESCAPE + 1) for _ in range(68)])
    bit: list[_Model] = field(default_factory=lambda: [_Model(2) for _ in range(68)])
    kind: list[_Model] = field(default_factory=lambda: [_Model(4) for _ in range(10)])


# -- low-delay coding ---------------------------------------------------------


class FapStreamEncoder:
    """Codes a stream of FAP frames, one :meth:`encode` call per frame.

    ``fap_quant``: 1..31 (the step of FAP n is Table 7's QP times it);
    ``intra_interval``: frames from one intra frame to the next (1 = every
    frame intra). Stateful: frames must be decoded in the order encoded,
    from an intra frame on.
    """

    def __init__(
        self, fap_quant: int = DEFAULT_FAP_QUANT, intra_interval: int = DEFAULT_INTRA_INTERVAL
    ) -> None:
        if not 1 <= fap_quant <= 31:
            raise FaceError(f"FAP_QUANT must be in 1..31, not {fap_quant}")
        if intra_interval < 1:
            raise FaceError("the intra interval must be at least 1 frame")
        self.fap_quant = fap_quant
        self.intra_interval = intra_interval
        self.frames = 0
        self._previous = np.zeros(FAP_COUNT)
        self._models = _Models()

    def encode(self, values: FloatArray, mask: BoolArray, *, intra: bool = False) -> bytes:
        """One coded frame: a header byte, then the arithmetic-coded FAPs.

        The first frame, every ``intra_interval``-th and any asked for are intra.
        """
        intra = intra or self.frames % self.intra_interval == 0
        self.frames += 1
        if intra:
            self._models = _Models()
            self._previous = np.zeros(FAP_COUNT)
        values = np.asarray(values, dtype=np.float64)
        mask = np.asarray(mask, dtype=bool)
        step = _STEPS * self.fap_quant
        coder = _Encoder()
        models = self._models
        decoded = np.zeros(FAP_COUNT)
        for g, group in enumerate(_GROUPS):
            present = [i for i in group if mask[i]]
            if not present:
                kind = MASK_NONE
            elif len(present) == len(group):
                kind = MASK_ALL
            else:
                kind = MASK_SOME
            models.kind[g].encode(coder, kind)
            if kind == MASK_SOME:
                for i in group:
                    models.bit[i].encode(coder, int(mask[i]))
            for i in present:
                e = int(np.rint((values[i] - self._previous[i]) / step[i]))
                e = max(-MAX_QUANTISED, min(MAX_QUANTISED, e))
                if -RESIDUAL_RANGE <= e <= RESIDUAL_RANGE:
                    models.residual[i].encode(coder, e + RESIDUAL_RANGE)
                else:
                    models.residual[i].encode(coder, ESCAPE)
                    _put_bits(coder, 1 if e < 0 else 0, 1)
                    _put_bits(coder, abs(e), ESCAPE_BITS)
                decoded[i] = self._previous[i] + e * step[i]
        self._previous = decoded  # unset FAPs predict from 0 when they return
        header = (0x80 if intra else 0) | self.fap_quant
        return bytes([header]) + coder.finish()


def is_intra(frame: bytes) -> bool:
    """True if a coded frame is an intra frame (a decoder may start there)."""
    return bool(frame) and bool(frame[0] & 0x80)


class FapStreamDecoder:
    """Decodes the frames of a :class:`FapStreamEncoder`, in order.

    :meth:`decode` returns ``(values, mask)``, or None for an inter frame
    it cannot decode: before the first intra frame (a viewer that joined
    mid-stream), or when ``ref`` (the number of the frame the encoder
    predicted from) is not the last frame this decoder decoded (a frame it
    never received); decoding resumes at the next intra frame.
    """

    def __init__(self) -> None:
        self._previous = np.zeros(FAP_COUNT)
        self._models = _Models()
        self._synced = False
        self._number: int | None = None

    def decode(
        self, frame: bytes, number: int | None = None, ref: int | None = None
    ) -> tuple[FloatArray, BoolArray] | None:
        """``number``: this frame's number; ``ref``: the number of the frame
        it is predicted from (None: the previous one decoded)."""
        if not frame or len(frame) > MAX_FRAME_BYTES:
            raise FapCodingError(f"a coded FAP frame has 1..{MAX_FRAME_BYTES} bytes")
        intra = is_intra(frame)
        follows = ref is None or ref == self._number
        if intra:
            self._models = _Models()
            self._previous = np.zeros(FAP_COUNT)
            self._synced = True
        elif not (self._synced and follows):
            self._synced = False
            return None
        self._number = number
        fap_quant = frame[0] & 0x1F
        if fap_quant == 0:
            raise FapCodingError("FAP_QUANT 0 in a coded FAP frame")
        step = _STEPS * fap_quant
        coder = _Decoder(frame[1:])
        models = self._models
        values = np.zeros(FAP_COUNT)
        mask = np.zeros(FAP_COUNT, dtype=bool)
        try:
            for g, group in enumerate(_GROUPS):
                kind = models.kind[g].decode(coder)
                if kind == MASK_NONE:
                    continue
                if kind == MASK_ALL:
                    present = list(group)
                elif kind == MASK_SOME:
                    present = [i for i in group if models.bit[i].decode(coder)]
                else:
                    raise FapCodingError("reserved FAP mask type 2")
                for i in present:
                    symbol = models.residual[i].decode(coder)
                    if symbol == ESCAPE:
                        negative = _get_bits(coder, 1)
                        e = _get_bits(coder, ESCAPE_BITS)
                        e = -e if negative else e
                    else:
                        e = symbol - RESIDUAL_RANGE
                    values[i] = self._previous[i] + e * step[i]
                    mask[i] = True
        except FapCodingError:
            self._synced = False
            raise
        self._previous = values.copy()
        return values, mask


# -- DCT coding (for files) ---------------------------------------------------

#: Frames per DCT segment (section 2.2.2).
SEGMENT = 16
DCT_MAGIC = b"RFAPDCT1"


def _dct_matrix(n: int = SEGMENT) -> FloatArray:
    k = np.arange(n)[:, None]
    i = np.arange(n)[None, :]
    m = np.sqrt(2.0 / n) * np.cos(np.pi * (2 * i + 1) * k / (2 * n))
    m[0] /= math.sqrt(2.0)
    out: FloatArray = m
    return out  # orthonormal: inverse is the transpose


_DCT = _dct_matrix()


class _BitWriter:
    def __init__(self) -> None:
        self.bits: list[int] = []

    def put(self, value: int, count: int) -> None:
        self.bits.extend((value >> k) & 1 for k in range(count - 1, -1, -1))

    def unsigned(self, value: int) -> None:  # Exp-Golomb
        value += 1
        length = value.bit_length()
        self.put(0, length - 1)
        self.put(value, length)

    def signed(self, value: int) -> None:
        self.unsigned(2 * value - 1 if value > 0 else -2 * value)

    def getvalue(self) -> bytes:
        out = bytearray((len(self.bits) + 7) // 8)
        for i, bit in enumerate(self.bits):
            if bit:
                out[i >> 3] |= 0x80 >> (i & 7)
        return bytes(out)


class _BitReader:
    def __init__(self, data: bytes) -> None:
        self.data = data
        self.at = 0

    def get(self, count: int) -> int:
        value = 0
        for _ in range(count):
            if self.at >> 3 >= len(self.data):
                raise FapCodingError("DCT-coded FAP file ends too early")
            value = 2 * value + ((self.data[self.at >> 3] >> (7 - (self.at & 7))) & 1)
            self.at += 1
        return value

    def unsigned(self, limit: int = 1 << 24) -> int:
        zeros = 0
        while self.get(1) == 0:
            zeros += 1
            if zeros > 32:
                raise FapCodingError("malformed Exp-Golomb code")
        value = (1 << zeros) | self.get(zeros)
        if value - 1 > limit:
            raise FapCodingError("value out of range")
        return value - 1

    def signed(self) -> int:
        u = self.unsigned()
        return (u + 1) // 2 if u % 2 else -(u // 2)


@dataclass(frozen=True, slots=True)
class CodedFapFile:
    """A decoded DCT-coded FAP file: ``values`` (frames, 68), ``mask`` the same."""

    fps: float
    values: FloatArray
    mask: BoolArray


def encode_dct_file(
    values: FloatArray, mask: BoolArray, fps: float, fap_quant: int = DEFAULT_FAP_QUANT
) -> bytes:
    """A DCT-coded FAP file of ``values``/``mask`` (frames, 68).

    Layout: magic, float64 fps, uint32 frames, uint8 FAP_QUANT, then per
    segment of 16 frames and per FAP: a present bit; if present, a 16-bit
    frame mask, the DC prediction error and the AC (run, level) pairs ended
    by a run of 16 (all Exp-Golomb, see the module docstring).
    """
    values = np.asarray(values, dtype=np.float64)
    mask = np.asarray(mask, dtype=bool)
    frames = values.shape[0]
    if not 1 <= fap_quant <= 31:
        raise FaceError(f"FAP_QUANT must be in 1..31, not {fap_quant}")
    ac_step = _STEPS * fap_quant
    dc_step = ac_step / 4.0
    writer = _BitWriter()
    previous_dc = np.zeros(FAP_COUNT, dtype=np.int64)
    for start in range(0, frames, SEGMENT):
        chunk = np.zeros((SEGMENT, FAP_COUNT))
        chunk_mask = np.zeros((SEGMENT, FAP_COUNT), dtype=bool)
        count = min(SEGMENT, frames - start)
        chunk[:count] = np.where(mask[start : start + count], values[start : start + count], 0.0)
        chunk_mask[:count] = mask[start : start + count]
        # pad a short last segment with its last frame (smooth, no ringing)
        chunk[count:] = chunk[count - 1]
        coefficients = _DCT @ chunk  # (16, 68)
        for i in range(FAP_COUNT):
            present = bool(chunk_mask[:count, i].any())
            writer.put(int(present), 1)
            if not present:
                continue
            bits = 0
            for k in range(SEGMENT):
                bits = (bits << 1) | int(chunk_mask[k, i])
            writer.put(bits, SEGMENT)
            dc = round(float(coefficients[0, i] / dc_step[i]))
            writer.signed(int(dc - previous_dc[i]))
            previous_dc[i] = dc
            run = 0
            for k in range(1, SEGMENT):
                level = round(float(coefficients[k, i] / ac_step[i]))
                if level == 0:
                    run += 1
                    continue
                writer.unsigned(run)
                writer.signed(int(level))
                run = 0
            writer.unsigned(SEGMENT)  # end of block
    header = DCT_MAGIC + np.float64(fps).tobytes() + np.uint32(frames).tobytes()
    return header + bytes([fap_quant]) + writer.getvalue()


#: A DCT file may hold at most this many frames (an hour at 60 fps).
MAX_DCT_FRAMES = 216_000


def decode_dct_file(data: bytes) -> CodedFapFile:
    """The frames of :func:`encode_dct_file`; raises :class:`FapCodingError`."""
    if not data.startswith(DCT_MAGIC) or len(data) < len(DCT_MAGIC) + 13:
        raise FapCodingError("not a DCT-coded FAP file")
    at = len(DCT_MAGIC)
    fps = float(np.frombuffer(data[at : at + 8], dtype="<f8")[0])
    frames = int(np.frombuffer(data[at + 8 : at + 12], dtype="<u4")[0])
    fap_quant = data[at + 12]
    if not (math.isfinite(fps) and fps > 0) or frames > MAX_DCT_FRAMES or not 1 <= fap_quant <= 31:
        raise FapCodingError("bad DCT-coded FAP file header")
    reader = _BitReader(data[at + 13 :])
    ac_step = _STEPS * fap_quant
    dc_step = ac_step / 4.0
    values = np.zeros((frames, FAP_COUNT))
    mask = np.zeros((frames, FAP_COUNT), dtype=bool)
    previous_dc = np.zeros(FAP_COUNT, dtype=np.int64)
    for start in range(0, frames, SEGMENT):
        count = min(SEGMENT, frames - start)
        for i in range(FAP_COUNT):
            if not reader.get(1):
                continue
            bits = reader.get(SEGMENT)
            frame_mask = np.array([(bits >> (SEGMENT - 1 - k)) & 1 for k in range(SEGMENT)], bool)
            dc = previous_dc[i] + reader.signed()
            previous_dc[i] = dc
            coefficients = np.zeros(SEGMENT)
            coefficients[0] = dc * dc_step[i]
            k = 1
            while True:
                run = reader.unsigned(SEGMENT)
                if run == SEGMENT:
                    break
                k += run
                if k >= SEGMENT:
                    raise FapCodingError("DCT coefficient past the segment")
                coefficients[k] = reader.signed() * ac_step[i]
                k += 1
            series = _DCT.T @ coefficients
            values[start : start + count, i] = np.where(frame_mask[:count], series[:count], 0.0)
            mask[start : start + count, i] = frame_mask[:count]
    return CodedFapFile(fps, values, mask)


def is_dct_file(head: bytes) -> bool:
    return head.startswith(DCT_MAGIC)


def encode_stream(
    frames: Sequence[tuple[FloatArray, BoolArray]],
    fap_quant: int = DEFAULT_FAP_QUANT,
    intra_interval: int = DEFAULT_INTRA_INTERVAL,
) -> Iterator[bytes]:
    """Coded frames of a sequence of ``(values, mask)`` (a convenience)."""
    encoder = FapStreamEncoder(fap_quant, intra_interval)
    for values, mask in frames:
        yield encoder.encode(values, mask)


# -- files ----------------------------------------------------------------------

#: A low-delay coded file: magic, float64 fps, then per frame a uint16 LE length and the frame.
STREAM_MAGIC = b"RFAPLDC1"


def encode_stream_file(
    values: FloatArray,
    mask: BoolArray,
    fps: float,
    fap_quant: int = DEFAULT_FAP_QUANT,
    intra_interval: int = DEFAULT_INTRA_INTERVAL,
) -> bytes:
    """A file of low-delay coded frames (the viewer stream's frames, length-prefixed)."""
    frames = encode_stream(list(zip(values, mask, strict=True)), fap_quant, intra_interval)
    parts = [STREAM_MAGIC, np.float64(fps).astype("<f8").tobytes()]
    for frame in frames:
        parts.append(np.uint16(len(frame)).astype("<u2").tobytes())
        parts.append(frame)
    return b"".join(parts)


def decode_stream_file(data: bytes) -> CodedFapFile:
    """The frames of :func:`encode_stream_file`; raises :class:`FapCodingError`."""
    if not data.startswith(STREAM_MAGIC) or len(data) < len(STREAM_MAGIC) + 8:
        raise FapCodingError("not a low-delay coded FAP file")
    at = len(STREAM_MAGIC)
    fps = float(np.frombuffer(data[at : at + 8], dtype="<f8")[0])
    if not (math.isfinite(fps) and fps > 0):
        raise FapCodingError("bad frame rate in a coded FAP file")
    at += 8
    decoder = FapStreamDecoder()
    values: list[FloatArray] = []
    masks: list[BoolArray] = []
    while at < len(data):
        if at + 2 > len(data) or len(values) >= MAX_DCT_FRAMES:
            raise FapCodingError("truncated or overlong coded FAP file")
        length = int(np.frombuffer(data[at : at + 2], dtype="<u2")[0])
        frame = data[at + 2 : at + 2 + length]
        if len(frame) != length:
            raise FapCodingError("truncated coded FAP file")
        decoded = decoder.decode(frame)
        if decoded is None:
            raise FapCodingError("a coded FAP file must start with an intra frame")
        values.append(decoded[0])
        masks.append(decoded[1])
        at += 2 + length
    if not values:
        return CodedFapFile(fps, np.zeros((0, FAP_COUNT)), np.zeros((0, FAP_COUNT), dtype=bool))
    return CodedFapFile(fps, np.stack(values), np.stack(masks))


def read_any_fap_file(path: str | Any) -> CodedFapFile:
    """A FAP file of any kind: DCT-coded, low-delay coded, or the text ``.fap`` format."""
    from pathlib import Path

    from realizer.face.fapfile import read_fap_file

    data = Path(path).read_bytes()
    if is_dct_file(data[:8]):
        return decode_dct_file(data)
    if data.startswith(STREAM_MAGIC):
        return decode_stream_file(data)
    text = read_fap_file(path)
    return CodedFapFile(text.fps, np.asarray(text.values, dtype=np.float64), text.mask)
