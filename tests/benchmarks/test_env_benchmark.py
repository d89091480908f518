"""The environments' benchmark still runs and prints measured figures beside the engine's own
and CartPole's, and a verdict per target (their speed is not asserted)."""

import re
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import env as env_benchmark


def test_env_benchmark_prints_every_env_beside_its_yardstick(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert env_benchmark.main(["--quick"]) == 0
    out = capsys.readouterr().out

    def rate(pattern: str) -> float:
        found = re.search(pattern, out, re.M)
        assert found, (pattern, out)
        return float(found.group(1).replace(",", ""))

    assert rate(r"^  NanoNavEnv \(paper-single\)\s+([\d,]+)\s+[\d.]+ us$") > 0
    assert rate(r"^  CartPole-v1 \(bare gymnasium\)\s+([\d,]+)\s+[\d.]+ us$") > 0
    for worlds in ("1", "100", "1,000"):
        assert rate(rf"^\s+{worlds} worlds\s+([\d,]+)\s+[\d.]+ of the engine's own$") > 0
    for label in ("PettingZoo dicts", "step_arrays"):
        assert rate(rf"^  {label}\s+([\d,]+)\s+[\d.]+ of the engine's own$") > 0
    assert rate(r"^  simulate\s+([\d,]+)\s+\(its own loop") > 0
    verdicts = re.findall(r"^(meets|BELOW) target: (.+), [\d,]+ vs 1,000,000", out, re.M)
    assert [what for _, what in verdicts] == [
        "vector env, 1,000 worlds",
        "swarm env, 1,000 robots, PettingZoo dicts",
        "swarm env, 1,000 robots, step_arrays",
    ]
