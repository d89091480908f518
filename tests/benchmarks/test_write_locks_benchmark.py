"""The write-lock benchmark still runs and prints each scenario's holds (not asserted on)."""

import re
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import write_locks as write_locks_benchmark


def test_write_locks_benchmark_prints_the_share_of_time_the_lock_is_held(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert write_locks_benchmark.main(["--quick"]) == 0
    out = capsys.readouterr().out
    for name in write_locks_benchmark.SCENARIOS:
        assert re.search(
            rf"^{name}\s+BEGIN IMMEDIATE \[MainThread\][^\n]*\s\d+\s+\d+\.\d\d$", out, re.M
        )
        held = re.search(rf"^{name}\s+write lock held [\d.]+ ms of [\d.]+ s: ([\d.]+)%", out, re.M)
        assert held is not None and 0 < float(held.group(1)) < 100, out
