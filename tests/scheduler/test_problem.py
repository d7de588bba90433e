"""How a :class:`Problem` records what it is given, and the models it reads.

The planner adds behaviours by their timing model (:meth:`Problem.add_model`,
which reads the model's precomputed phase table) and the caller-term views
(``phases``, ``starts``, ``equalities``, ``orderings``) are made on demand:
these tests pin that the views say exactly what was added, that keys
mentioned before their behaviour keep their place (and give the same times),
and that the engines hand out one model per shape.
"""

from __future__ import annotations

import pickle

import pytest

from realizer.bml_parser import BML_NS, parse_bml
from realizer.engines import EngineRegistry
from realizer.engines import face as face_module
from realizer.scheduler.solver import BLOCK_START, Problem, Source, solve
from realizer.scheduler.timing import Phase, TimingModel

NOD = TimingModel(
    ("start", "ready", "stroke", "end"),
    (Phase(0.3, 2.0), Phase(0.2, 1.0, 0.1, 0.5), Phase(0.4, 0.5)),
)
FACE = TimingModel(("start", "attackPeak", "end"), (Phase(0.3), Phase(1.0, 0.05)))


def test_a_model_precomputes_what_the_solver_reads() -> None:
    assert NOD.table == (2.0, 0.3, 0.0, float("inf"), 1.0, 0.2, 0.1, 0.5, 0.5, 0.4, 0.0,
                         float("inf"))  # fmt: skip
    assert NOD.positions == {"start": 0, "ready": 1, "stroke": 2, "end": 3}
    copy = pickle.loads(pickle.dumps(NOD))  # plans travel to other processes
    assert copy == NOD and copy.table == NOD.table and copy.positions == NOD.positions


def test_the_views_say_what_was_added() -> None:
    problem = Problem()
    a, b = Source("behaviour", "a"), Source("behaviour", "b")
    assert problem.add_model("a", NOD, a) == 1
    assert problem.add_model("b", FACE, b) == 5
    problem.equal(("b", "start"), 0.0, ("a", "stroke"), 0.25, b)
    problem.order(("a", "end"), 0.5, ("b", "end"), 0.0, Source("constraint", "c"))
    assert list(problem.keys) == [BLOCK_START] + [("a", s) for s in NOD.syncs] + [
        ("b", s) for s in FACE.syncs
    ]
    assert problem.starts == [("a", "start"), ("b", "start")]
    assert problem.phases == [
        (("a", "start"), ("a", "ready"), NOD.phases[0], a),
        (("a", "ready"), ("a", "stroke"), NOD.phases[1], a),
        (("a", "stroke"), ("a", "end"), NOD.phases[2], a),
        (("b", "start"), ("b", "attackPeak"), FACE.phases[0], b),
        (("b", "attackPeak"), ("b", "end"), FACE.phases[1], b),
    ]
    (tie,) = problem.equalities
    assert (tie.a, tie.ka, tie.b, tie.kb, tie.source) == (("b", "start"), 0.0, ("a", "stroke"),
                                                          0.25, b)  # fmt: skip
    (order,) = problem.orderings
    assert (order.a, order.ka, order.b, order.kb) == (("a", "end"), 0.5, ("b", "end"), 0.0)


def test_keys_known_before_their_behaviour_keep_their_place_and_their_times() -> None:
    def build(tie_first: bool) -> dict[tuple[str, str], float]:
        problem = Problem()
        tie = (("b", "start"), 0.0, ("a", "stroke"), 0.25, Source("behaviour", "b"))
        if tie_first:  # ("b", "start") and ("a", "stroke") get indices before a and b
            problem.equal(*tie)
        problem.add_model("a", NOD, Source("behaviour", "a"))
        problem.add_behaviour("b", FACE.syncs, FACE.phases, Source("behaviour", "b"))
        if not tie_first:
            problem.equal(*tie)
        return solve(problem)

    late, early = build(False), build(True)
    assert late.keys() == early.keys()
    for key, time in late.items():
        assert early[key] == pytest.approx(time, abs=1e-9), key
    assert early[("b", "start")] == pytest.approx(early[("a", "stroke")] + 0.25, abs=1e-9)


def test_a_behaviour_naming_one_sync_twice_is_still_one_chain() -> None:
    problem = Problem()
    problem.add_behaviour("a", ("start", "start"), [Phase(1.0)], Source("behaviour", "a"))
    assert list(problem.keys) == [BLOCK_START, ("a", "start")]
    assert problem._first == {} and problem._phase_a == [1] and problem._phase_b == [1]


def test_keys_are_made_when_read_and_name_every_index_once() -> None:
    # A behaviour with new keys is recorded by its first index alone; keys
    # named before their behaviour, an id added twice and a sync named twice
    # get entries of their own. keys (made on demand) and index_of must give
    # each key the index the solvers use, in index order.
    problem = Problem()
    problem.equal(("c", "end"), 0.0, BLOCK_START, 2.0, Source("fixed", "c", True))  # c unseen
    problem.add_model("a", NOD, Source("behaviour", "a"))
    problem.add_model("c", FACE, Source("behaviour", "c"))  # c:end known: not consecutive
    problem.add_model("a", FACE, Source("behaviour", "a"))  # a again: a:start, a:end shared
    problem.add_behaviour("d", ("start", "start"), [Phase(1.0)], Source("behaviour", "d"))
    problem.add_model("e", FACE, Source("behaviour", "e"))
    keys = problem.keys
    assert list(keys.values()) == list(range(problem.size)) and len(keys) == problem.size
    assert keys[("c", "end")] == 1 and keys[("a", "start")] == 2 and keys[("e", "start")] == 10
    assert [key[0] for key in keys][1:] == ["c", *"aaaa", "c", "c", "a", "d", *"eee"]
    for key, index in keys.items():
        assert problem.index_of(key) == index
    assert problem.index_of(("a", "nowhere")) is None and problem.index_of(("z", "start")) is None
    assert problem._first == {"e": 10}  # the only behaviour added with all-new keys
    # a key named after its behaviour was added gets the next index and is listed
    problem.equal(("e", "relax"), 0.0, ("e", "end"), 0.5, Source("behaviour", "e"))
    assert problem.keys[("e", "relax")] == problem.size - 1 == 13
    times = solve(problem)
    assert times[("c", "end")] == pytest.approx(2.0, abs=1e-9)
    assert list(times) == list(problem.keys)


def test_the_face_engine_plans_each_shape_once_and_keeps_a_bounded_cache(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    registry = EngineRegistry.standard()
    block = parse_bml(
        f'<bml xmlns="{BML_NS}" id="m"><head id="n1" lexeme="NOD"/><head id="n2" lexeme="SHAKE"/>'
        '<head id="n3" lexeme="NOD" repetition="3"/><faceLexeme id="f" lexeme="RAISE_BROWS"/>'
        "</bml>"
    ).block
    n1, n2, n3, f = (registry.plan(b) for b in block.behaviours)
    assert n1 is n2 and n1 is not n3 and n3.syncs[4:6] == ("stroke:2", "stroke:3")
    assert f.syncs == ("start", "attackPeak", "relax", "end")
    engine = registry.engines[0]
    assert isinstance(engine, face_module.FaceEngine)
    monkeypatch.setattr(face_module, "TIMING_CACHE", 2)
    engine._timings.clear()
    for behaviour in block.behaviours:
        registry.plan(behaviour)
    assert 1 <= len(engine._timings) <= 2
