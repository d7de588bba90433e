"""Emotions to MPEG-4 FAP ranges (Raouzaiou et al. 2002, sections 4 and 6; Paul 2010, chapter 6).

Data (``realizer/face/data/emotion``):

- ``profiles.txt``: every archetypal profile of Raouzaiou et al. 2002, Table 5 in the
  profile file format of Paul 2010, figure 6.5 (a label line ``Fear 8``, then
  ``F3 [400, 560], F5 [-240, -160], ...``).
- ``additions.txt``: FAPs added to some of those profiles (same format), for
  face formations the paper's vocabulary or its FAP-to-AU mapping (Table 1)
  names but a profile leaves out; they never change a range of Table 5.
- ``wheels.txt``: where the six archetypes sit on Plutchik's wheel (angle in
  degrees, Whissell activation) and which profile each uses by default.
- ``vocabulary.txt``: emotion words with activation, evaluation, angle and,
  for words "similar in nature to an archetypal one", their category.

Rules. For an emotion I in the category of archetype A (Raouzaiou et al. 2002, section 4.1,
Paul 2010, section 6.2), every range of A's profile is scaled by
``a_I / a_A``. For I between archetypes A1 and A2 on the wheel (section 4.2):

1. I uses the FAPs of either profile;
2. a FAP in both with the same sign: translate each range by ``a_I / a_Ak``,
   then interpolate the translated centres and lengths by angle;
3. a FAP in both with opposite signs: intersect the translated ranges and
   drop the FAP when the intersection is empty;
4. a FAP in one profile only: ``a_I / (2 a_Ak)`` times its range ("averaged
   with the neutral face").

The angular weights. Raouzaiou et al. 2002, equations (5) and (6) (and Paul 2010, equations
6.3 and 6.4) print the weight ``(w_I - w_A1) / (w_A2 - w_A1)`` on A1's term,
which gives I *all* of A2's profile when I sits on A1. Raouzaiou et al. 2002's own worked
example (guilty, equation 12) puts that weight on A2 (the nearer sad) and is
the linear interpolation. This module interpolates by default
(``weighting="interpolate"``) and keeps the printed form as
``weighting="as-printed"``, which Paul 2010's FAP 20 example follows.
docs/emotion.md gives the numbers.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import Literal

import numpy as np

from realizer.face.convert.config import FAP_COUNT, FapConfiguration, check_fap_number
from realizer.face.convert.errors import ConversionError, DataFileError
from realizer.face.convert.facs import DATA_DIR

Weighting = Literal["interpolate", "as-printed"]

#: The six archetypal emotions of Raouzaiou et al. 2002 (Ekman), in the order of Table 5.
ARCHETYPES = ("anger", "sadness", "joy", "disgust", "fear", "surprise")

#: Angles closer than this (degrees) count as the same wheel position.
ANGLE_TOLERANCE_DEG = 1e-6


@dataclass(frozen=True, slots=True)
class FapRange:
    """A FAP's range of variation ``[low, high]`` in FAPU-scaled units."""

    low: float
    high: float

    def __post_init__(self) -> None:
        if self.low > self.high:
            raise ConversionError(f"range [{self.low}, {self.high}] has low above high")

    @classmethod
    def ordered(cls, a: float, b: float) -> FapRange:
        return cls(min(a, b), max(a, b))

    @classmethod
    def around(cls, center: float, length: float) -> FapRange:
        return cls(center - length / 2, center + length / 2)

    @property
    def center(self) -> float:
        return (self.low + self.high) / 2

    @property
    def length(self) -> float:
        return self.high - self.low

    @property
    def sign(self) -> int:
        """Direction of movement: the sign of the centre (0 for a range held at 0)."""
        return int(np.sign(self.center))

    def scaled(self, factor: float) -> FapRange:
        return FapRange.ordered(self.low * factor, self.high * factor)

    def intersection(self, other: FapRange) -> FapRange | None:
        low, high = max(self.low, other.low), min(self.high, other.high)
        return FapRange(low, high) if low <= high else None


RangeMap = dict[int, FapRange]


@dataclass(frozen=True, slots=True)
class Profile:
    """One archetypal profile: ``archetype`` (lower case), ``number`` (k of P^(k)),
    and its FAP ranges in file order."""

    archetype: str
    number: int
    ranges: tuple[tuple[int, FapRange], ...]

    def as_dict(self) -> RangeMap:
        return dict(self.ranges)

    @property
    def label(self) -> str:
        return f"{self.archetype.capitalize()} {self.number}"

    @property
    def key(self) -> tuple[str, int]:
        return (self.archetype, self.number)


