"""The API memory soak still runs, samples the API's memory each round and sees no 5xx."""

import re
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import api_memory as api_memory_benchmark

pytestmark = pytest.mark.timeout(300)


def test_api_memory_benchmark_samples_every_round_without_a_server_error(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert api_memory_benchmark.main(["--quick"]) == 0
    out = capsys.readouterr().out
    rows = re.findall(r"^\s*(\d+)\s+(\d+)\s+(\d+)\s+(\d+)\s+(\d+\.\d)$", out, re.M)
    assert [int(row[0]) for row in rows] == [0, 1, 2, 3], out
    assert all(int(row[3]) == 0 for row in rows), "a fuzzed request got a 5xx"
    assert all(float(row[4]) > 50 for row in rows)
    assert re.search(r"^API RSS: [\d.]+ MB at the start, [\d.]+ MB at most; growth", out, re.M)
