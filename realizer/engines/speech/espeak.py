"""eSpeak NG through its C library (``libespeak-ng.so.1``), called with ctypes.

The library runs in its synchronous mode (``AUDIO_OUTPUT_SYNCHRONOUS``):
``espeak_Synth`` returns when the text is spoken, having called our callback
with each chunk of samples and the events that fall in it. Phoneme events
(``espeakINITIALIZE_PHONEME_EVENTS``, with IPA names), word events and mark
events (SSML ``<mark name>``) carry the sample index they fall on, so
markers, words and phonemes share the audio's clock exactly; nothing is
parsed from command-line output.

The library keeps one global state (voice, parameters, callback), so every
call into it holds :data:`_LOCK`; :meth:`EspeakBackend.synthesize` is safe to
call from any thread and runs one synthesis at a time.

Debian: ``libespeak-ng1`` and ``espeak-ng-data`` (installed by
``scripts/setup.sh``).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import threading
import time
from dataclasses import dataclass, field
from typing import Any
from xml.sax.saxutils import unescape

import numpy as np

from realizer.bml_parser import SpeechText
from realizer.engines.speech.tts import Phoneme, Synthesis, TtsError, ssml

_LIBRARY_NAMES = ("libespeak-ng.so.1", "libespeak-ng.so", "espeak-ng")

# speak_lib.h
_AUDIO_OUTPUT_SYNCHRONOUS = 2
_INITIALIZE_PHONEME_EVENTS = 0x0001
_INITIALIZE_PHONEME_IPA = 0x0002
_INITIALIZE_DONT_EXIT = 0x8000
_CHARS_UTF8 = 1
_SSML = 0x10
_POS_CHARACTER = 1
_EVENT_LIST_TERMINATED = 0
_EVENT_WORD = 1
_EVENT_MARK = 3
_EVENT_PHONEME = 7
_PARAM_RATE = 1
_EE_OK = 0

#: Audio chunk length the library hands the callback, milliseconds.
CHUNK_MS = 20


class _EventId(ctypes.Union):
    _fields_ = (
        ("number", ctypes.c_int),
        ("name", ctypes.c_char_p),
        ("string", ctypes.c_char * 8),
    )


class _Event(ctypes.Structure):
    _fields_ = (
        ("type", ctypes.c_int),
        ("unique_identifier", ctypes.c_uint),
        ("text_position", ctypes.c_int),
        ("length", ctypes.c_int),
        ("audio_position", ctypes.c_int),
        ("sample", ctypes.c_int),
        ("user_data", ctypes.c_void_p),
        ("id", _EventId),
    )


class _Voice(ctypes.Structure):
    _fields_ = (
        ("name", ctypes.c_char_p),
        ("languages", ctypes.c_void_p),  # (priority byte, name, NUL) pairs, then NUL
        ("identifier", ctypes.c_char_p),
        ("gender", ctypes.c_ubyte),
        ("age", ctypes.c_ubyte),
        ("variant", ctypes.c_ubyte),
        ("xx1", ctypes.c_ubyte),
        ("score", ctypes.c_int),
        ("spare", ctypes.c_void_p),
    )


_CALLBACK = ctypes.CFUNCTYPE(
    ctypes.c_int, ctypes.POINTER(ctypes.c_short), ctypes.c_int, ctypes.POINTER(_Event)
)

_LOCK = threading.Lock()


@dataclass(slots=True)
class _Library:
    """The loaded library, its sample rate and installed languages (one per process)."""

    lib: ctypes.CDLL
    sample_rate: int
    languages: frozenset[str]
    callback: object = None  # keeps the ctypes callback alive
    sink: list[tuple[bytes, list[tuple[int, int, int, int, str]]]] = field(default_factory=list)
    first_chunk: float = 0.0


_STATE: _Library | None = None


def _load() -> _Library:
    """Load and initialise the library once; raises :class:`TtsError` if it is missing."""
    global _STATE
    if _STATE is not None:
        return _STATE
    lib = None
    for name in _LIBRARY_NAMES:
        path = (
            ctypes.util.find_library(name) if "/" not in name and not name.endswith(".1") else name
        )
        try:
            lib = ctypes.CDLL(path or name)
            break
        except OSError:
            continue
    if lib is None:
        raise TtsError(
            "eSpeak NG is not installed (Debian: apt-get install libespeak-ng1 espeak-ng-data)"
        )
    lib.espeak_Initialize.restype = ctypes.c_int
    lib.espeak_Initialize.argtypes = (ctypes.c_int, ctypes.c_int, ctypes.c_char_p, ctypes.c_int)
    lib.espeak_Synth.restype = ctypes.c_int
    lib.espeak_Synth.argtypes = (
        ctypes.c_char_p, ctypes.c_size_t, ctypes.c_uint, ctypes.c_int, ctypes.c_uint,
        ctypes.c_uint, ctypes.c_void_p, ctypes.c_void_p,
    )  # fmt: skip
    lib.espeak_SetVoiceByName.restype = ctypes.c_int
    lib.espeak_SetVoiceByName.argtypes = (ctypes.c_char_p,)
    lib.espeak_SetParameter.restype = ctypes.c_int
    lib.espeak_SetParameter.argtypes = (ctypes.c_int, ctypes.c_int, ctypes.c_int)
    lib.espeak_ListVoices.restype = ctypes.POINTER(ctypes.POINTER(_Voice))
    lib.espeak_ListVoices.argtypes = (ctypes.c_void_p,)
    lib.espeak_SetSynthCallback.argtypes = (_CALLBACK,)
    options = _INITIALIZE_PHONEME_EVENTS | _INITIALIZE_PHONEME_IPA | _INITIALIZE_DONT_EXIT
    rate = lib.espeak_Initialize(_AUDIO_OUTPUT_SYNCHRONOUS, CHUNK_MS, None, options)
    if rate <= 0:
        raise TtsError("eSpeak NG could not start (is espeak-ng-data installed?)")
    state = _Library(lib, rate, _languages(lib))

    def on_audio(wav: Any, count: int, events: Any) -> int:
        found: list[tuple[int, int, int, int, str]] = []
        index = 0
        while events[index].type != _EVENT_LIST_TERMINATED:
            event = events[index]
            if event.type == _EVENT_PHONEME:
                label = bytes(event.id.string).decode("utf-8", "ignore")
            elif event.type == _EVENT_MARK:
                label = (event.id.name or b"").decode("utf-8", "replace")
            else:
                label = ""
            found.append((event.type, event.sample, event.text_position, event.length, label))
            index += 1
        if count > 0 and not state.first_chunk:
            state.first_chunk = time.perf_counter()
        samples = ctypes.string_at(wav, count * 2) if count > 0 and wav else b""
        state.sink.append((samples, found))
        return 0

    state.callback = _CALLBACK(on_audio)
    lib.espeak_SetSynthCallback(state.callback)
    _STATE = state
    return state


def _languages(lib: ctypes.CDLL) -> frozenset[str]:
    """Every language tag of every installed voice, lower case."""
    found: set[str] = set()
    voices = lib.espeak_ListVoices(None)
    index = 0
    while voices[index]:
        pointer = voices[index].contents.languages
        raw = ctypes.string_at(pointer, 512) if pointer else b""
        position = 0
        while position < len(raw) and raw[position] != 0:
            end = raw.index(b"\0", position + 1)
            found.add(raw[position + 1 : end].decode("ascii", "ignore").lower())
            position = end + 1
        index += 1
    return frozenset(found)


@dataclass(slots=True)
class EspeakBackend:
    """eSpeak NG; ``voice`` is the default voice (a language tag), ``rate`` words per minute."""

    voice: str = "en"
    rate: int = 175
    name: str = "espeak"

    @classmethod
    def load(cls, voice: str | None = None, rate: int = 175) -> EspeakBackend:
        """Load the library now; raises :class:`TtsError` if missing or the voice is unknown."""
        with _LOCK:
            state = _load()
        backend = cls(voice or "en", rate)
        if not backend.has_language(backend.voice):
            raise TtsError(f"eSpeak NG has no voice for {backend.voice!r}")
        del state
        return backend

    def has_language(self, language: str) -> bool:
        return self.voice_for(language) is not None

    def voice_for(self, language: str) -> str | None:
        """The installed voice tag for a BCP 47 tag: itself, else its primary language."""
        languages = _load().languages
        tag = language.strip().lower().replace("_", "-")
        if tag in languages:
            return tag
        primary = tag.partition("-")[0]
        return primary if primary in languages else None

    def synthesize(self, text: SpeechText, language: str | None = None) -> Synthesis:
        voice = self.voice_for(language) if language else None
        voice = voice or self.voice
        document, _ = ssml(text)
        data = document.encode("utf-8")
        with _LOCK:
            state = _load()
            lib = state.lib
            if lib.espeak_SetVoiceByName(voice.encode("ascii")) != _EE_OK:
                raise TtsError(f"eSpeak NG cannot select the voice {voice!r}")
            lib.espeak_SetParameter(_PARAM_RATE, self.rate, 0)
            state.sink = []
            state.first_chunk = 0.0
            started = time.perf_counter()
            status = lib.espeak_Synth(
                data, len(data) + 1, 0, _POS_CHARACTER, 0, _CHARS_UTF8 | _SSML, None, None
            )
            chunks, state.sink = state.sink, []
            first = state.first_chunk - started if state.first_chunk else 0.0
        if status != _EE_OK:
            raise TtsError(f"eSpeak NG failed on the text (error {status})")
        return _assemble(chunks, state.sample_rate, document, voice, first)


def _assemble(
    chunks: list[tuple[bytes, list[tuple[int, int, int, int, str]]]],
    rate: int,
    document: str,
    voice: str,
    first_audio: float,
) -> Synthesis:
    audio = np.frombuffer(b"".join(c for c, _ in chunks), dtype=np.int16).copy()
    total = len(audio)
    events = [e for _, found in chunks for e in found]
    phoneme_starts: list[tuple[str, int]] = []
    words: list[tuple[str, int]] = []
    markers: dict[str, float] = {}
    for kind, sample, position, length, label in events:
        sample = min(max(sample, 0), total)
        if kind == _EVENT_PHONEME:
            phoneme_starts.append((label, sample))
        elif kind == _EVENT_WORD:
            words.append((_word_at(document, position - 1, length), sample))
        elif kind == _EVENT_MARK:
            markers.setdefault(label, sample / rate)
    phonemes: list[Phoneme] = []
    for index, (symbol, sample) in enumerate(phoneme_starts):
        last = phoneme_starts[index + 1][1] if index + 1 < len(phoneme_starts) else total
        if last > sample:
            phonemes.append(Phoneme(symbol, sample / rate, last / rate))
    timed_words: list[tuple[str, float, float]] = []
    words = [(w, start) for w, start in words if w.strip()]
    for index, (word, sample) in enumerate(words):
        limit = words[index + 1][1] if index + 1 < len(words) else total
        # a word ends where its last sound ends, before any pause that follows it
        begin, stop = sample / rate, limit / rate
        spoken = [p.end for p in phonemes if p.symbol and begin <= p.start < stop]
        end = min(max(spoken, default=stop), stop)  # seconds
        timed_words.append((word, sample / rate, end))
    for name, when in list(markers.items()):
        # A marker is heard at a word boundary: the start of the word after
        # it (where eSpeak NG puts it) or, after the last word, that word's end.
        if not any(abs(start - when) < 1e-3 for _, start, _ in timed_words):
            before = [end for _, start, end in timed_words if start <= when]
            markers[name] = max(before, default=when)
    return Synthesis(
        audio=audio,
        sample_rate=rate,
        phonemes=tuple(phonemes),
        words=tuple(timed_words),
        markers=markers,
        voice=voice,
        backend="espeak",
        first_audio=first_audio,
    )


def _word_at(document: str, start: int, length: int) -> str:
    """The word eSpeak NG reports at a character offset, entities decoded."""
    amp = document.rfind("&", 0, start + 1)
    if amp >= 0 and document.rfind(";", 0, start) < amp <= start:
        start, length = amp, max(length, document.find(";", amp) + 1 - amp)
    return unescape(document[start : start + length]).strip()