@dataclass(frozen=True, slots=True)
class ProfileSet:
    profiles: tuple[Profile, ...]

    def get(self, archetype: str, number: int) -> Profile:
        for profile in self.profiles:
            if profile.archetype == archetype.lower() and profile.number == number:
                return profile
        numbers = self.numbers(archetype)
        raise ConversionError(
            f"no profile {archetype} {number}; {archetype} has "
            + (", ".join(map(str, numbers)) if numbers else "no profiles")
        )

    def numbers(self, archetype: str) -> tuple[int, ...]:
        return tuple(p.number for p in self.profiles if p.archetype == archetype.lower())


def _parse_range_list(text: str, *, source: str, line: int) -> tuple[tuple[int, FapRange], ...]:
    """Parse ``F3 [400, 560], F5 [-240, -160]`` (a bare ``F37 0`` is ``[0, 0]``)."""
    ranges: list[tuple[int, FapRange]] = []
    rest = text.strip()
    while rest:
        if not rest.startswith(("F", "f")):
            raise DataFileError(f"expected F<number> at {rest[:20]!r}", source=source, line=line)
        head, sep, tail = rest[1:].partition(",")
        token = head.strip()
        try:
            if "[" in token:
                number, _, bound = token.partition("[")
                low_text = bound
                high_text, _, after = tail.partition("]")
                if after.strip() and not after.strip().startswith(","):
                    raise DataFileError(
                        f"junk after range: {after[:20]!r}", source=source, line=line
                    )
                fap = check_fap_number(int(number))
                rng = FapRange.ordered(float(low_text), float(high_text))
                rest = after.strip().removeprefix(",").strip()
            else:
                number, value = token.split()
                fap = check_fap_number(int(number))
                rng = FapRange(float(value), float(value))
                rest = tail.strip() if sep else ""
        except DataFileError:
            raise
        except (ValueError, ConversionError) as error:
            raise DataFileError(
                f"bad FAP range {token!r}: {error}", source=source, line=line
            ) from None
        if any(existing == fap for existing, _ in ranges):
            raise DataFileError(f"F{fap} appears twice in one profile", source=source, line=line)
        ranges.append((fap, rng))
    return tuple(ranges)


def _comment_free(text: str) -> list[tuple[int, str]]:
    lines = []
    for number, line in enumerate(text.splitlines(), start=1):
        body = line.partition("#")[0].strip()
        if body:
            lines.append((number, body))
    return lines


def parse_profiles(text: str, *, source: str = "<profiles>") -> ProfileSet:
    """Parse a profile file (Paul 2010, figure 6.5); raise DataFileError."""
    profiles: list[Profile] = []
    lines = _comment_free(text)
    if len(lines) % 2:
        raise DataFileError(
            "a profile label without its profile line", source=source, line=lines[-1][0]
        )
    for (label_line, label), (line, body) in zip(lines[::2], lines[1::2], strict=True):
        fields = label.split()
        if len(fields) != 2 or not fields[1].lstrip("-").isdigit():
            raise DataFileError(
                f"expected a profile label '<Archetype> <number>', got {label!r}",
                source=source,
                line=label_line,
            )
        profile = Profile(
            fields[0].lower(), int(fields[1]), _parse_range_list(body, source=source, line=line)
        )
        if any(p.archetype == profile.archetype and p.number == profile.number for p in profiles):
            raise DataFileError(f"profile {label} appears twice", source=source, line=label_line)
        profiles.append(profile)
    return ProfileSet(tuple(profiles))


def add_ranges(profiles: ProfileSet, additions: ProfileSet) -> ProfileSet:
    """``profiles`` with the FAP ranges of ``additions`` (same file format)
    appended to the profiles of the same label. An addition may only add
    FAPs a profile lacks, never change one it has: the ranges of Raouzaiou
    et al. 2002, Table 5 stay as transcribed."""
    merged = []
    for profile in profiles.profiles:
        extra = [a for a in additions.profiles if (a.archetype, a.number) == profile.key]
        ranges = profile.ranges
        for addition in extra:
            clash = sorted(set(dict(addition.ranges)) & set(dict(ranges)))
            if clash:
                raise ConversionError(
                    f"addition to {profile.label} repeats F{clash[0]} of the profile"
                )
            ranges = ranges + addition.ranges
        merged.append(Profile(profile.archetype, profile.number, ranges))
    known = {p.key for p in profiles.profiles}
    for addition in additions.profiles:
        if addition.key not in known:
            raise ConversionError(f"addition to {addition.label}, which is no profile")
    return ProfileSet(tuple(merged))


