"""benchmarks/env_breakdown.py runs end to end (compiling its own loop over the engine's step)
and prints each stage of a vector env's world-step as measured figures (their size is not
asserted: speed lives in the benchmark)."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import env_breakdown


@pytest.mark.timeout(1200)
def test_the_breakdown_prints_every_stage_in_ns_and_robot_steps(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert env_breakdown.main(["--quick"]) == 0
    out = capsys.readouterr().out
    rows = re.findall(r"^  (.+?)\s+(\d+) ns\s+([\d,]+) robot-steps/s$", out, flags=re.M)
    assert [label for label, _, _ in rows] == [
        "one world over and over, one compiled loop",
        "100 worlds in turn, one compiled loop",
        "Worlds.step, 100 worlds a call",
        "NanoNavVectorEnv.step, 100 worlds",
        "simulate, one robot (it also learns)",
    ]
    for _, ns, rate in rows:
        # ns and robot-steps/s are one figure twice: each the other's inverse
        assert int(ns) > 0
        assert abs(int(ns) * float(rate.replace(",", "")) / 1e9 - 1) < 0.01
