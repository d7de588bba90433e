"""Idle motion (realizer.face.idle) and the session's use of it."""

from __future__ import annotations

import numpy as np
import pytest

from realizer.face.idle import DEGREE_AU, IDLE_FAPS, IdleMotion, IdleSettings


def frames(motion: IdleMotion, seconds: float, rate: float = 100.0) -> np.ndarray:
    return np.array([motion.frame(k / rate)[0] for k in range(int(seconds * rate))])


def test_the_same_seed_gives_the_same_motion_whatever_was_asked_before() -> None:
    a = IdleMotion(IdleSettings(seed=5))
    b = IdleMotion(IdleSettings(seed=5))
    times = [0.0, 3.7, 12.25, 31.0, 95.5]
    for t in times:
        a.frame(t - 0.5)  # a different history
    for t in times:
        np.testing.assert_array_equal(a.frame(t)[0], b.frame(t)[0])


def test_different_seeds_move_differently() -> None:
    a = frames(IdleMotion(IdleSettings(seed=1)), 20.0, 20.0)
    b = frames(IdleMotion(IdleSettings(seed=2)), 20.0, 20.0)
    assert not np.allclose(a, b)


def test_the_mask_names_exactly_the_idle_faps() -> None:
    _, mask = IdleMotion().frame(1.0)
    assert sorted(np.flatnonzero(mask) + 1) == sorted(IDLE_FAPS)


def blinks(lids: np.ndarray) -> int:
    shut = lids >= 1000.0
    return int(np.sum(shut[1:] & ~shut[:-1]))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_blinks_come_at_natural_random_intervals_and_close_the_eyes(seed: int) -> None:
    values = frames(IdleMotion(IdleSettings(seed=seed)), 120.0)
    count = blinks(values[:, 18])
    assert 15 <= count <= 70  # 7.5 to 35 a minute: about 15 to 20 is typical
    np.testing.assert_array_equal(values[:, 18], values[:, 19])  # both eyes at once
    shut = np.flatnonzero(values[:, 18] >= 1000.0)
    gaps = np.diff(shut)[np.diff(shut) > 1] / 100.0
    assert gaps.std() > 0.3  # irregular, not a metronome


def test_a_blink_is_quick() -> None:
    values = frames(IdleMotion(IdleSettings(seed=3)), 40.0, 400.0)[:, 18]
    closed = values > 200.0  # noticeably closing
    starts = np.flatnonzero(closed[1:] & ~closed[:-1])
    ends = np.flatnonzero(~closed[1:] & closed[:-1])
    durations = (ends[: len(starts)] - starts[: len(ends)]) / 400.0
    assert len(durations) > 5
    assert np.all(durations < 0.45)


def test_saccades_are_small_quick_jumps() -> None:
    settings = IdleSettings(seed=4)
    values = frames(IdleMotion(settings), 60.0, 200.0)
    yaw = values[:, 22] / DEGREE_AU
    pitch = values[:, 24] / DEGREE_AU
    assert np.abs(yaw).max() <= settings.saccade_degrees + 1e-9
    np.testing.assert_array_equal(values[:, 22], values[:, 23])  # the eyes move together
    speed = np.abs(np.diff(yaw)) * 200.0  # degrees per second
    moving = speed > 20.0
    jumps = int(np.sum(moving[1:] & ~moving[:-1]))
    assert 15 <= jumps <= 120
    assert moving.mean() < 0.1  # the eyes rest between jumps
    assert np.abs(pitch).max() > 0.1


def test_the_upper_lids_follow_the_eyes_pitch() -> None:
    values = frames(IdleMotion(IdleSettings(seed=6)), 60.0, 50.0)
    open_ = values[:, 18] < 150.0  # not in a blink (following moves them < 100)
    pitch, lids = values[open_, 24], values[open_, 18]
    assert np.corrcoef(pitch, lids)[0, 1] > 0.7  # looking down lowers the lids
    down, up = lids[pitch > DEGREE_AU], lids[pitch < -DEGREE_AU]
    assert len(down) and len(up)
    assert np.median(down) > 0.0 > np.median(up)  # and looking up raises them


def test_breathing_and_head_motion_are_small_and_slow() -> None:
    values = frames(IdleMotion(IdleSettings(seed=7)), 30.0, 50.0)
    head = values[:, 47:50] / DEGREE_AU
    assert np.abs(head).max() < 2.0
    assert np.abs(head).max(axis=0).min() > 0.05  # every axis moves a little
    assert np.abs(np.diff(head, axis=0)).max() * 50.0 < 3.0  # degrees per second


@pytest.mark.parametrize(
    "bad",
    [
        {"blink_interval": (5.0, 1.0)},
        {"blink_interval": (0.0, 1.0)},
        {"saccade_interval": (0.01, 1.0)},
        {"blink_close_s": 0.0},
    ],
)
def test_bad_settings_are_refused(bad: dict[str, object]) -> None:
    with pytest.raises(ValueError):
        IdleSettings(**bad)  # type: ignore[arg-type]