def _num(value: float) -> str:
    return str(int(value)) if value == int(value) else repr(value)


def format_range_list(ranges: Iterable[tuple[int, FapRange]]) -> str:
    return ", ".join(f"F{fap} [{_num(r.low)}, {_num(r.high)}]" for fap, r in ranges)


def format_profiles(profiles: ProfileSet) -> str:
    """Write profiles in the file format; :func:`parse_profiles` reads them back equal."""
    out: list[str] = []
    for profile in profiles.profiles:
        out.append(profile.label)
        out.append(format_range_list(profile.ranges))
    return "\n".join(out) + "\n"


@dataclass(frozen=True, slots=True)
class Archetype:
    """An archetype's place on a wheel: angle (degrees), Whissell activation."""

    name: str
    angle: float
    activation: float
    default_profile: int
    term: str


@dataclass(frozen=True, slots=True)
class Wheel:
    name: str
    archetypes: tuple[Archetype, ...]  # ascending angle

    def archetype(self, name: str) -> Archetype:
        for archetype in self.archetypes:
            if archetype.name == name.lower():
                return archetype
        raise ConversionError(f"wheel {self.name!r} has no archetype {name!r}")

    def neighbours(self, angle: float) -> tuple[Archetype, Archetype, float, float, float]:
        """The archetypes on either side of ``angle`` and the three angles unwrapped
        so that ``w1 <= angle <= w2`` (degrees)."""
        a = angle % 360.0
        ordered = sorted(self.archetypes, key=lambda x: x.angle)
        below = [x for x in ordered if x.angle <= a]
        first = below[-1] if below else ordered[-1]
        index = ordered.index(first)
        second = ordered[(index + 1) % len(ordered)]
        w1 = first.angle if first.angle <= a else first.angle - 360.0
        w2 = second.angle if second.angle > w1 else second.angle + 360.0
        if w2 <= a:
            w2 += 360.0
        return first, second, w1, a, w2


@dataclass(frozen=True, slots=True)
class EmotionWord:
    word: str
    wheel: str
    angle: float
    activation: float | None
    evaluation: float | None
    category: str | None
    source: str


def _opt(text: str) -> float | None:
    return None if text == "-" else float(text)


def parse_wheels(text: str, *, source: str = "<wheels>") -> dict[str, Wheel]:
    rows: dict[str, list[Archetype]] = {}
    for line, body in _comment_free(text):
        fields = body.split()
        if len(fields) != 6:
            raise DataFileError(f"expected 6 columns, got {len(fields)}", source=source, line=line)
        try:
            archetype = Archetype(
                fields[1].lower(), float(fields[2]), float(fields[3]), int(fields[4]), fields[5]
            )
        except ValueError as error:
            raise DataFileError(str(error), source=source, line=line) from None
        if archetype.name not in ARCHETYPES:
            raise DataFileError(
                f"{fields[1]!r} is not an archetypal emotion", source=source, line=line
            )
        if archetype.activation <= 0:
            raise DataFileError("activation must be positive", source=source, line=line)
        rows.setdefault(fields[0], []).append(archetype)
    return {
        name: Wheel(name, tuple(sorted(items, key=lambda a: a.angle)))
        for name, items in rows.items()
    }


def format_wheels(wheels: Mapping[str, Wheel]) -> str:
    return (
        "\n".join(
            f"{wheel.name}  {a.name}  {_num(a.angle)}  {_num(a.activation)}  "
            f"{a.default_profile}  {a.term}"
            for wheel in wheels.values()
            for a in wheel.archetypes
        )
        + "\n"
    )


def parse_vocabulary(text: str, *, source: str = "<vocabulary>") -> dict[str, EmotionWord]:
    words: dict[str, EmotionWord] = {}
    for line, body in _comment_free(text):
        fields = body.split()
        if len(fields) != 7:
            raise DataFileError(f"expected 7 columns, got {len(fields)}", source=source, line=line)
        try:
            word = EmotionWord(
                fields[0].lower(),
                fields[1],
                float(fields[2]),
                _opt(fields[3]),
                _opt(fields[4]),
                None if fields[5] == "-" else fields[5].lower(),
                fields[6],
            )
        except ValueError as error:
            raise DataFileError(str(error), source=source, line=line) from None
        if word.word in words:
            raise DataFileError(f"word {word.word!r} appears twice", source=source, line=line)
        words[word.word] = word
    return words


