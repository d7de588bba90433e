"""The face engine: timing models and FAP animations for face, head and gaze behaviours.

For the scheduler (docs/interfaces.md, "Engines"), the engine

- says which behaviours it handles (:meth:`FaceEngine.handles`),
- plans each one: its sync points in canonical order with preferred phase
  durations and stretch costs (:meth:`FaceEngine.plan`, from
  ``realizer/face/data/engine.toml``),
- realizes it once its sync times are solved (:meth:`FaceEngine.realize`):
  an animation over FAPs 3..68 that the mixer of :mod:`realizer.face.tracks`
  combines with the others.

Behaviours and what they become:

=====================  ===========================================  ========  =======
behaviour              FAP values                                   priority  blend
=====================  ===========================================  ========  =======
emotion (rf:)          emotion converter (Raouzaiou et al. 2002, Paul 2010, ch 6)  0         add
expression (rf:)       FAP 2 expressions (Tekalp and Ostermann 2000, Table 4)         0         add
viseme (rf:)           FAP 1 visemes (Tekalp and Ostermann 2000, Table 3)             1         add
faceLexeme, face       BML lexeme -> AUs -> FAPs (Paul 2010, ch 5)    2         add
faceFacs               one AU -> FAPs                               2         add
faceShift              a lexeme that stays after ``end``            2         add
head                   NOD / SHAKE / TILT keyframes on FAPs 48-50   2         add
gaze, gazeShift        eyeball FAPs 23-26, head 48/49 by influence  2         replace
headDirectionShift     head pitch and yaw FAPs 48/49, held after    2         replace
fap (rf:)              explicit low-level FAPs                      3         replace
=====================  ===========================================  ========  =======

Emotions and expressions are the base layer that refinements add to (Paul
2010, section 7.4, advises setting the controller with the fewest parameters
first); explicit low-level FAPs win over FAP 1 and 2 as Tekalp and Ostermann 2000, section
2.1 asks ("the lower level FAPs have priority"); a gaze replaces the previous
gaze direction rather than adding to it.

Face envelopes follow ``start``, ``attackPeak``, ``relax``, ``end`` with the
behaviour's ``curve`` (linear, hermite, triangular). Head movements put a
keyframe at each stroke (``stroke``, ``stroke:2``, ...): a NOD goes down at
every stroke and back up between, a SHAKE turns left at each stroke and right
between, a TILT tilts at the strokes and holds until ``relax``.

Gaze targets: a target the session's scene knows (``realizer.scene``: the
camera, the user, other characters' eyes, targets clients place) arrives as
``sceneYaw``/``scenePitch`` degrees and is looked at; otherwise the
direction words (LEFT, RIGHT, UP, DOWN, UPLEFT, ...) used as ``target`` or
``offsetDirection`` turn the gaze by
``offsetAngle`` degrees (default 20 for a direction-word target); any other
target is straight ahead. With influence EYES the eyes turn alone (up to
their limit); with NECK, HEAD, SHOULDER, WAIST or WHOLE the eyes turn up to
``eye_share_deg`` and the head takes the rest.

headDirectionShift turns the head alone to its target (the scene's
direction, or a direction word) by its ``stroke`` and holds it there, as
the new rest direction, until another shift; a gaze in the meantime turns
the head its own way and replaces it while it lasts.
"""

from __future__ import annotations

import importlib
import math
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from realizer.bml_parser import Behaviour
from realizer.face.convert.config import FAP_COUNT, FapConfiguration, check_fap_number
from realizer.face.convert.emotion import ARCHETYPES, EmotionConverter, load_default_converter
from realizer.face.convert.errors import ConversionError
from realizer.face.convert.facs import DATA_DIR, FacsMapping, load_default_mapping
from realizer.face.convert.lexemes import (
    LexemeTable,
    facs_behaviour_faps,
    lexeme_faps,
    load_default_lexemes,
)
from realizer.face.convert.visemes import (
    FAP12_MAX,
    ShapeTable,
    expression_faps,
    load_default_expressions,
    load_default_visemes,
    viseme_faps,
)
from realizer.face.tracks import (
    Blend,
    CurveKind,
    Envelope,
    FapAnimation,
    FapLimits,
    KeyframeAnimation,
    check_curve,
)
from realizer.scheduler.timing import Phase, TimingModel, TimingModelError

