"""Speech audio on the session clock: clips mixed into chunks of a fixed sample grid.

Sample ``i`` of the clock is at ``i / rate`` seconds; a chunk for
``[start, end)`` holds samples ``round(start * rate)`` up to
``round(end * rate)``, so chunks asked for back to back join exactly. Clips
at another rate are resampled by linear interpolation.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from realizer.engines.speech.engine import AudioClip


def mix_audio(clips: Sequence[AudioClip], start: float, end: float, rate: int) -> AudioClip:
    """The clips summed over ``[start, end)`` at ``rate`` Hz, clipped to int16."""
    first = round(start * rate)
    count = max(0, round(end * rate) - first)
    out = np.zeros(count, dtype=np.float64)
    for clip in clips:
        if clip.sample_rate == rate:
            offset = round(clip.start * rate) - first
            lo, hi = max(0, offset), min(count, offset + len(clip.samples))
            if hi > lo:
                out[lo:hi] += clip.samples[lo - offset : hi - offset]
        else:
            times = (first + np.arange(count)) / rate
            position = (times - clip.start) * clip.sample_rate
            inside = (position >= 0) & (position <= len(clip.samples) - 1)
            if inside.any():
                source = np.arange(len(clip.samples), dtype=np.float64)
                out[inside] += np.interp(position[inside], source, clip.samples)
    samples = np.clip(np.round(out), -32768, 32767).astype(np.int16)
    return AudioClip(first / rate, samples, rate)