def format_vocabulary(words: Mapping[str, EmotionWord]) -> str:
    def opt(value: float | None) -> str:
        return "-" if value is None else _num(value)

    return (
        "\n".join(
            f"{w.word}  {w.wheel}  {_num(w.angle)}  {opt(w.activation)}  {opt(w.evaluation)}  "
            f"{w.category or '-'}  {w.source}"
            for w in words.values()
        )
        + "\n"
    )


# --- the rules --------------------------------------------------------------------


def same_category(
    profile: Mapping[int, FapRange], a_archetype: float, a_emotion: float
) -> RangeMap:
    """Raouzaiou et al. 2002, section 4.1: every range scaled by ``a_I / a_A``."""
    ratio = a_emotion / a_archetype
    return {fap: rng.scaled(ratio) for fap, rng in profile.items()}


def angular_weights(
    w1: float, w_i: float, w2: float, weighting: Weighting = "interpolate"
) -> tuple[float, float]:
    """Weights of A1's and A2's terms for an emotion at ``w_i`` between ``w1`` and ``w2``.

    ``"interpolate"``: A1 weighs ``(w2 - w_i) / (w2 - w1)`` (1 on A1);
    Raouzaiou et al. 2002's worked example. ``"as-printed"``: A1 weighs ``(w_i - w1) / (w2 - w1)``,
    Raouzaiou et al. 2002, equations (5)-(6) and Paul 2010 (6.3)-(6.4) as printed.
    """
    if not w1 <= w_i <= w2 or w2 <= w1:
        raise ConversionError(f"angle {w_i} is not between {w1} and {w2}")
    toward_second = (w_i - w1) / (w2 - w1)
    if weighting == "interpolate":
        return 1.0 - toward_second, toward_second
    if weighting == "as-printed":
        return toward_second, 1.0 - toward_second
    raise ConversionError(f"unknown weighting {weighting!r}")


def weighted_range(
    c1: float, s1: float, c2: float, s2: float, weight1: float, weight2: float
) -> FapRange:
    """Raouzaiou et al. 2002, rule 2 (iii): centre and length as weighted sums of the two
    translated ranges' centres and lengths."""
    return FapRange.around(weight1 * c1 + weight2 * c2, weight1 * s1 + weight2 * s2)


def between_archetypes(
    profile1: Mapping[int, FapRange],
    a1: float,
    w1: float,
    profile2: Mapping[int, FapRange],
    a2: float,
    w2: float,
    a_emotion: float,
    w_emotion: float,
    weighting: Weighting = "interpolate",
) -> RangeMap:
    """Raouzaiou et al. 2002, section 4.2, rules 1-6: the profile of an emotion at angle
    ``w_emotion`` (degrees) and activation ``a_emotion`` between archetype 1
    (``profile1``, activation ``a1``, angle ``w1``) and archetype 2."""
    weight1, weight2 = angular_weights(w1, w_emotion, w2, weighting)
    result: RangeMap = {}
    for fap in sorted(set(profile1) | set(profile2)):
        if fap in profile1 and fap in profile2:
            t1 = profile1[fap].scaled(a_emotion / a1)
            t2 = profile2[fap].scaled(a_emotion / a2)
            if t1.sign * t2.sign < 0:  # rule 3: contradictory directions
                meet = t1.intersection(t2)
                if meet is not None:
                    result[fap] = meet
            else:  # rule 2: same direction (a range held at 0 agrees with both)
                result[fap] = weighted_range(
                    t1.center, t1.length, t2.center, t2.length, weight1, weight2
                )
        elif fap in profile1:  # rule 4: averaged with the neutral face
            result[fap] = profile1[fap].scaled(a_emotion / (2 * a1))
        else:
            result[fap] = profile2[fap].scaled(a_emotion / (2 * a2))
    return result


@dataclass(frozen=True, slots=True)
class EmotionProfile:
    """The FAP ranges computed for one emotion, and how they were obtained."""

    ranges: tuple[tuple[int, FapRange], ...]
    rule: str  # "archetype", "same-category" or "between"
    sources: tuple[str, ...]  # the archetypal profiles used, e.g. ("Fear 8",)
    angle: float
    activation: float

    def as_dict(self) -> RangeMap:
        return dict(self.ranges)

    def configuration(self) -> FapConfiguration:
        """The FAP values to animate: each range's midpoint (Raouzaiou et al. 2002, section 6.1:
        "The FAP values that we used are the median ones of the ranges")."""
        values = np.zeros(FAP_COUNT)
        mask = np.zeros(FAP_COUNT, dtype=bool)
        for fap, rng in self.ranges:
            values[fap - 1] = rng.center
            mask[fap - 1] = True
        return FapConfiguration(values, mask)


