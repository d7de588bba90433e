"""Parse-and-serialise throughput of the BML parser against bare lxml.

For the conformance corpus plus the examples, and for one block of 5,000
behaviours, this times ``serialise(parse_bml(doc))`` (an unchanged parsed
block is given back as its source text), the same with the tree written
again (``from_source=False``, what a changed block costs) and, as the baseline,
``lxml.etree.tostring(lxml.etree.fromstring(doc))`` with the same hardened
parser settings; it prints documents per second, MB/s and the ratio of our
throughput to lxml's (goal: at least 1/3).

It also prints a floor: lxml's parse plus a Python loop that merely touches
every element's tag, attributes, text, tail and line, which any pure-Python
tree built from lxml must pay; its ratio bounds what the parser can reach.

And, when the Java reference parser of the BML community (saiba/OpenBMLParser)
is built (``bash scripts/build_openbml.sh``; found in ``.cache/openbml`` or
where ``REALIZER_OPENBML`` names) and ``java`` runs, the same documents
through ``BehaviourBlock.readXML`` + ``toXMLString`` after JIT warm-up
(benchmarks/java/OpenBmlBench.java), in the same run, on the documents both
parsers accept; goal: the ratio realizer/Java at least 1. Without a built
reference that column is skipped with the reason.

The first lines say whether the parser's hot modules run compiled (mypyc,
``scripts/build_compiled.py``) or as Python (``REALIZER_PURE=1`` times the
sources where the extensions are built).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from lxml import etree

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _timing import figure, skipped

from realizer import compiled
from realizer.bml_parser import BML_NS, parse_bml, serialise
from realizer.bml_parser.reader import _BYTES_PARSER

ROOT = Path(__file__).resolve().parents[1]


def corpus() -> list[bytes]:
    return [data for _, data in corpus_files()]


def corpus_files() -> list[tuple[Path, bytes]]:
    """The examples and ``REALIZER_BML_CORPUS``'s documents that the parser accepts."""
    paths = sorted((ROOT / "examples" / "bml").glob("*.xml"))
    # more BML from elsewhere (for example a conformance corpus): a folder of
    # .xml files named by REALIZER_BML_CORPUS, its subfolders included (the
    # shared corpus keeps each source's documents in a folder of their own)
    extra = os.environ.get("REALIZER_BML_CORPUS")
    if extra and Path(extra).is_dir():
        paths += sorted(Path(extra).rglob("*.xml"))
    documents = []
    for path in paths:
        data = path.read_bytes()
        try:
            parse_bml(data)
        except Exception:
            continue  # the deliberately broken ones
        documents.append((path, data))
    return documents


def java_classpath() -> tuple[str | None, str]:
    """The reference parser's classpath, or None and why it is not available."""
    where = Path(os.environ.get("REALIZER_OPENBML", ROOT / ".cache" / "openbml"))
    listing = where / "classpath"
    if not listing.is_file():
        return None, f"no built reference parser in {where} (bash scripts/build_openbml.sh)"
    if shutil.which("java") is None:
        return None, "no java on PATH"
    # the listing names the folder it was built in; read it against ``where``
    # (a copied or linked .cache would otherwise run another tree's classes)
    jars = [
        Path(entry).name for entry in listing.read_text().strip().split(os.pathsep)[1:] if entry
    ]
    classpath = os.pathsep.join(
        [str(where / "classes"), *(str(where / "lib" / jar) for jar in jars)]
    )
    harness = ROOT / "benchmarks" / "java" / "OpenBmlBench.java"
    built = where / "classes" / "OpenBmlBench.class"
    if shutil.which("javac") and (
        not built.is_file() or built.stat().st_mtime < harness.stat().st_mtime
    ):
        # the harness changed since the reference was built: compile it alone
        subprocess.run(
            ["javac", "-nowarn", "-implicit:none", "-sourcepath", "/nonexistent", "-d",
             str(where / "classes"), "-cp",
             classpath, str(harness)],
            check=True, capture_output=True, timeout=120,
        )  # fmt: skip
    return classpath, ""


