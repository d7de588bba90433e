"""Write the browser viewer's one-click examples from ``examples/bml/``.

    python scripts/viewer_examples.py

Writes ``realizer/service/static/examples.json``: a list of ``{"title",
"file", "bml"}``, one per example (the XML comment that opens each file is
dropped; the BML itself is unchanged). Run it after changing the examples.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "realizer/service/static/examples.json"


def main() -> int:
    examples = []
    for path in sorted((ROOT / "examples/bml").glob("*.xml")):
        text = path.read_text(encoding="utf-8")
        text = re.sub(r"^<\?xml[^>]*\?>\s*", "", text)
        text = re.sub(r"^<!--.*?-->\s*", "", text, flags=re.S)
        title = re.sub(r"^\d+_", "", path.stem).replace("_", " ")
        examples.append({"title": title, "file": f"examples/bml/{path.name}", "bml": text.strip()})
    OUT.write_text(json.dumps(examples, indent=1) + "\n", encoding="utf-8")
    print(f"{OUT}: {len(examples)} examples")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