FACE_TYPES = ("faceLexeme", "faceFacs", "faceShift", "fap", "emotion", "viseme", "expression")
HEAD_TYPES = ("head",)
GAZE_TYPES = ("gaze", "gazeShift")
HEAD_SHIFT_TYPES = ("headDirectionShift",)
HANDLED_TYPES = FACE_TYPES + HEAD_TYPES + GAZE_TYPES + HEAD_SHIFT_TYPES

#: Layering of the behaviour types (see the module docstring).
PRIORITY: dict[str, int] = {
    "emotion": 0,
    "expression": 0,
    "viseme": 1,
    "faceLexeme": 2,
    "faceFacs": 2,
    "faceShift": 2,
    "head": 2,
    "gaze": 2,
    "gazeShift": 2,
    "headDirectionShift": 2,
    "fap": 3,
}
BLEND: dict[str, Blend] = {
    "fap": "replace",
    "gaze": "replace",
    "gazeShift": "replace",
    "headDirectionShift": "replace",
}

#: Angle units per degree (FAPU "AU" is 1e-5 rad, Tekalp and Ostermann 2000, Table 7).
ANGLE_UNITS_PER_DEGREE = math.pi / 180.0 * 1e5

#: (yaw to the left, pitch down) unit directions of the BML direction words.
DIRECTIONS: dict[str, tuple[float, float]] = {
    "LEFT": (1.0, 0.0),
    "RIGHT": (-1.0, 0.0),
    "UP": (0.0, -1.0),
    "DOWN": (0.0, 1.0),
    "UPLEFT": (math.sqrt(0.5), -math.sqrt(0.5)),
    "UPRIGHT": (-math.sqrt(0.5), -math.sqrt(0.5)),
    "DOWNLEFT": (math.sqrt(0.5), math.sqrt(0.5)),
    "DOWNRIGHT": (-math.sqrt(0.5), math.sqrt(0.5)),
}
DEFAULT_TARGET_ANGLE_DEG = 20.0


#: faceLexeme configurations a face engine keeps, (lexeme, amount) pairs.
LEXEME_CACHE = 256


@lru_cache(maxsize=1)
def load_engine_data() -> dict[str, Any]:
    path = DATA_DIR / "engine.toml"
    with path.open("rb") as handle:
        return tomllib.load(handle)


def _phase(entry: Mapping[str, float]) -> Phase:
    return Phase(
        float(entry["preferred"]), float(entry.get("weight", 1.0)), float(entry.get("minimum", 0.0))
    )


@lru_cache(maxsize=16)
def _phase_table(name: str) -> tuple[Phase, ...]:
    """The phases of one entry of engine.toml's [timing], read once."""
    return tuple(_phase(p) for p in load_engine_data()["timing"][name]["phases"])


@lru_cache(maxsize=1)
def _head_repeat() -> Phase:
    return _phase(load_engine_data()["timing"]["head"]["repeat"])


def _strokes(syncs: tuple[str, ...]) -> tuple[str, ...]:
    return tuple(s for s in syncs if s == "stroke" or s.startswith("stroke:"))


def _number_param(behaviour: Behaviour, name: str, default: float) -> float:
    try:
        return behaviour.number(name, default)
    except ValueError:
        raise ConversionError(
            f"{behaviour.type} {behaviour.id!r}: {name} is not a number"
        ) from None


def _curve(behaviour: Behaviour) -> CurveKind:
    return check_curve((behaviour.param("curve") or "linear").strip().lower())


def parse_fap_values(text: str) -> FapConfiguration:
    """``rf:fap`` values: ``N=V`` pairs separated by spaces or commas."""
    values: dict[int, float] = {}
    for item in re.split(r"[\s,]+", text.strip()):
        if not item:
            continue
        number, sep, value = item.partition("=")
        try:
            if not sep:
                raise ValueError
            values[check_fap_number(int(number))] = float(value)
        except ValueError:
            raise ConversionError(f"bad FAP value {item!r}; expected N=V") from None
    if not values:
        raise ConversionError("no FAP values given")
    return FapConfiguration.from_mapping(values)


def parse_profile_choices(text: str | None) -> dict[str, int]:
    """``fear=8`` or ``fear=8, joy=1`` -> ``{"fear": 8, "joy": 1}``."""
    choices: dict[str, int] = {}
    for item in re.split(r"[\s,]+", (text or "").strip()):
        if not item:
            continue
        name, sep, number = item.partition("=")
        if not sep or name.lower() not in ARCHETYPES or not number.isdigit():
            raise ConversionError(
                f"bad profile choice {item!r}; expected ARCHETYPE=K with ARCHETYPE one of "
                + ", ".join(ARCHETYPES)
            )
        choices[name.lower()] = int(number)
    return choices