def bml(body: str) -> str:
    return (
        '<bml xmlns="http://www.bml-initiative.org/bml/bml-1.0" id="b1" characterId="c">'
        f"{body}</bml>"
    )


def test_a_session_without_idle_motion_shows_a_neutral_face() -> None:
    from realizer.face.default import load_default_face
    from realizer.session import Session

    session = Session("c", load_default_face())
    assert not session.frame(2.0).mask.any()


def test_a_session_shows_idle_motion_between_behaviours() -> None:
    from realizer.face.default import load_default_face
    from realizer.session import Session

    motion = IdleMotion(IdleSettings(seed=9))
    session = Session("c", load_default_face(), idle=motion)
    for now in (0.5, 7.25):
        frame = session.frame(now)
        values, mask = IdleMotion(IdleSettings(seed=9)).frame(now)
        np.testing.assert_array_equal(frame.mask, mask)
        np.testing.assert_array_equal(frame.values, values)


def test_explicit_behaviours_win_per_fap_over_idle_motion() -> None:
    from realizer.face.default import load_default_face
    from realizer.session import Session

    face = load_default_face()
    plain = Session("c", face)
    alive = Session("c", face, idle=IdleMotion(IdleSettings(seed=9)))
    block = bml('<faceLexeme id="f" lexeme="CLOSE_EYES" start="0" end="3"/>')
    for session in (plain, alive):
        assert session.receive_bml(block, now=0.0) is not None
        session.tick(1.5)
    explicit, mixed = plain.frame(1.5), alive.frame(1.5)
    assert explicit.mask[18] and explicit.values[18] > 0
    # the lids are the behaviour's, not a blink or gaze following
    assert mixed.values[18] == explicit.values[18]
    assert mixed.values[19] == explicit.values[19]
    # FAPs the behaviour leaves alone are the idle motion's
    idle, _ = IdleMotion(IdleSettings(seed=9)).frame(1.5)
    free = ~explicit.mask
    np.testing.assert_array_equal(mixed.values[free], np.where(free, idle, 0.0)[free])
    assert mixed.mask[47] and not explicit.mask[47]


def test_session_factory_keeps_idle_motion_off_unless_asked() -> None:
    from realizer.face.default import load_default_face
    from realizer.service.assets import session_factory

    face = load_default_face()
    assert session_factory(face)("c").idle is None
    a = session_factory(face, idle=True)("alice").idle
    b = session_factory(face, idle=True)("bob").idle
    assert a is not None and b is not None
    assert a.settings.seed != b.settings.seed  # each character its own motion
    again = session_factory(face, idle=True)("alice").idle
    assert again is not None and again.settings.seed == a.settings.seed


def test_the_commands_turn_idle_motion_on_by_default_and_off_with_the_environment(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import argparse
    import os

    from realizer.commands import render, serve
    from realizer.service.settings import resolve

    def idle(args: argparse.Namespace) -> bool:
        # serve's flag is None when not given: its settings (file, then
        # REALIZER_IDLE) decide
        if args.command_name == "serve":
            return resolve({}, {"idle": args.idle}, os.environ).idle
        return bool(args.idle)

    for command in (render, serve):
        for setting, expected in (("1", True), ("0", False)):
            monkeypatch.setenv("REALIZER_IDLE", setting)
            parser = argparse.ArgumentParser()
            command.register(parser.add_subparsers(dest="command_name"))
            words = ["render", "x.bml", "-o", "x.mp4"] if command is render else ["serve"]
            assert idle(parser.parse_args(words)) is expected
            assert idle(parser.parse_args([*words, "--no-idle"])) is False


def test_an_offset_moves_the_motion_in_time_and_unix_times_still_blink() -> None:
    """A worker's idle motion runs on the wall clock (``offset``: the Unix
    time of its frame 0): two motions whose offsets differ by d agree when
    asked d apart, and at Unix-size times the motion still blinks, looks
    about and stays in its ranges (no precision lost)."""
    settings = IdleSettings(seed=5)
    epoch = 1_780_000_000.25
    early = IdleMotion(settings, offset=epoch)
    late = IdleMotion(settings, offset=epoch + 42.5)
    for t in np.arange(0.0, 20.0, 1 / 60):
        a, mask_a = early.frame(t + 42.5)
        b, mask_b = late.frame(t)
        assert np.array_equal(a, b) and np.array_equal(mask_a, mask_b)
    lids = [early.frame(t)[0][18] for t in np.arange(0.0, 60.0, 1 / 60)]
    assert max(lids) > 900  # shut in a blink
    yaw = [early.frame(t)[0][22] / DEGREE_AU for t in np.arange(0.0, 60.0, 1 / 60)]
    assert 0.5 < max(abs(y) for y in yaw) <= 4.0 + 1e-9
