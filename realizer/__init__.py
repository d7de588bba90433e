"""A real-time BML 1.0 realizer.

Embodied conversational agents, dialogue managers and SAIBA behaviour planners
send Behavior Markup Language; the realizer parses it (:mod:`realizer.bml_parser`),
schedules every sync point (:mod:`realizer.scheduler`), turns face, head and gaze
behaviours into MPEG-4 facial animation (:mod:`realizer.face`) and streams frames
to remote viewers (:mod:`realizer.service`).
"""

from __future__ import annotations

__version__ = "0.1.0"

# Compiled modules (mypyc) run only when built from the present sources;
# otherwise their Python sources do (realizer/compiled.py).
from realizer import compiled as _compiled

_compiled.select()