def java_pass(classpath: str, paths: list[Path], seconds: float) -> dict[str, object]:
    """Run the Java harness on ``paths``: its accepted indices and best seconds per pass."""
    done = subprocess.run(
        ["java", "-cp", classpath, "OpenBmlBench", str(seconds), *map(str, paths)],
        capture_output=True,
        text=True,
        timeout=120 + 4 * seconds,
        check=True,
    )
    result: dict[str, object] = json.loads(done.stdout.strip().splitlines()[-1])
    missing = {"accepted", "seconds_per_pass", "cpu_seconds_per_pass"} - result.keys()
    if missing:
        raise RuntimeError(
            f"the Java harness printed no {', '.join(sorted(missing))}: an old build of it? "
            "(bash scripts/build_openbml.sh)"
        )
    return result


def big_block(behaviours: int) -> bytes:
    lines = [f'<bml xmlns="{BML_NS}" id="big">']
    for i in range(behaviours):
        kind = i % 4
        if kind == 0:
            lines.append(f'  <head id="h{i}" lexeme="NOD" start="{i * 0.1:.1f}"/>')
        elif kind == 1:
            lines.append(f'  <gesture id="g{i}" lexeme="BEAT" stroke="h{i - 1}:stroke+0.2"/>')
        elif kind == 2:
            lines.append(
                f'  <faceLexeme id="f{i}" lexeme="RAISE_BROWS" amount="0.5" '
                f'start="g{i - 1}:start" end="g{i - 1}:end+1"/>'
            )
        else:
            lines.append(
                f'  <speech id="s{i}" start="f{i - 1}:relax"><text>Hello <sync id="a"/>'
                "there, world.</text></speech>"
            )
    lines.append("</bml>")
    return "\n".join(lines).encode()


def best_within(
    function: Callable[[], object], seconds: float, repeats: int
) -> tuple[float, float]:
    """The best wall time and the best CPU time of one call, over at least
    ``repeats`` calls and ``seconds``.

    The same method as the Java harness (the best of rounds over a few
    seconds): on a shared machine, a few repeats of a 60 ms call may all
    land in busy moments, and the two sides would not be compared alike.
    CPU time (this process's) is what a busy machine disturbs least.
    """
    best = best_cpu = float("inf")
    count = 0
    end = time.perf_counter() + seconds
    while count < repeats or time.perf_counter() < end:
        start = time.perf_counter()
        cpu = time.process_time()
        function()
        best_cpu = min(best_cpu, time.process_time() - cpu)
        best = min(best, time.perf_counter() - start)
        count += 1
    return best, best_cpu


