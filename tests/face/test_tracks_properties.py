"""Properties of the mixer and the file formats, over generated input."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from realizer.face.convert.config import FapConfiguration
from realizer.face.convert.emotion import (
    FapRange,
    Profile,
    ProfileSet,
    format_profiles,
    parse_profiles,
)
from realizer.face.convert.facs import (
    AuKey,
    FacsMapping,
    FapInfluence,
    format_mapping,
    parse_mapping,
)
from realizer.face.fapfile import FapFile, format_fap_file, parse_fap_file
from realizer.face.tracks import Envelope, FapAnimation, FapLimits, mix

faps = st.integers(min_value=3, max_value=68)
values = st.floats(min_value=-2000, max_value=2000, allow_nan=False).map(lambda v: round(v, 3))


@st.composite
def animations(draw: st.DrawFn) -> FapAnimation:
    chosen = draw(st.dictionaries(faps, values, min_size=1, max_size=6))
    start = draw(st.floats(min_value=0, max_value=2))
    lengths = draw(st.lists(st.floats(min_value=0, max_value=1), min_size=3, max_size=3))
    peak = start + lengths[0]
    relax = peak + lengths[1]
    return FapAnimation(
        FapConfiguration.from_mapping(chosen),
        Envelope(
            start, peak, relax, relax + lengths[2], draw(st.sampled_from(("linear", "hermite")))
        ),
    )


@settings(max_examples=60, deadline=None)
@given(
    st.lists(animations(), min_size=1, max_size=5),
    st.floats(min_value=0, max_value=5),
    st.randoms(),
)
def test_additive_layers_of_one_priority_commute(layers, now, random) -> None:  # type: ignore[no-untyped-def]
    shuffled = list(layers)
    random.shuffle(shuffled)
    a, mask_a = mix(layers, now)
    b, mask_b = mix(shuffled, now)
    assert np.allclose(a, b) and np.array_equal(mask_a, mask_b)


@settings(max_examples=60, deadline=None)
@given(st.lists(animations(), min_size=1, max_size=5), st.floats(min_value=0, max_value=5))
def test_the_mix_stays_within_each_faps_range(layers, now) -> None:  # type: ignore[no-untyped-def]
    limits = FapLimits(np.full(68, -500.0), np.full(68, 700.0))
    result, _ = mix(layers, now, limits)
    assert result.min() >= -500.0 and result.max() <= 700.0


influences = st.builds(
    FapInfluence,
    faps,
    st.just(0.0),
    st.sampled_from([0.5, 1.0, 0.25]),
    values,
    values,
)


@settings(max_examples=40, deadline=None)
@given(
    st.dictionaries(
        st.tuples(st.integers(1, 64), st.sampled_from([None, "L", "R"])),
        st.lists(influences, max_size=4),
        max_size=6,
    )
)
def test_any_mapping_round_trips_through_its_file_format(table) -> None:  # type: ignore[no-untyped-def]
    mapping = FacsMapping(
        tuple((AuKey(au, side), tuple(lines)) for (au, side), lines in table.items())
    )
    assert parse_mapping(format_mapping(mapping)) == mapping


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.dictionaries(faps, st.tuples(values, values), min_size=1, max_size=5), max_size=4)
)
def test_any_profile_set_round_trips_through_its_file_format(rows) -> None:  # type: ignore[no-untyped-def]
    profiles = ProfileSet(
        tuple(
            Profile(
                "fear", number, tuple((fap, FapRange.ordered(*pair)) for fap, pair in row.items())
            )
            for number, row in enumerate(rows)
        )
    )
    assert parse_profiles(format_profiles(profiles)) == profiles


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 5), st.data())
def test_any_fap_stream_round_trips_through_a_fap_file(frames, data) -> None:  # type: ignore[no-untyped-def]
    mask = np.array(
        data.draw(
            st.lists(
                st.lists(st.booleans(), min_size=68, max_size=68), min_size=frames, max_size=frames
            )
        )
    )
    mask[:, :2] = False
    numbers = np.array(
        data.draw(
            st.lists(
                st.lists(st.integers(-5000, 5000), min_size=68, max_size=68),
                min_size=frames,
                max_size=frames,
            )
        ),
        dtype=float,
    )
    stream = FapFile("a name with spaces", 25, np.where(mask, numbers, 0.0), mask)
    again = parse_fap_file(format_fap_file(stream))
    assert again.name == "a name with spaces"
    assert np.array_equal(again.mask, stream.mask) and np.array_equal(again.values, stream.values)
