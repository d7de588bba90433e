"""Build the API reference (HTML) from the docstrings with pdoc.

    .venv/bin/python scripts/build_api_docs.py            # into out/api/
    .venv/bin/python scripts/build_api_docs.py -o DIR

Open ``out/api/index.html``. The docstrings are reStructuredText. Every warning
pdoc gives (an annotation it cannot resolve, a name in ``__all__`` that does
not exist) fails the build, so the reference stays complete;
tests/test_api_docs.py runs it.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def resolve_lazy_exports(package: str) -> None:
    """Import the names a package exports lazily (``__getattr__``) so pdoc sees them."""
    module = importlib.import_module(package)
    for name in getattr(module, "__all__", ()):
        getattr(module, name)


def build(output: Path) -> list[str]:
    """Write the reference into ``output``; return pdoc's warnings (empty when clean)."""
    import pdoc
    import pdoc.render

    sys.path.insert(0, str(ROOT))
    # from the sources, whatever is compiled: pdoc reads signatures and
    # annotations of Python functions (realizer/compiled.py)
    os.environ["REALIZER_PURE"] = "1"
    resolve_lazy_exports("realizer.face")
    pdoc.render.configure(docformat="restructuredtext", show_source=False)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pdoc.pdoc("realizer", output_directory=output)
    return [str(w.message) for w in caught]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Build the API reference with pdoc.")
    parser.add_argument("-o", "--output", type=Path, default=ROOT / "out" / "api")
    args = parser.parse_args(argv)
    problems = build(args.output)
    for problem in problems:
        print(f"build_api_docs: warning: {problem}", file=sys.stderr)
    if problems:
        return 1
    print(f"API reference: {args.output / 'index.html'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
