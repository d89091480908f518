"""The physics report's checks pass at a test's sample size: the mean squared displacement of
passive and active Brownian robots and their heading correlation at several lags, against the
formulas, with tolerances of four standard errors of the simulated means."""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import physics


def test_every_theory_check_passes_and_the_report_says_so(
    capsys: pytest.CaptureFixture[str],
) -> None:
    checks = physics.all_checks(robots=5_000, seed=7)
    failed = [c.line() for c in checks if not c.passed]
    assert not failed, failed
    names = {c.name for c in checks}
    assert {"passive MSD (um^2)", "active MSD (um^2)", "heading correlation"} <= names
    # the checks are not vacuous: each simulated mean has a real spread and lags differ
    assert all(c.standard_error > 0 for c in checks if c.lag_s is not None)
    assert physics.main(["--quick"]) == 0
    assert "checks within 4 standard errors" in capsys.readouterr().out
