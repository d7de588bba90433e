"""Imported by the planner processes' fork server before it forks a child.

Imports what planning needs (the parser, the session, the engines, the
solver with its scipy) and plans one small block of the common behaviours
with the standard engines, so the tables and caches the engines load on
first use are loaded once, in the fork server, and every child forked from
it starts warm (realizer.service.planner). Failures are logged and
ignored: a child then loads what it needs itself.

No threads are started here (the fork server forks; a thread would not
survive it) and no speech is synthesised (the TTS backend is the child's).
"""

from __future__ import annotations

import logging


def warm_up() -> None:
    """Load what planning loads on first use (a benchmark calls it too, so
    that it times messages, not imports)."""
    from realizer.scheduler import solver
    from realizer.service import planner  # noqa: F401  (the child's code)
    from realizer.session import Session

    solver.warm_up()
    session = Session("warm-up")
    ns = "http://www.bml-initiative.org/bml/bml-1.0"
    session.receive_bml(
        f'<bml xmlns="{ns}" id="warm"><faceLexeme id="f" lexeme="RAISE_BROWS" start="0" '
        'end="1"/><head id="h" lexeme="NOD" start="f:end"/><gaze id="g" target="LEFT" '
        'start="0" end="1"/><faceFacs id="a" au="12" start="0.2" end="0.8"/></bml>',
        0.0,
    )


try:
    warm_up()
except Exception:  # a warm-up is an optimisation: never stop the fork server
    logging.getLogger("realizer.service").exception("planner warm-up failed")
