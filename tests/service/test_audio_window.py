"""The viewer protocol's audio stream without a server: which samples are sent when."""

from __future__ import annotations

import itertools

import numpy as np

from realizer.engines.speech.engine import AudioClip
from realizer.service import codec
from realizer.service.audio import AUDIO_LEAD, AUDIO_RATE, AudioStream


class _Speaker:
    """A session stand-in: silent until a clip is added, then that clip."""

    def __init__(self) -> None:
        self.clip: AudioClip | None = None

    def audio(self, start: float, end: float, rate: int) -> AudioClip | None:
        clip = self.clip
        if clip is None or clip.end <= start or clip.start >= end:
            return None
        first, last = round(start * rate), round(end * rate)
        out = np.zeros(last - first, dtype=np.int16)
        c0 = round(clip.start * rate)
        lo, hi = max(first, c0), min(last, c0 + len(clip.samples))
        out[lo - first : hi - first] = clip.samples[lo - c0 : hi - c0]
        return AudioClip(first / rate, out, rate)


def _sent(messages: list[bytes]) -> list[tuple[float, np.ndarray]]:
    chunks = []
    for raw in messages:
        m = codec.unpack(raw)
        if m["type"] == "audio":
            chunks.append((m["t"], np.frombuffer(m["samples"], dtype="<i2")))
    return chunks


def test_speech_that_starts_inside_an_already_looked_at_window_is_sent_whole() -> None:
    # Regression: the stream took silent windows as sent up to the lead, so
    # a block committed just after a tick lost the first 50-67 ms of speech.
    speaker = _Speaker()
    stream = AudioStream("alice")
    period = 1 / 60
    now = 10.0
    for _ in range(30):  # half a second of silence, one tick a frame
        assert stream.messages(speaker, now) == []
        now += period
    # A speech committed between two ticks starts one frame from now, well
    # inside the window the last silent tick looked at.
    start = now + period
    assert start < now - period + AUDIO_LEAD
    samples = np.full(int(0.5 * AUDIO_RATE), 1000, dtype=np.int16)
    speaker.clip = AudioClip(start, samples, AUDIO_RATE)
    received: list[tuple[float, np.ndarray]] = []
    for _ in range(60):
        received += _sent(stream.messages(speaker, now))
        now += period
    # Chunks join sample for sample, and every sample of the speech arrives.
    for (t0, s0), (t1, _) in itertools.pairwise(received):
        assert round(t1 * AUDIO_RATE) == round(t0 * AUDIO_RATE) + len(s0)
    whole = np.concatenate([s for _, s in received])
    assert int(np.count_nonzero(whole)) == len(samples)
    first_loud = round(received[0][0] * AUDIO_RATE) + int(np.flatnonzero(whole)[0])
    assert first_loud == round(start * AUDIO_RATE)


def test_silence_sends_nothing_and_sound_is_sent_ahead_by_the_lead() -> None:
    speaker = _Speaker()
    stream = AudioStream("alice")
    speaker.clip = AudioClip(0.0, np.full(AUDIO_RATE, 7, dtype=np.int16), AUDIO_RATE)
    ((t, s),) = _sent(stream.messages(speaker, 0.0))
    assert t == 0.0 and len(s) == round(AUDIO_LEAD * AUDIO_RATE)
    speaker.clip = None
    assert stream.messages(speaker, 5.0) == []