def _shape_number(table: ShapeTable, text: str) -> int:
    """A viseme or expression given by number, name or one of its phonemes."""
    key = text.strip()
    if key.isdigit():
        return int(key)
    for shape in table.shapes:
        words = {shape.label[0].lower()} if shape.label else set()
        if shape.label:
            words |= {p.lower() for p in shape.label[0].split(",")}
        if key.lower() in words:
            return shape.number
    raise ConversionError(f"unknown {table.kind.lower()} {text!r}")


#: Timing models kept by :meth:`FaceEngine.timing` (then the cache starts again).
TIMING_CACHE = 1024


@dataclass(frozen=True, slots=True)
class FaceEngine:
    """Plans and realizes face, head and gaze behaviours; data defaults to the shipped files."""

    mapping: FacsMapping
    lexemes: LexemeTable
    emotions: EmotionConverter
    visemes: ShapeTable
    expressions: ShapeTable
    limits: FapLimits
    #: (type, params) of behaviours already validated: planning a block
    #: checks each lexeme once, not once per behaviour
    _valid: set[tuple[str, tuple[tuple[str, str], ...]]] = field(
        default_factory=set, compare=False, repr=False
    )
    #: (type, sync points) -> the timing model: models are immutable and
    #: depend on nothing else, so a block plans each shape once (the
    #: scheduler reads a model's precomputed phase table, made once a model)
    _timings: dict[tuple[str, tuple[str, ...]], TimingModel] = field(
        default_factory=dict, compare=False, repr=False
    )
    #: (lexeme, amount) -> a faceLexeme's FAP configuration: the lexeme's AUs
    #: through the FACS mapping once, not once per behaviour (a block of 250
    #: lexemes spent a third of its realization there); at most
    #: LEXEME_CACHE entries (amounts are the peer's numbers)
    _lexeme_faps: dict[tuple[str, float], FapConfiguration] = field(
        default_factory=dict, compare=False, repr=False
    )

    @classmethod
    def default(cls, limits: FapLimits | None = None) -> FaceEngine:
        return cls(
            load_default_mapping(),
            load_default_lexemes(),
            load_default_converter(),
            load_default_visemes(),
            load_default_expressions(),
            limits or default_limits(),
        )

    # --- which and when --------------------------------------------------------

    def handles(self, behaviour: Behaviour) -> bool:
        return behaviour.type in HANDLED_TYPES

    def timing(self, behaviour: Behaviour) -> TimingModel:
        """Sync points and phase preferences (seconds) of a handled behaviour."""
        syncs = tuple(behaviour.syncs)
        kind = behaviour.type
        cached = self._timings.get((kind, syncs))
        if cached is not None:
            return cached
        model = self._timing(behaviour, kind, syncs)
        if len(self._timings) >= TIMING_CACHE:
            self._timings.clear()  # bounded: sync sets come from the peer
        self._timings[(kind, syncs)] = model
        return model

    def _timing(self, behaviour: Behaviour, kind: str, syncs: tuple[str, ...]) -> TimingModel:
        table: tuple[Phase, ...]
        if kind in ("faceShift", "gazeShift"):
            table = _phase_table("shift")
        elif kind == "viseme":
            table = _phase_table("viseme")
        elif kind in FACE_TYPES:
            table = _phase_table("face")
        elif kind == "gaze":
            table = _phase_table("gaze")
            if len(syncs) != len(table) + 1:
                # The 2008 draft's seven-point gaze: the model is the engine's
                # own, and the registry re-expresses it over the draft's points.
                syncs = ("start", "ready", "relax", "end")
        elif kind == "head":
            base = _phase_table("head")
            extra = max(0, len(_strokes(syncs)) - 1)
            table = base[:3] + (_head_repeat(),) * extra + base[3:]
        elif kind == "headDirectionShift":
            table = _phase_table("head")  # the seven sync points of a head movement
        else:
            raise ConversionError(f"the face engine does not handle {kind!r}")
        if len(table) != len(syncs) - 1:
            raise ConversionError(
                f"{kind} {behaviour.id!r}: {len(syncs)} sync points but {len(table)} timing phases"
            )
        return TimingModel(syncs, table)

    def plan(self, behaviour: Behaviour) -> TimingModel:
        """The scheduler's TimingModel for the behaviour (docs/interfaces.md).

        The behaviour's parameters are checked here, before scheduling: one
        the engine cannot realize (an unknown lexeme, emotion word, AU ...)
        raises TimingModelError, which the scheduler turns into a
        CANNOT_CREATE_BEHAVIOR warning while the rest of the block goes on.
        """
        try:
            self.validate(behaviour)
            return self.timing(behaviour)
        except ConversionError as error:
            raise TimingModelError(str(error)) from None

    # --- what ------------------------------------------------------------------

    def validate(self, behaviour: Behaviour) -> None:
        """Raise ConversionError if the behaviour's parameters cannot be realized."""
        key = (behaviour.type, behaviour.params)
        if key in self._valid:
            return
        if behaviour.type in FACE_TYPES:
            self.configuration(behaviour)
        elif behaviour.type in GAZE_TYPES:
            self._gaze(behaviour)
        elif behaviour.type == "head":
            self._head_lexeme(behaviour)
        elif behaviour.type == "headDirectionShift":
            self._head_direction(behaviour)
        self._valid.add(key)

    def configuration(self, behaviour: Behaviour) -> FapConfiguration:
        """The FAP values at full level of a face behaviour (not head or gaze)."""
        kind = behaviour.type
        where = f"{kind} {behaviour.id!r}"
        try:
            if kind in ("faceLexeme", "faceShift"):
                lexeme = behaviour.lexeme or behaviour.param("type")
                if not lexeme:
                    raise ConversionError("no lexeme")
                amount = _number_param(behaviour, "amount", 0.5)
                found = self._lexeme_faps.get((lexeme, amount))
                if found is None:
                    found = lexeme_faps(lexeme, amount, table=self.lexemes, mapping=self.mapping)
                    if len(self._lexeme_faps) >= LEXEME_CACHE:
                        self._lexeme_faps.clear()
                    self._lexeme_faps[(lexeme, amount)] = found
                # a copy: the arrays of a configuration are the caller's
                return FapConfiguration(found.values.copy(), found.mask.copy())
            if kind == "faceFacs":
                au = behaviour.param("au")
                if au is None or not au.strip().isdigit():
                    raise ConversionError(f"au {au!r} is not an Action Unit number")
                return facs_behaviour_faps(
                    int(au),
                    behaviour.param("side", "BOTH"),
                    _number_param(behaviour, "amount", 0.5),
                    mapping=self.mapping,
                )
            if kind == "fap":
                values = parse_fap_values(behaviour.param("values") or "")
                return values.scaled(_number_param(behaviour, "amount", 1.0))
            if kind == "emotion":
                return self._emotion(behaviour)
            if kind == "viseme":
                first = _shape_number(self.visemes, behaviour.param("viseme1") or "")
                second_text = behaviour.param("viseme2")
                second = 0 if second_text is None else _shape_number(self.visemes, second_text)
                blend = _number_param(behaviour, "blend", FAP12_MAX)
                return viseme_faps(first, second, blend, table=self.visemes)
            if kind == "expression":
                first = _shape_number(self.expressions, behaviour.param("expression1") or "")
                second_text = behaviour.param("expression2")
                return expression_faps(
                    first,
                    _number_param(behaviour, "intensity1", FAP12_MAX),
                    None if second_text is None else _shape_number(self.expressions, second_text),
                    _number_param(behaviour, "intensity2", 0.0),
                    table=self.expressions,
                )
        except ConversionError as error:
            raise ConversionError(f"{where}: {error}") from None
        raise ConversionError(f"{where}: not a face behaviour")

    def _emotion(self, behaviour: Behaviour) -> FapConfiguration:
        choices = parse_profile_choices(behaviour.param("profile"))
        word = behaviour.param("word")
        activation_text = behaviour.param("activation")
        activation = None if activation_text is None else float(activation_text)
        if word:
            profile = self.emotions.for_word(word, activation=activation, choices=choices)
        else:
            angle = behaviour.param("angle")
            if angle is None or activation is None:
                raise ConversionError("an emotion needs a word, or an angle and an activation")
            profile = self.emotions.for_point(float(angle), activation, choices=choices)
        return profile.configuration().scaled(_number_param(behaviour, "amount", 1.0))

    def realize(
        self, behaviour: Behaviour, times: Mapping[str, float]
    ) -> FapAnimation | KeyframeAnimation | None:
        """The behaviour's animation at its solved sync ``times`` (global seconds).

        Parameters were checked by :meth:`plan`; a behaviour that did not pass
        it raises ConversionError here. Returns None for behaviours it does not
        handle.
        """
        kind = behaviour.type
        if kind not in HANDLED_TYPES:
            return None
        priority = PRIORITY[kind]
        blend = BLEND.get(kind, "add")
        if kind == "head":
            return self._head(behaviour, times, priority)
        if kind == "headDirectionShift":
            # turned by the stroke, then held: the head's new rest direction
            arrive = times.get("stroke", times["end"])
            envelope = Envelope(times["start"], arrive, math.inf, math.inf, "hermite")
            return FapAnimation(
                self._head_direction(behaviour), envelope, priority, blend, behaviour.id
            )
        if kind in GAZE_TYPES:
            target = self._gaze(behaviour)
            if kind == "gazeShift":
                envelope = Envelope(times["start"], times["end"], math.inf, math.inf, "hermite")
            else:
                envelope = Envelope(
                    times["start"], times["ready"], times["relax"], times["end"], "hermite"
                )
            return FapAnimation(target, envelope, priority, blend, behaviour.id)
        curve = _curve(behaviour)
        if kind == "faceShift":
            envelope = Envelope(times["start"], times["end"], math.inf, math.inf, curve)
        else:
            envelope = Envelope.from_syncs(times, curve)
        return FapAnimation(self.configuration(behaviour), envelope, priority, blend, behaviour.id)

    def _head(
        self, behaviour: Behaviour, times: Mapping[str, float], priority: int
    ) -> KeyframeAnimation:
        lexeme = self._head_lexeme(behaviour)
        table = load_engine_data()["head"]
        fap = int(table[lexeme]["fap"])
        amplitude = float(table[lexeme]["amplitude"]) * _number_param(behaviour, "amount", 0.5)
        strokes = [times[s] for s in _strokes(tuple(behaviour.syncs)) if s in times]
        if not strokes:
            raise ConversionError(f"head {behaviour.id!r}: no stroke time")
        start, end = times["start"], times["end"]
        stroke_start = times.get("strokeStart", start)
        stroke_end = times.get("strokeEnd", strokes[-1])
        relax = times.get("relax", stroke_end)
        keys: list[tuple[float, float]] = [(start, 0.0)]
        if lexeme == "NOD":  # down at each stroke, back up between
            keys.append((stroke_start, -0.15 * amplitude))
            for i, t in enumerate(strokes):
                keys.append((t, amplitude))
                if i + 1 < len(strokes):
                    keys.append(((t + strokes[i + 1]) / 2, -0.15 * amplitude))
            keys += [(stroke_end, 0.0), (end, 0.0)]
        elif lexeme == "SHAKE":  # left at each stroke, right between and after
            keys.append((stroke_start, 0.0))
            for i, t in enumerate(strokes):
                keys.append((t, amplitude))
                after = strokes[i + 1] if i + 1 < len(strokes) else stroke_end
                keys.append(((t + after) / 2, -amplitude))
            keys += [(stroke_end, 0.0), (end, 0.0)]
        else:  # TILT: tilt at the strokes, hold until relax
            keys.append((stroke_start, 0.0))
            for i, t in enumerate(strokes):
                keys.append((t, amplitude))
                if i + 1 < len(strokes):
                    keys.append(((t + strokes[i + 1]) / 2, 0.5 * amplitude))
            keys += [(max(relax, strokes[-1]), amplitude), (end, 0.0)]
        keys.sort(key=lambda key: key[0])
        return KeyframeAnimation(
            (fap,),
            np.array([t for t, _ in keys]),
            np.array([[v] for _, v in keys]),
            "hermite",
            priority,
            "add",
            behaviour.id,
        )

    def _head_lexeme(self, behaviour: Behaviour) -> str:
        lexeme = (behaviour.lexeme or behaviour.param("type") or "").strip().upper()
        table = load_engine_data()["head"]
        if lexeme not in table:
            raise ConversionError(
                f"head {behaviour.id!r}: unknown lexeme {lexeme!r}; known: {', '.join(table)}"
            )
        return lexeme

    def _head_direction(self, behaviour: Behaviour) -> FapConfiguration:
        """Head pitch and yaw (FAPs 48, 49) of a headDirectionShift: the
        scene's direction to its target, or a direction word's
        DEFAULT_TARGET_ANGLE_DEG; any other target: straight ahead."""
        target = (behaviour.param("target") or "").strip().upper().replace("_", "")
        scene_yaw, scene_pitch = behaviour.param("sceneYaw"), behaviour.param("scenePitch")
        if scene_yaw is not None and scene_pitch is not None:
            yaw, pitch = float(scene_yaw), float(scene_pitch)
        elif target in DIRECTIONS:
            dy, dp = DIRECTIONS[target]
            yaw, pitch = dy * DEFAULT_TARGET_ANGLE_DEG, dp * DEFAULT_TARGET_ANGLE_DEG
        else:
            yaw = pitch = 0.0
        return FapConfiguration.from_mapping(
            {49: yaw * ANGLE_UNITS_PER_DEGREE, 48: pitch * ANGLE_UNITS_PER_DEGREE}
        )

    def _gaze(self, behaviour: Behaviour) -> FapConfiguration:
        data = load_engine_data()["gaze"]
        target = (behaviour.param("target") or "").strip().upper().replace("_", "")
        # the draft dialect (Paul 2010) names them direction and angle
        direction_word = (
            (behaviour.param("offsetDirection") or behaviour.param("direction") or "")
            .strip()
            .upper()
        )
        angle_name = "offsetAngle" if behaviour.param("offsetAngle") is not None else "angle"
        angle = _number_param(behaviour, angle_name, 0.0)
        yaw = pitch = 0.0
        scene_yaw, scene_pitch = behaviour.param("sceneYaw"), behaviour.param("scenePitch")
        if scene_yaw is not None and scene_pitch is not None:
            # The session found the target in its scene (realizer.scene): the
            # direction from the eyes, degrees, yaw to the left, pitch down.
            yaw, pitch = float(scene_yaw), float(scene_pitch)
        elif target in DIRECTIONS:
            dy, dp = DIRECTIONS[target]
            base = DEFAULT_TARGET_ANGLE_DEG if not direction_word else 0.0
            yaw, pitch = dy * base, dp * base
        if direction_word:
            if direction_word not in DIRECTIONS:
                raise ConversionError(
                    f"gaze {behaviour.id!r}: unknown offsetDirection {direction_word!r}"
                )
            dy, dp = DIRECTIONS[direction_word]
            yaw += dy * angle
            pitch += dp * angle
        influence = (behaviour.param("influence") or "EYES").strip().upper()
        eye_limit = float(data["eye_limit_deg"])
        if influence == "EYES":
            eye_yaw, eye_pitch, head_yaw, head_pitch = yaw, pitch, 0.0, 0.0
        else:
            share = float(data["eye_share_deg"])
            eye_yaw = float(np.clip(yaw, -share, share))
            eye_pitch = float(np.clip(pitch, -share, share))
            head_yaw, head_pitch = yaw - eye_yaw, pitch - eye_pitch
        eye_yaw = float(np.clip(eye_yaw, -eye_limit, eye_limit))
        eye_pitch = float(np.clip(eye_pitch, -eye_limit, eye_limit))
        values = {
            23: eye_yaw * ANGLE_UNITS_PER_DEGREE,
            24: eye_yaw * ANGLE_UNITS_PER_DEGREE,
            25: eye_pitch * ANGLE_UNITS_PER_DEGREE,
            26: eye_pitch * ANGLE_UNITS_PER_DEGREE,
        }
        if influence != "EYES":
            values[49] = head_yaw * ANGLE_UNITS_PER_DEGREE
            values[48] = head_pitch * ANGLE_UNITS_PER_DEGREE
        return FapConfiguration.from_mapping(values)


def default_limits() -> FapLimits:
    """Each FAP's range from the FAP table of :mod:`realizer.face.faps` (Tekalp and Ostermann 2000
    Table 7): the I-frame quantised minimum and maximum times the quantisation
    step, i.e. the largest values an MPEG-4 FAP stream can carry (a
    unidirectional FAP such as open_jaw cannot go below 0). Unbounded if the
    table is not available."""
    try:
        fap_table = importlib.import_module("realizer.face.faps")
    except ImportError:
        return FapLimits.unbounded()
    lower = np.full(FAP_COUNT, -np.inf)
    upper = np.full(FAP_COUNT, np.inf)
    for number, info in fap_table.load_fap_table().items():
        if number <= 2:
            continue  # FAP 1 and 2 are expanded into the others, never mixed
        lower[number - 1] = float(info.iframe_min) * float(info.quant_step)
        upper[number - 1] = float(info.iframe_max) * float(info.quant_step)
    return FapLimits(lower, upper)
