"""The cost benchmark still runs and prints a row per scenario (its figures are not asserted)."""

import re
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import cost as cost_benchmark


def test_cost_benchmark_prints_seconds_per_unit_for_every_scenario(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert cost_benchmark.main(["--quick"]) == 0
    out = capsys.readouterr().out
    for label, _ in cost_benchmark.SPREAD:
        row = re.search(rf"^{re.escape(label)}\s+\d+\s+[\d,]+\s+\d+\s+[\d,]+\s+[\d,]+\s+[\d,]+"
                        r"\s+(\d+\.\d\d)\s+\d+%", out, re.M)  # fmt: skip
        assert row is not None, label
        assert float(row.group(1)) > 0
    assert re.search(r"ratio \d+\.\d\d", out)
    assert re.search(r"suggested: \de\+\d\d", out)
