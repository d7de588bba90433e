"""The engine registry: which engine plans and realizes each behaviour.

Engines own timing knowledge (docs/architecture.md). Each engine says
which behaviours it handles, gives a :class:`~realizer.scheduler.timing.TimingModel`
for each (its sync points in canonical order, preferred durations, costs and
bounds) and, once the scheduler has solved the times, realizes the behaviour
as an :class:`~realizer.face.animation.Animation` (or nothing, for behaviours
no body part shows). The registry is what the scheduler is handed as its
planner (:class:`realizer.scheduler.plan.Planner`); the scheduler never
imports an engine and never special-cases a behaviour type.
"""

from __future__ import annotations

import itertools
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cache
from importlib import resources
from typing import Any, Protocol

from realizer.bml_parser import Behaviour
from realizer.engines.default import DefaultEngine
from realizer.scheduler.timing import Phase, TimingModel


class Engine(Protocol):
    def handles(self, behaviour: Behaviour) -> bool: ...
    def plan(self, behaviour: Behaviour) -> TimingModel: ...
    def realize(self, behaviour: Behaviour, times: Mapping[str, float]) -> Any: ...


@dataclass(slots=True)
class EngineRegistry:
    """Engines in priority order; the default engine answers for the rest."""

    engines: list[Engine] = field(default_factory=list)
    default: DefaultEngine = field(default_factory=DefaultEngine)

    @classmethod
    def standard(cls) -> EngineRegistry:
        """The face engine, the speech engine and the default engine."""
        from realizer.engines.face import FaceEngine
        from realizer.engines.speech import SpeechEngine

        return cls([FaceEngine.default(), SpeechEngine.default()])

    def engine_for(self, behaviour: Behaviour) -> Engine:
        for engine in self.engines:
            if engine.handles(behaviour):
                return engine
        return self.default

    def prepare(self, behaviour: Behaviour) -> None:
        """Do the slow work of planning ``behaviour`` ahead, off the clock.

        An engine may have ``prepare(behaviour)``: work whose result it keeps
        for :meth:`plan` and that does not depend on time (the speech engine
        synthesises the speech). A live service calls this before it reads
        the clock for a block, so that a block whose speech takes long to
        synthesise is timed from when its audio is ready (docs/speech.md).
        """
        prepare = getattr(self.engine_for(behaviour), "prepare", None)
        if prepare is not None:
            prepare(behaviour)

    def plan(self, behaviour: Behaviour) -> TimingModel:
        model = self.engine_for(behaviour).plan(behaviour)
        if model.syncs != behaviour.syncs:
            # The scheduler addresses sync points by the parser's names.
            model = _align(model, behaviour.syncs)
        return model

    def plan_plain(self, behaviour: Behaviour) -> TimingModel:
        """The default engine's model, for a behaviour its own engine cannot plan."""
        return self.default.plan(behaviour)

    def notes(self, behaviour: Behaviour) -> tuple[str, ...]:
        """What the behaviour's engine has to say about how it planned it (for warnings)."""
        notes = getattr(self.engine_for(behaviour), "notes", None)
        return tuple(notes(behaviour)) if notes is not None else ()

    def realize(self, behaviour: Behaviour, times: Mapping[str, float]) -> Any:
        return self.engine_for(behaviour).realize(behaviour, times)

    def channels(self, behaviour: Behaviour) -> frozenset[str]:
        """The resource channels the behaviour needs for itself (data/channels.toml)."""
        by_type, by_lexeme = _channels()
        lexeme = (behaviour.lexeme or "").upper()
        found = by_lexeme.get((behaviour.type, lexeme))
        return found if found is not None else by_type.get(behaviour.type, frozenset())

    @property
    def fap_limits(self) -> Any:
        """The face engine's FAP limits (for the mixer), or None without a face engine."""
        from realizer.face.tracks import FapLimits

        for engine in self.engines:
            limits = getattr(engine, "limits", None)
            if isinstance(limits, FapLimits):
                return limits
        return None


@cache
def _channels() -> tuple[dict[str, frozenset[str]], dict[tuple[str, str], frozenset[str]]]:
    """(type -> channels, (type, lexeme) -> channels), loaded once."""
    text = resources.files("realizer.engines").joinpath("data/channels.toml").read_text("utf-8")
    raw: dict[str, Any] = tomllib.loads(text)
    by_type = {kind: frozenset(names) for kind, names in raw["channels"].items()}
    by_lexeme = {
        (kind, lexeme): frozenset(names)
        for kind, table in raw.get("lexemes", {}).items()
        for lexeme, names in table.items()
    }
    return by_type, by_lexeme


def _align(model: TimingModel, syncs: tuple[str, ...]) -> TimingModel:
    """Re-express a model over ``syncs`` (phases spanning missing points merge)."""
    offsets = model.preferred_offsets()
    known = [s for s in syncs if s in offsets]
    phases = []
    for before, after in itertools.pairwise(syncs):
        if before in offsets and after in offsets:
            phases.append(Phase(max(0.0, offsets[after] - offsets[before])))
        else:
            phases.append(Phase(0.3 if known else 1.0))
    return TimingModel(syncs, tuple(phases))
