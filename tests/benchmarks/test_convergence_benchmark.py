"""benchmarks/convergence.py runs and prints, for each sensor, rule and radius, the share that
reaches the cell at three time steps, the paired change from dt to dt/4 and whether it holds
(its figures live in the benchmark)."""

import re
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import convergence


def test_convergence_prints_every_row_with_its_verdict(capsys: pytest.CaptureFixture[str]) -> None:
    assert convergence.main(["--quick"]) == 0
    out = capsys.readouterr().out
    rows = re.findall(
        r"^  (each_step|counted)\s+2 um\s+(\w+)\s+(?:\d\.\d\d \[\d\.\d\d, \d\.\d\d\]\s+){3}"
        r"[+-]\d\.\d\d \[[+-]\d\.\d\d, [+-]\d\.\d\d\]\s+(yes|NO) \(\+-\d\.\d\d\) *$",
        out, re.M,
    )  # fmt: skip
    assert [(sensor, policy) for sensor, policy, _ in rows] == [
        ("each_step", "gradient"), ("each_step", "exact_gradient"),
        ("counted", "gradient"), ("counted", "exact_gradient"),
    ], out  # fmt: skip
    held = sum(verdict == "yes" for _, _, verdict in rows)
    assert f"held: {held} of 4 rows" in out
