"""The physical question's report runs end to end and prints, per radius, the Peclet numbers
and each policy against the robot that does not steer and a passive one (values not asserted
here: tests/engine/test_active_brownian.py pins the physics)."""

import re
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import physical_question


def test_the_question_prints_every_radius_and_policy(capsys: pytest.CaptureFixture[str]) -> None:
    assert physical_question.main(["--quick"]) == 0
    out = capsys.readouterr().out
    assert re.findall(r"^R = ([\d.]+) um: D_T", out, re.M) == ["1.0", "5.0"]
    for policy in physical_question.POLICIES:
        assert len(re.findall(rf"^  {policy}\s", out, re.M)) == 2, policy
    assert out.count("passive (speed 0)") == 2 and "Pe_R" in out
    # every policy but the bar is paired with it, and the passive robot too
    assert len(re.findall(r"minus gradient", out)) == 2
    assert len(re.findall(r"minus blind_tumble", out)) == 2
    for policy in ("passive \\(speed 0\\)", "q_learning", "exact_gradient"):
        assert len(re.findall(rf"^  {policy}\s.*[+-]\d\.\d\d \[.*\]\*?\s*$", out, re.M)) == 2
