"""Optional dependencies: which extra provides which import, and one clear error.

``pip install realizer`` gives the core (the BML parser, the scheduler, the
session, the service and its client). Rendering, charts and benchmarks need
extras (``pip install 'realizer[render]'``, ``[plots]``, ``[bench]``, or
``[all]``); pyproject.toml's ``[project.optional-dependencies]`` is the list,
and :data:`EXTRAS` below must name the same extras.

A command that needs an extra calls :func:`require` before its work starts;
the command line turns a :class:`MissingExtraError`, and any
:class:`ModuleNotFoundError` for a module of :data:`EXTRAS`, into one line::

    realizer: error: realizer render needs the 'render' extra (no module named
    'OpenGL'): pip install 'realizer[render]'

This module imports nothing heavy: the command line loads it on every start.
"""

from __future__ import annotations

import importlib.util

from realizer.errors import RealizerError

#: Extra -> the top-level import names it provides (what :func:`require` checks).
EXTRAS: dict[str, tuple[str, ...]] = {
    "render": ("OpenGL", "PIL", "tqdm"),
    "plots": ("matplotlib",),
    "bench": ("trimesh", "psutil"),
    "cluster": ("nats",),
    "stomp": ("stomp",),
}


class MissingExtraError(RealizerError, ImportError):
    """A feature needs an optional dependency that is not installed.

    ``extra`` is the name to install (``pip install 'realizer[EXTRA]'``),
    ``module`` the first missing import and ``feature`` what needed it.
    """

    def __init__(self, extra: str, module: str, feature: str) -> None:
        self.extra = extra
        self.module = module
        self.feature = feature
        super().__init__(
            f"{feature} needs the {extra!r} extra (no module named {module!r}): "
            f"pip install 'realizer[{extra}]'"
        )


def missing(extra: str) -> str | None:
    """The first import of ``extra`` that cannot be found, or None when all can."""
    for module in EXTRAS[extra]:
        if importlib.util.find_spec(module) is None:
            return module
    return None


def require(extra: str, feature: str) -> None:
    """Raise :class:`MissingExtraError` unless every import of ``extra`` is installed.

    ``feature`` says who needs it, for the message (``"realizer render"``).
    Checking finds the modules without importing them, so it costs little.
    """
    module = missing(extra)
    if module is not None:
        raise MissingExtraError(extra, module, feature)


def extra_for_module(name: str) -> str | None:
    """The extra that provides the module ``name`` (dotted or not), or None."""
    top = name.partition(".")[0]
    for extra, modules in EXTRAS.items():
        if top in modules:
            return extra
    return None


def explain(error: ModuleNotFoundError, feature: str) -> MissingExtraError | None:
    """A :class:`MissingExtraError` for ``error`` when an extra provides its module."""
    if error.name is None:
        return None
    extra = extra_for_module(error.name)
    if extra is None:
        return None
    return MissingExtraError(extra, error.name.partition(".")[0], feature)
