"""The speech engine: ``<speech>`` timed by a real TTS, spoken as audio, shown as lip sync.

Planning (:meth:`SpeechEngine.plan`) synthesises the text with the TTS
backend (eSpeak NG by default) and gives the scheduler one phase per stretch
between neighbouring sync points (``start``, each ``<sync id>`` of the text,
``end``) whose preferred length is the time the TTS takes to speak it, so
the markers get the times at which they are actually heard and the speech
lasts as long as its audio.

Stretching (docs/speech.md): a speech phase never shrinks below its spoken
length (audio cannot be squeezed without re-synthesis) and may grow by at
most :attr:`SpeechLimits.max_pause` seconds; when the solver makes it
longer, :func:`lay_out` inserts that much silence just before the later
marker (at the word boundary where the marker is heard), and shifts the
phonemes after it alike. So every marker is heard at its solved time, to the
nearest audio sample.

Realizing (:meth:`SpeechEngine.realize`) gives a :class:`SpeechRealization`:
the laid-out audio (:class:`AudioClip`, on the session's clock) and the
articulation as two animations (:mod:`realizer.engines.speech.lipsync`).

The engine is safe to call from a worker thread: the backend serialises its
own calls, and the engine's cache of syntheses holds a lock.

Failures never stop a block: with no TTS, or a TTS failing on a text, the
speech is timed by the syllable estimate (:class:`RateSpeechTiming`), stays
silent, and :meth:`SpeechEngine.notes` says why (the session turns notes
into ``warningFeedback``). An unknown ``xml:lang`` uses the default voice,
with a note. A text over :attr:`SpeechLimits.max_characters` is refused
(a :class:`TimingModelError`, which the scheduler reports), never truncated.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from realizer.bml_parser import Behaviour, SpeechText
from realizer.engines.speech.timing import RateSpeechTiming, SpeechPlan
from realizer.engines.speech.tts import Synthesis, TtsBackend, TtsError, load_backend
from realizer.scheduler.timing import Phase, TimingModel, TimingModelError


@dataclass(frozen=True, slots=True)
class SpeechLimits:
    """Named limits of the speech engine."""

    #: characters of text per speech; a longer speech is refused with a warning
    max_characters: int = 2000
    #: seconds of silence the scheduler may insert before one marker
    max_pause: float = 2.0
    #: syntheses kept for realizing what was planned (oldest forgotten first)
    cache_entries: int = 64


@dataclass(frozen=True, slots=True, eq=False)
class AudioClip:
    """Mono PCM16 ``samples`` at ``sample_rate`` Hz; sample 0 plays at ``start``.

    ``start`` is in global seconds (the session's clock).
    """

    start: float
    samples: npt.NDArray[np.int16]
    sample_rate: int
    behaviour_id: str = ""

    @property
    def end(self) -> float:
        return self.start + len(self.samples) / self.sample_rate

    def cut(self, at: float) -> AudioClip:
        """The clip stopped at ``at`` (global seconds)."""
        keep = max(0, min(len(self.samples), round((at - self.start) * self.sample_rate)))
        return AudioClip(self.start, self.samples[:keep], self.sample_rate, self.behaviour_id)


@dataclass(frozen=True, slots=True, eq=False)
class SpeechRealization:
    """A realized speech: its audio (None when silent) and its lip animations."""

    audio: AudioClip | None
    parts: tuple[object, ...]
    #: each phoneme (IPA, global start, global end) as laid out
    phonemes: tuple[tuple[str, float, float], ...] = ()
    #: each marker's global time as heard
    markers: Mapping[str, float] = field(default_factory=dict)


def lay_out(
    synthesis: Synthesis, syncs: Sequence[str], times: Mapping[str, float]
) -> tuple[AudioClip, tuple[tuple[str, float, float], ...], dict[str, float]]:
    """Place the synthesis on the solved times: silence inserted before markers.

    ``syncs`` are the speech's sync points in order (``start``, markers,
    ``end``), ``times`` their solved global times. Returns the audio clip,
    the phonemes in global seconds and each marker's heard time.
    """
    rate = synthesis.sample_rate
    natural = [0.0, *(synthesis.markers.get(s, 0.0) for s in syncs[1:-1]), synthesis.duration]
    for index in range(1, len(natural)):
        natural[index] = max(natural[index], natural[index - 1])
    start = times[syncs[0]]
    pieces: list[npt.NDArray[np.int16]] = []
    cursor = 0  # samples laid so far
    phonemes: list[tuple[str, float, float]] = []
    heard: dict[str, float] = {}
    for index, sync in enumerate(syncs[:-1]):
        begin = round(natural[index] * rate)
        stop = round(natural[index + 1] * rate)
        target = round((times[sync] - start) * rate)
        if index and target > cursor:  # the pause before this marker
            pieces.append(np.zeros(target - cursor, dtype=np.int16))
            cursor = target
        if index:
            heard[sync] = start + cursor / rate
        offset = start + cursor / rate - natural[index]
        for p in synthesis.phonemes:
            if natural[index] <= p.start < natural[index + 1] or (
                index == len(syncs) - 2 and p.start >= natural[index + 1]
            ):
                phonemes.append(
                    (p.symbol, p.start + offset, min(p.end, natural[index + 1]) + offset)
                )
        pieces.append(synthesis.audio[begin:stop])
        cursor += stop - begin
    end_target = round((times[syncs[-1]] - start) * rate)
    if end_target > cursor:
        pieces.append(np.zeros(end_target - cursor, dtype=np.int16))
    audio = np.concatenate(pieces) if pieces else np.zeros(0, dtype=np.int16)
    return AudioClip(start, audio, rate), tuple(phonemes), heard


@dataclass(slots=True, eq=False)
class SpeechEngine:
    """Plans and realizes ``<speech>``.

    ``backend`` is the TTS (None: the syllable estimate, silent);
    ``unavailable`` says why there is none (for the warning). ``lead`` is
    the visual lead of the lips over the audio in seconds (None: the data
    file's).
    """

    backend: TtsBackend | None = None
    unavailable: str = ""
    limits: SpeechLimits = field(default_factory=SpeechLimits)
    estimate: RateSpeechTiming = field(default_factory=RateSpeechTiming)
    lead: float | None = None
    weight: float = 10.0  # speech stretches reluctantly
    _cache: OrderedDict[tuple[object, ...], tuple[Synthesis | None, tuple[str, ...]]] = field(
        default_factory=OrderedDict, repr=False
    )
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    @classmethod
    def default(cls, backend: str = "espeak", **options: str) -> SpeechEngine:
        """The engine with the named backend, or the estimate with a note when it cannot load."""
        try:
            return cls(load_backend(backend, **options))
        except TtsError as exc:
            return cls(None, unavailable=str(exc))

    # -- which and when --------------------------------------------------------

    def handles(self, behaviour: Behaviour) -> bool:
        return behaviour.type == "speech" and behaviour.speech is not None

    def prepare(self, behaviour: Behaviour) -> None:
        """Synthesise the speech now (cached for :meth:`plan`); a text over the limit is left
        for :meth:`plan` to refuse."""
        speech = behaviour.speech
        if speech is not None and len(speech.plain) <= self.limits.max_characters:
            self._synthesis(behaviour)

    def plan(self, behaviour: Behaviour) -> TimingModel:
        speech = behaviour.speech
        assert speech is not None
        length = len(speech.plain)
        if length > self.limits.max_characters:
            raise TimingModelError(
                f"speech of {length} characters is over the limit of "
                f"{self.limits.max_characters} (SpeechLimits.max_characters); "
                "it is refused, not spoken"
            )
        synthesis, _ = self._synthesis(behaviour)
        plan = synthesis.plan() if synthesis is not None else self.estimate.plan(speech)
        return self._model(behaviour, plan, exact=synthesis is not None)

    def _model(self, behaviour: Behaviour, plan: SpeechPlan, *, exact: bool) -> TimingModel:
        times = [0.0, *(plan.markers.get(name, 0.0) for name in behaviour.syncs[1:-1])]
        times.append(plan.duration)
        phases = []
        for index in range(len(times) - 1):
            length = max(0.0, times[index + 1] - times[index])
            phases.append(
                Phase(
                    length,
                    weight=self.weight,
                    # audio is never squeezed; an estimate may be (it is a guess)
                    minimum=length if exact else length * 0.6,
                    maximum=length + self.limits.max_pause,
                )
            )
        return TimingModel(behaviour.syncs, tuple(phases))

    def notes(self, behaviour: Behaviour) -> tuple[str, ...]:
        """Warnings about how this speech was planned (empty when all is well)."""
        if not self.handles(behaviour):
            return ()
        return self._synthesis(behaviour)[1]

    # -- synthesis ---------------------------------------------------------------

    def synthesis(self, behaviour: Behaviour) -> Synthesis | None:
        """The TTS output for this speech (cached), or None when it is silent."""
        return self._synthesis(behaviour)[0]

    def _synthesis(self, behaviour: Behaviour) -> tuple[Synthesis | None, tuple[str, ...]]:
        speech = behaviour.speech
        assert speech is not None
        language = behaviour.param("lang")
        key = (language, speech.runs)
        with self._lock:
            found = self._cache.get(key)
            if found is not None:
                self._cache.move_to_end(key)
                return found
        result = self._synthesise(speech, language)
        with self._lock:
            self._cache[key] = result
            while len(self._cache) > self.limits.cache_entries:
                self._cache.popitem(last=False)
        return result

    def _synthesise(
        self, speech: SpeechText, language: str | None
    ) -> tuple[Synthesis | None, tuple[str, ...]]:
        if self.backend is None:
            reason = self.unavailable or "no TTS backend"
            return None, (f"{reason}; speech is timed by a syllable estimate and silent",)
        notes: list[str] = []
        if language and not self.backend.has_language(language):
            notes.append(
                f"no {self.backend.name} voice for xml:lang={language!r}; the default voice speaks"
            )
            language = None
        try:
            return self.backend.synthesize(speech, language), tuple(notes)
        except TtsError as exc:
            notes.append(f"{exc}; speech is timed by a syllable estimate and silent")
            return None, tuple(notes)

    # -- realization ---------------------------------------------------------------

    def realize(self, behaviour: Behaviour, times: Mapping[str, float]) -> SpeechRealization:
        from realizer.engines.speech.lipsync import lip_animations

        synthesis, _ = self._synthesis(behaviour)
        syncs = behaviour.syncs
        if synthesis is None:
            # silent: with no phonemes the mouth does not move; the timing
            # and its feedback still hold.
            return SpeechRealization(None, (), (), {s: times[s] for s in syncs[1:-1]})
        clip, phonemes, heard = lay_out(synthesis, syncs, times)
        clip = AudioClip(clip.start, clip.samples, clip.sample_rate, behaviour.id)
        parts = lip_animations(phonemes, lead=self.lead, behaviour_id=behaviour.id)
        return SpeechRealization(clip, parts, phonemes, heard)
