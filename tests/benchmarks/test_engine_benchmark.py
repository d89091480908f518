"""The engine benchmark still runs and prints measured figures (its speed is not asserted)."""

import re
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import engine as engine_benchmark


def test_engine_benchmark_prints_rates_and_ratios(capsys: pytest.CaptureFixture[str]) -> None:
    code = engine_benchmark.main(["--quick", "--models", "inverse_square", "--robots", "1,15"])
    out = capsys.readouterr().out
    assert code == 0
    rows = re.findall(r"^inverse_square\s+(\d+)\s+([\d,]+)\s+([\d,]+)\s+([\d,]+)x$", out, re.M)
    assert [int(r[0]) for r in rows] == [1, 15]
    for _, rate, naive, _ in rows:
        assert int(rate.replace(",", "")) > 0 and int(naive.replace(",", "")) > 0
    assert "target: inverse_square, 15 robots, ratio" in out
    # the active Brownian physics is measured beside the lattice in the same run
    brownian = re.findall(r"^active_brownian, (\w+)\s+15\s+([\d,]+)\s+([\d.]+)$", out, re.M)
    assert {policy for policy, _, _ in brownian} == {"q_learning", "run_and_tumble", "gradient"}
    assert all(int(rate.replace(",", "")) > 0 for _, rate, _ in brownian)
