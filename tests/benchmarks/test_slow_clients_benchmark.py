"""The slow-clients benchmark still runs end to end and counts what it opened and what was cut."""

import re
import shutil
import sys
from pathlib import Path

import pytest

from tests.conftest import in_ci

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import slow_clients as slow_clients_benchmark

pytestmark = pytest.mark.timeout(120)
FIGURES = re.compile(r"^  GET /(?:jobs/\{id\}|healthz) +p50 +([\d.]+) +p95 +([\d.]+) +p99 +"
                     r"([\d.]+) ms +(\d+) answers +(\d+) non-2xx +(\d+) errors$", re.M)  # fmt: skip


def test_slow_clients_benchmark_prints_latencies_and_what_is_left_open(
    capsys: pytest.CaptureFixture[str],
) -> None:
    if shutil.which("wrk") is None:
        if in_ci():
            pytest.fail("wrk must be installed in CI; .ci/run installs it")
        pytest.skip("wrk is not installed (apt-get install wrk)")
    common = ["--slow-headers", "20", "--streams", "30", "--addresses", "2", "--wrk-s", "1",
              "--hold-s", "2.5", "--api-env", "NANONAV_EVENTS_STREAMS_PER_KEY=10"]  # fmt: skip
    # A head timeout of 1 s cuts the slow headers within the hold; the streams are measured
    # under the default, as a client of a loaded machine may take a second to send its head.
    headers = ["--parts", "headers", "--api-env", "NANONAV_API_HEADER_TIMEOUT_S=1"]
    assert slow_clients_benchmark.main([*headers, *common]) == 0
    assert slow_clients_benchmark.main(["--parts", "streams", *common]) == 0
    out = capsys.readouterr().out
    assert "0 of 20 still open after 2.5 s; answers they got: 408" in out, out
    assert "answered: 20 200, 10 503; 20 open while measured" in out, out
    figures = FIGURES.findall(out)
    assert len(figures) == 4, out
    for p50, p95, p99, answers, non_2xx, errors in figures:
        assert 0 < float(p50) <= float(p95) <= float(p99)
        assert int(answers) > 0 and int(non_2xx) == 0 and int(errors) == 0
