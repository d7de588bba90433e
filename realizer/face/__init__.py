"""MPEG-4 facial animation: FAP table, FAPU, feature points, face model, deformation.

Sources: Tekalp and Ostermann, "Face and 2-D mesh animation in MPEG-4" (2000),
section 2.1 and Annex: FAPs, feature points, FAPU, FaceDefMesh/FaceDefTransform;
and Paul, "Realization and high level specification of facial expressions for
embodied agents" (2010), chapter 4: FaceEditor's deformers, vertex masks, rigid
jaw, eyes and neck, the parameter XML. See docs/references.md.

The public names are imported lazily, so ``import realizer.face`` stays cheap:

* :data:`FAP_TABLE`, :class:`FapInfo`, :func:`fap` -- :mod:`realizer.face.faps`
* :class:`Fapu` -- :mod:`realizer.face.fapu`
* :class:`FapFrame` -- :mod:`realizer.face.frame`
* :class:`Face`, :class:`FaceParameters` -- :mod:`realizer.face.model`
* :class:`FaceRig`, :func:`rig_for` -- :mod:`realizer.face.deform`; the function
  ``deform`` itself is imported from there (``from realizer.face.deform import
  deform``): the package attribute ``deform`` is that submodule
* :func:`load_default_face` -- :mod:`realizer.face.default` (the MakeHuman head)
* :func:`load_face`, :func:`save_face` -- :mod:`realizer.face.paramfile`
* :func:`build_test_head` -- :mod:`realizer.face.testhead`
* :func:`load_default_face` -- :mod:`realizer.face.default`
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "FAP_TABLE": "faps",
    "FapInfo": "faps",
    "fap": "faps",
    "Fapu": "fapu",
    "FapFrame": "frame",
    "Face": "model",
    "FaceParameters": "model",
    "FaceRig": "deform",
    "rig_for": "deform",
    "load_default_face": "default",
    "load_face": "paramfile",
    "save_face": "paramfile",
    "build_test_head": "testhead",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'realizer.face' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"realizer.face.{module}"), name)
    globals()[name] = value  # resolved once; later lookups skip this function
    return value
