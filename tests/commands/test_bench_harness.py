"""The benchmarks' own harness: what it starts keeps working under load."""

from __future__ import annotations

import sys
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from realizer.commands import bench


def test_a_server_started_by_the_service_benchmark_never_blocks_on_its_log(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Regression: ``bench_service.start_server`` read the server's stderr
    only up to its start line, so a server that logged more than a pipe
    holds (64 kB: one line per connection, at 10 x 100 and 50 x 200) froze
    in its log writes and the benchmark timed out. ~130 kB of refused
    handshakes are logged here; the server must still answer."""
    monkeypatch.setattr(sys, "path", [str(bench.benchmarks_dir()), *sys.path])
    import bench_service

    process, port = bench_service.start_server(60.0, [])
    try:
        for _ in range(40):
            with pytest.raises(urllib.error.HTTPError) as refused:  # 426: not a handshake
                urllib.request.urlopen(
                    f"http://127.0.0.1:{port}/view?character={'x' * 3000}", timeout=10
                )
            refused.value.close()
        assert bench_service.health(port)["status"] == "ok"
    finally:
        bench_service.stop_server(process)


def test_the_parser_benchmark_reads_the_reference_from_where_it_is(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """Regression: the built reference's listing names the folder it was
    built in; a ``.cache`` copied or linked from another checkout ran that
    checkout's old harness (no ``cpu_seconds_per_pass``) and the bench died
    with a KeyError. The classpath is now read against the folder it is in,
    and a harness that prints too little is named."""
    monkeypatch.setattr(sys, "path", [str(bench.benchmarks_dir()), *sys.path])
    import bench_parser

    where = tmp_path / "openbml"
    (where / "classes").mkdir(parents=True)
    (where / "lib").mkdir()
    (where / "classpath").write_text(
        "/elsewhere/openbml/classes:/elsewhere/openbml/lib/a.jar:/elsewhere/openbml/lib/b.jar:\n"
    )
    monkeypatch.setenv("REALIZER_OPENBML", str(where))
    monkeypatch.setattr(
        bench_parser.shutil, "which", lambda name: None if name == "javac" else name
    )
    classpath, reason = bench_parser.java_classpath()
    assert reason == ""
    assert classpath == ":".join(
        [str(where / "classes"), str(where / "lib" / "a.jar"), str(where / "lib" / "b.jar")]
    )

    class Done:
        stdout = '{"documents": 1, "accepted": [0], "seconds_per_pass": 0.001}\n'

    monkeypatch.setattr("subprocess.run", lambda *args, **kwargs: Done())
    with pytest.raises(RuntimeError, match="cpu_seconds_per_pass"):
        bench_parser.java_pass("cp", [tmp_path / "x.xml"], 0.1)
