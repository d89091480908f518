"""The network-policy benchmark still runs and prints, case by case, the ONNX network's rate
beside the Q-table's from the same run, and a verdict per target (speed is not asserted)."""

import re
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import network_policy


def test_network_policy_benchmark_prints_each_case_beside_the_table(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert network_policy.main(["--quick"]) == 0
    out = capsys.readouterr().out
    rows = re.findall(r"^  (\S.+?)\s{2,}([\d,]+)\s+([\d,]+)\s+([\d.]+)$", out, re.M)
    assert [row[0] for row in rows] == [
        "lattice, every step",
        "active_brownian, every step",
        "active_brownian, every 0.1 s",
        "active_brownian, every 1 s",
    ], out
    for _, network, table, ratio in rows:
        assert int(network.replace(",", "")) > 0 and int(table.replace(",", "")) > 0
        assert float(ratio) > 0
    verdicts = re.findall(r"^(meets|BELOW) target: ONNX MLP, (.+), [\d,]+ vs 1,000,000", out, re.M)
    assert [what for _, what in verdicts] == ["lattice, every step", "active_brownian, every step"]
