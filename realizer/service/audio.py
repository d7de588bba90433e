"""The viewer protocol's audio stream: a character's speech as PCM16 chunks on the server clock.

Sans-I/O (like the stage): :class:`AudioStream` keeps, for one character,
how far its audio has been sent, and turns the session's audio
(:meth:`realizer.session.Session.audio`) into ``audio`` messages
(protocols/viewer.md). Each tick sends the samples from where the last
chunk ended up to :data:`AUDIO_LEAD` seconds ahead of the clock, so a viewer
holds a little audio to schedule ahead (Web Audio plays it at the chunk's
time ``t``); chunks join sample for sample. Silence sends nothing, and a stretch that
was silent when looked at is only taken as sent up to the clock, not up to
the lead: speech a new block adds there is still sent whole.

When a block is interrupted, audio already sent beyond that instant must not
play: the stream sends ``audioCut`` with the instant, and resends from then
whatever is now due (a REPLACE block's new speech).

Why PCM16 and not Opus: it needs no codec library on either side (the
browser turns int16 into float32 samples in one loop), adds no codec delay,
and speech at 22,050 Hz mono is 44 kB/s, sent only while a character
speaks; a maintained pure-Python Opus encoder does not exist (the bindings
need libopus).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from realizer.service import codec
from realizer.service.messages import PROTOCOL_VERSION

#: Sample rate of the stream (Hz): eSpeak NG's own rate.
AUDIO_RATE = 22050
#: Seconds of audio sent ahead of the clock.
AUDIO_LEAD = 0.1
#: A viewer whose audio backlog exceeds this many seconds loses the oldest
#: chunks (audio is never allowed to delay frames or grow without bound).
MAX_BACKLOG_S = 2.0
#: If the stream fell this far behind the clock (no viewer for a while), it
#: restarts at the clock instead of sending the past.
RESTART_S = 0.5

AUDIO_VALUES = ("pcm16", "none")


@dataclass(slots=True)
class AudioStream:
    """How far one character's audio has been sent (seconds on the server clock)."""

    character: str
    sent_until: float | None = None
    rate: int = AUDIO_RATE
    lead: float = AUDIO_LEAD

    def messages(self, session: Any, now: float) -> list[bytes]:
        """The ``audioCut`` and ``audio`` messages due at ``now``, encoded."""
        out: list[bytes] = []
        take_cut = getattr(session, "take_audio_cut", None)
        cut = take_cut() if take_cut is not None else None
        if cut is not None and self.sent_until is not None and cut < self.sent_until:
            out.append(codec.pack({"type": "audioCut", "v": PROTOCOL_VERSION,
                                   "character": self.character, "t": cut}))  # fmt: skip
            self.sent_until = max(cut, now)
        audio = getattr(session, "audio", None)
        if audio is None:
            return out
        start = self.sent_until
        if start is None or start < now - RESTART_S:
            start = now
        first = round(start * self.rate)
        last = round((now + self.lead) * self.rate)
        if last <= first:
            return out
        chunk = audio(first / self.rate, last / self.rate, self.rate)
        if chunk is None or not len(chunk.samples):
            # Nothing sounds there *yet*: a block committed before the next
            # tick may start speaking inside this window, so only the past is
            # done with. Advancing to the lead would cut the first lead's
            # worth of a new speech (up to AUDIO_LEAD seconds of it).
            self.sent_until = max(start, now)
            return out
        self.sent_until = last / self.rate
        out.append(
            codec.pack(
                {
                    "type": "audio",
                    "v": PROTOCOL_VERSION,
                    "character": self.character,
                    "t": chunk.start,
                    "rate": self.rate,
                    "channels": 1,
                    "format": "pcm16",
                    "count": len(chunk.samples),
                    "samples": chunk.samples.astype("<i2").tobytes(),
                }
            )
        )
        return out


def backlog_limit(rate: int = AUDIO_RATE, fps: float = 60.0) -> int:
    """How many audio messages a viewer may have queued (about :data:`MAX_BACKLOG_S`)."""
    return max(4, int(MAX_BACKLOG_S * fps))
