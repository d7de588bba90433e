"""The default face: the head of the CC0 MakeHuman base mesh, rigged for MPEG-4.

The files live in ``realizer/face/data/default_face/`` (``default_face.npz``
and ``default_face.xml``, the face file pair of :mod:`realizer.face.paramfile`;
``ORIGIN.md`` and ``LICENSE.md`` say where they come from: MakeHuman hm08,
CC0 1.0). ``scripts/extract_default_face.py`` made them and reproduces them.

Feature points of Tekalp and Ostermann 2000, Table 6 are placed on it (all but 11.5, hair
thickness: the head has no hair), and FAPs 3..68 have deformation settings
in the face parameter format of Paul 2010, Appendix C.
"""

from __future__ import annotations

from functools import cache
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from realizer.face.model import Face

__all__ = ["DEFAULT_FACE_STEM", "default_face_path", "load_default_face"]

#: File stem of the default face inside the package data directory.
DEFAULT_FACE_STEM = "default_face"


def default_face_path() -> Path:
    """The stem path (without .npz/.xml) of the shipped default face."""
    root = resources.files("realizer.face").joinpath("data", "default_face")
    return Path(str(root)) / DEFAULT_FACE_STEM


@cache
def load_default_face() -> Face:
    """Load the default face once per process (Faces are immutable)."""
    from realizer.face.paramfile import load_face

    return load_face(default_face_path())
