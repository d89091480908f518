"""The design-seed sweeps of the active Brownian physics run end to end on seeds of the caller's
choosing and print a row per setting, each paired with the gradient (values not asserted here:
they are measurements, reported in the documentation with their commands)."""

import re
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import decision_interval
import run_and_tumble

pytestmark = pytest.mark.timeout(600)
TINY = ["--seeds-from", "7100", "--seeds", "2", "--worlds", "1", "--radii", "2"]


def test_the_interval_sweep_prints_a_row_per_setting(capsys: pytest.CaptureFixture[str]) -> None:
    args = [*TINY, "--intervals", "step,0.5", "--exponents", "0.6", "--episodes", "1"]
    assert decision_interval.main(args) == 0
    out = capsys.readouterr().out
    assert "seeds 7100-7101 x 1 worlds" in out
    assert re.search(r"^R = 2.0 um: gradient \d", out, re.M)
    rows = re.findall(r"^  (step|0\.5)\s+0\.6\s+1\s+0\.9\s+\d\.\d\d .*[+-]\d\.\d\d \[", out, re.M)
    assert rows == ["step", "0.5"]


def test_the_run_and_tumble_sweep_shows_its_best_and_the_defaults(
    capsys: pytest.CaptureFixture[str],
) -> None:
    args = [*TINY, "--tumble", "0.5,2", "--rising", "0.05", "--memory", "3", "--best", "1",
            "--policy", "steer_and_tumble"]  # fmt: skip
    assert run_and_tumble.main(args) == 0
    out = capsys.readouterr().out
    assert "seeds 7100-7101 x 1 worlds" in out and "3 settings of steer_and_tumble" in out
    rows = re.findall(r"^  ([\d.]+)\s+([\d.]+)\s+([\d.]+)\s+\d\.\d\d", out, re.M)
    # the best one, and the defaults (once, where they are the best)
    assert 1 <= len(rows) <= 2 and ("1", "0.25", "1") in rows
    assert out.count("(defaults)") == 1
