"""The training-speed benchmark still runs end to end (a smoke run: a few rollouts a case)
and prints, for each case, decisions a second beside the raw env's; the new trainer's rows
with their peak memory (its speed is not asserted)."""

import re
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import train_speed


def test_train_speed_benchmark_prints_old_and_new_beside_the_raw_env(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert train_speed.main(["--quick"]) == 0
    out = capsys.readouterr().out

    def rate(case: str) -> float:
        found = re.search(rf"^  {re.escape(case)}\s+([\d,]+)", out, re.M)
        assert found, (case, out)
        return float(found.group(1).replace(",", ""))

    for worlds in ("64", "256"):
        assert rate(f"raw env, {worlds} worlds") > 0
        for net in ("MLP", "GRU-25"):
            case = f"new, {net}, {worlds} worlds"
            assert rate(case) > 0
            row = re.search(rf"^  {re.escape(case)}.* of the raw env's  peak [\d,]+ MB$", out, re.M)
            assert row, out
    assert rate("old, SB3 PPO, 8 worlds") > 0
    assert rate("old, SB3 recurrent PPO, 8 worlds") > 0
    assert rate("new, MLP, 64 worlds, 1 thread") > 0
    assert rate("new, MLP, 64 worlds, 2 threads") > 0
    assert "target: 100,000 decisions a second" in out


def test_the_recurrent_update_is_timed_with_the_new_gru_and_the_cell_loop_alternately(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert train_speed.main(["--gru", "--quick"]) == 0
    out = capsys.readouterr().out
    for name in ("new (nanonav.rl.gru)", "old (nn.GRUCell in a loop)"):
        pattern = rf"^  {re.escape(name)}: median ([\d.]+)  \(([\d.]+), ([\d.]+)\)$"
        row = re.search(pattern, out, re.M)
        assert row, out
        assert float(row.group(1)) > 0