def measure(
    name: str,
    documents: list[bytes],
    repeats: int,
    java_seconds: float | None = None,
    seconds: float = 0.0,
    java_cpu: float | None = None,
) -> None:
    """Realizer, lxml and floor on ``documents``; ``java_seconds``: the Java
    reference's best seconds per pass over the same documents, when measured."""
    size = sum(len(d) for d in documents)

    def ours() -> None:
        for document in documents:
            serialise(parse_bml(document).block)

    def written() -> None:
        for document in documents:
            serialise(parse_bml(document).block, from_source=False)

    def bare() -> None:
        for document in documents:
            etree.tostring(etree.fromstring(document, _BYTES_PARSER))

    def floor() -> None:
        for document in documents:
            for el in etree.fromstring(document, _BYTES_PARSER).iter():
                (el.tag, tuple(el.attrib.items()), el.text, el.tail, el.sourceline)

    t_ours, cpu_ours = best_within(ours, seconds, repeats)
    t_written, cpu_written = best_within(written, seconds, repeats)
    t_lxml, _ = best_within(bare, seconds, repeats)
    t_floor, _ = best_within(floor, seconds, repeats)
    print(
        f"{name}: {len(documents)} documents, {size / 1e3:.1f} kB\n"
        f"  realizer parse+serialise: {t_ours * 1e3:8.2f} ms  "
        f"({len(documents) / t_ours:9.0f} docs/s, {size / t_ours / 1e6:6.2f} MB/s)\n"
        f"  realizer parse+writer:    {t_written * 1e3:8.2f} ms  "
        f"({len(documents) / t_written:9.0f} docs/s; the tree written again, as for a "
        "changed block)\n"
        f"  lxml parse+tostring:      {t_lxml * 1e3:8.2f} ms  "
        f"({len(documents) / t_lxml:9.0f} docs/s, {size / t_lxml / 1e6:6.2f} MB/s)\n"
        f"  floor (lxml parse + touching every element from Python): {t_floor * 1e3:.2f} ms"
    )
    figure(f"{name}: realizer parse+serialise", len(documents) / t_ours, "docs/s")
    figure(f"{name}: realizer parse+writer (changed block)", len(documents) / t_written,
           "docs/s")  # fmt: skip
    figure(f"{name}: lxml parse+tostring", len(documents) / t_lxml, "docs/s")
    figure(f"{name}: ratio realizer/lxml", t_lxml / t_ours, "x", goal=1 / 3, higher_is_better=True)
    figure(f"{name}: ratio floor/lxml", t_lxml / t_floor, "x")
    if java_seconds is not None:
        figure(f"{name}: Java reference readXML+toXMLString", len(documents) / java_seconds,
               "docs/s")  # fmt: skip
        figure(f"{name}: ratio realizer/Java", java_seconds / t_ours, "x", goal=1.0,
               higher_is_better=True)  # fmt: skip
        figure(f"{name}: ratio realizer parse+writer/Java", java_seconds / t_written, "x")
    if java_cpu is not None:
        figure(f"{name}: ratio realizer/Java, CPU time", java_cpu / cpu_ours, "x", goal=1.0,
               higher_is_better=True)  # fmt: skip
        figure(f"{name}: ratio realizer parse+writer/Java, CPU time", java_cpu / cpu_written,
               "x")  # fmt: skip


def run(quick: bool = False) -> None:
    repeats = 3 if quick else 7
    # per figure: as long as the Java harness measures (its warm-up aside)
    budget = 1.0 if quick else 3.0
    files = corpus_files()
    big = big_block(5000)
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    # compiled (mypyc, scripts/build_compiled.py) or pure Python (REALIZER_PURE=1)
    print(f"parser modules: {compiled.describe()}")
    classpath, reason = java_classpath()
    if classpath is None:
        skipped("ratio realizer/Java", reason)
        measure("corpus + examples", [data for _, data in files], repeats, seconds=budget)
        measure("one block of 5,000 behaviours", [big], repeats, seconds=budget)
        return
    seconds = 2.0 if quick else 6.0
    with tempfile.TemporaryDirectory() as folder:
        big_path = Path(folder) / "big.xml"
        big_path.write_bytes(big)
        java = java_pass(classpath, [path for path, _ in files], seconds)
        java_big = java_pass(classpath, [big_path], seconds)
    accepted = set(java["accepted"])  # type: ignore[arg-type]
    both = [data for index, (_, data) in enumerate(files) if index in accepted]
    print(
        f"the Java reference refuses {len(files) - len(both)} of the {len(files)} documents "
        "the realizer accepts; both are timed on the other ones"
    )
    measure("corpus + examples", both, repeats, float(java["seconds_per_pass"]), budget,  # type: ignore[arg-type]
            float(java["cpu_seconds_per_pass"]))  # type: ignore[arg-type]  # fmt: skip
    measure("one block of 5,000 behaviours", [big], repeats,
            float(java_big["seconds_per_pass"]), budget,  # type: ignore[arg-type]
            float(java_big["cpu_seconds_per_pass"]))  # type: ignore[arg-type]  # fmt: skip
    print(f"load average {os.getloadavg()[0]:.2f} at the end")


if __name__ == "__main__":
    run(quick="--quick" in sys.argv)
