"""The benchmarks' own harness: what it starts keeps working under load."""

from __future__ import annotations

import sys
import urllib.error
import urllib.request

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
