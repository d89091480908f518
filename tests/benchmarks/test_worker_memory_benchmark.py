"""The worker memory benchmark runs a job of each kind on a real worker and prints its memory
after each (its size is not asserted here: the figure lives in the benchmark)."""

import re
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import worker_memory

pytestmark = pytest.mark.timeout(600)


def test_worker_memory_benchmark_prints_the_workers_memory_after_each_job(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert worker_memory.main() == 0
    out = capsys.readouterr().out
    rows = re.findall(r"^  (.+?)\s+(\d+)\s+(\d+)$", out, re.M)
    assert [label for label, _, _ in rows] == [
        "ready, no job yet",
        "first job: paper-single, seed 7",
        "tumour-microswimmers",
        "a sent network's evaluation",
        "a study of four jobs",
    ], out
    for _, now, peak in rows:
        # a worker that holds the engine holds more than Python alone; its peak is a peak
        assert 100 <= int(now) <= int(peak)
    assert re.search(r"^(meets|BELOW) target: \d+ MB after the first job vs 600 MB$", out, re.M)