@dataclass(frozen=True, slots=True)
class EmotionConverter:
    """Emotion words and wheel points to profiles, with the default data unless given."""

    profiles: ProfileSet
    wheels: Mapping[str, Wheel]
    vocabulary: Mapping[str, EmotionWord]
    default_wheel: str = "measured"
    weighting: Weighting = "interpolate"

    def wheel(self, name: str | None = None) -> Wheel:
        key = name or self.default_wheel
        if key not in self.wheels:
            raise ConversionError(f"unknown wheel {key!r}; known: {', '.join(self.wheels)}")
        return self.wheels[key]

    def _profile(self, archetype: Archetype, choices: Mapping[str, int] | None) -> Profile:
        number = (choices or {}).get(archetype.name, archetype.default_profile)
        return self.profiles.get(archetype.name, number)

    def for_point(
        self,
        angle: float,
        activation: float,
        *,
        wheel: str | None = None,
        choices: Mapping[str, int] | None = None,
        category: str | None = None,
    ) -> EmotionProfile:
        """The profile at wheel ``angle`` (degrees) and ``activation``; ``choices``
        picks profiles by number per archetype (``{"fear": 8}``); ``category``
        forces the same-category rule with that archetype."""
        if not activation > 0 or not math.isfinite(activation):
            raise ConversionError(f"activation must be a positive number, not {activation}")
        chosen = self.wheel(wheel)
        for name in choices or {}:
            if name not in ARCHETYPES:
                raise ConversionError(
                    f"{name!r} is not an archetypal emotion ({', '.join(ARCHETYPES)})"
                )
        if category is None:
            for archetype in chosen.archetypes:
                delta = abs((angle - archetype.angle + 180.0) % 360.0 - 180.0)
                if delta < ANGLE_TOLERANCE_DEG:
                    category = archetype.name
        if category is not None:
            archetype = chosen.archetype(category)
            profile = self._profile(archetype, choices)
            ranges = same_category(profile.as_dict(), archetype.activation, activation)
            rule = "archetype" if activation == archetype.activation else "same-category"
            return EmotionProfile(
                tuple(sorted(ranges.items())), rule, (profile.label,), angle % 360.0, activation
            )
        first, second, w1, w_i, w2 = chosen.neighbours(angle)
        p1, p2 = self._profile(first, choices), self._profile(second, choices)
        ranges = between_archetypes(
            p1.as_dict(),
            first.activation,
            w1,
            p2.as_dict(),
            second.activation,
            w2,
            activation,
            w_i,
            self.weighting,
        )
        return EmotionProfile(
            tuple(sorted(ranges.items())),
            "between",
            (p1.label, p2.label),
            angle % 360.0,
            activation,
        )

    def for_word(
        self,
        word: str,
        *,
        activation: float | None = None,
        choices: Mapping[str, int] | None = None,
    ) -> EmotionProfile:
        """The profile of an emotion word; ``activation`` overrides the word's."""
        key = word.strip().lower()
        if key not in self.vocabulary:
            raise ConversionError(
                f"unknown emotion word {word!r}; known: {', '.join(sorted(self.vocabulary))}"
            )
        entry = self.vocabulary[key]
        chosen = self.wheel(entry.wheel)
        value = activation if activation is not None else entry.activation
        if value is None and entry.category is not None:
            value = chosen.archetype(entry.category).activation
        if value is None:
            raise ConversionError(f"{word!r} has no published activation; give one")
        return self.for_point(
            entry.angle, value, wheel=entry.wheel, choices=choices, category=entry.category
        )


@lru_cache(maxsize=2)
def load_default_converter(*, additions: bool = True) -> EmotionConverter:
    """The converter over the shipped data files: the profiles of
    ``profiles.txt`` (Raouzaiou et al. 2002, Table 5) with the FAPs of
    ``additions.txt`` added (``additions=False``: Table 5's alone)."""
    folder = DATA_DIR / "emotion"

    def read(name: str) -> tuple[str, str]:
        path = folder / name
        return path.read_text(encoding="utf-8"), str(path)

    profiles_text, profiles_source = read("profiles.txt")
    wheels_text, wheels_source = read("wheels.txt")
    words_text, words_source = read("vocabulary.txt")
    profiles = parse_profiles(profiles_text, source=profiles_source)
    if additions:
        extra_text, extra_source = read("additions.txt")
        profiles = add_ranges(profiles, parse_profiles(extra_text, source=extra_source))
    return EmotionConverter(
        profiles,
        parse_wheels(wheels_text, source=wheels_source),
        parse_vocabulary(words_text, source=words_source),
    )
