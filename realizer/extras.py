"""Optional dependencies: which extra provides which import, and one clear error.

``pip install realizer`` gives the core, small enough for a dialogue manager
that only talks to a realizer: the BML parser, the session, the Python
client (:mod:`realizer.client`) and the command line. Everything with a
heavy dependency is an extra: ``[serve]`` (the service: scipy for the face's
mesh deformation and the scheduler's sparse solver), ``[schedule]`` (scipy
for the scheduler's sparse path: blocks of more than 160 sync points),
``[render]``, ``[plots]``, ``[bench]``, ``[cluster]``, ``[stomp]`` or
``[all]``. pyproject.toml's ``[project.optional-dependencies]`` is the
list, and :data:`EXTRAS` below must name the same extras.

Several extras bring scipy; a command names the one that fits it
(:data:`COMMAND_EXTRAS`), and a module that needs scipy (at import time,
or the solver when a block takes the sparse path) raises
:class:`MissingExtraError` through :func:`missing_module` instead of a bare
:class:`ModuleNotFoundError`.

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
    "serve": ("scipy",),
    "schedule": ("scipy",),
    "render": ("OpenGL", "PIL", "tqdm", "scipy"),
    "plots": ("matplotlib", "scipy"),
    "bench": ("trimesh", "psutil", "scipy"),
    "cluster": ("nats", "scipy"),
    "stomp": ("stomp",),
}

#: Command -> the extra to name when that command misses a module which
#: several extras provide (scipy: ``realizer serve`` says ``[serve]``).
COMMAND_EXTRAS: dict[str, str] = {
    "schedule": "schedule",
    "faps": "schedule",
    "serve": "serve",
    "worker": "cluster",
    "gateway": "cluster",
    "render": "render",
    "face": "render",
    "fap-sheet": "render",
    "expressions": "render",
    "plot": "plots",
    "plot-faps": "plots",
    "bench": "bench",
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


def extra_for_module(name: str, prefer: str | None = None) -> str | None:
    """The extra that provides the module ``name`` (dotted or not), or None.

    ``prefer`` (an extra) wins when it provides the module too.
    """
    top = name.partition(".")[0]
    if prefer is not None and top in EXTRAS.get(prefer, ()):
        return prefer
    for extra, modules in EXTRAS.items():
        if top in modules:
            return extra
    return None


def explain(
    error: ImportError, feature: str, command: str | None = None
) -> MissingExtraError | None:
    """A :class:`MissingExtraError` for ``error`` when an extra provides its module.

    ``command`` (``"serve"``) picks the extra :data:`COMMAND_EXTRAS` gives it
    among those that provide the module; a :class:`MissingExtraError` raised
    by a module (:func:`missing_module`) is named again for the command.
    """
    name = error.module if isinstance(error, MissingExtraError) else error.name
    if name is None or not isinstance(error, ModuleNotFoundError | MissingExtraError):
        return None
    prefer = COMMAND_EXTRAS.get(command) if command is not None else None
    extra = extra_for_module(name, prefer)
    if extra is None:
        return None
    return MissingExtraError(extra, name.partition(".")[0], feature)


def missing_module(error: ModuleNotFoundError, extra: str, feature: str) -> ImportError:
    """What a module raises when an import it cannot do without fails.

    A :class:`MissingExtraError` naming ``extra`` when ``error`` is about one
    of its modules, else ``error`` itself (a broken install is not a missing
    extra)::

        try:
            import scipy.sparse as sp
        except ModuleNotFoundError as error:
            raise missing_module(error, "schedule", "realizer.scheduler") from error
    """
    top = (error.name or "").partition(".")[0]
    if top in EXTRAS[extra]:
        return MissingExtraError(extra, top, feature)
    return error
