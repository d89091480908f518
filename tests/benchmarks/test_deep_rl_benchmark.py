"""The deep-learning benchmark still runs end to end (a smoke run: a few thousand decisions of
training, two fresh seeds), with the learners steering by the action set or by a continuous
turn, and prints every learner beside the baselines, the paired
differences with Holm's p, and the training rate beside CartPole's (nothing is asserted of
what is learned)."""

import re
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import deep_rl


@pytest.mark.parametrize("steering", ["discrete", "continuous"])
def test_deep_rl_benchmark_prints_each_learner_beside_the_baselines(
    steering: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert deep_rl.main(["--quick", "--steering", steering]) == 0
    out = capsys.readouterr().out
    assert f"the deep learners steering {steering}ly" in out
    for algo in ("ppo", "recurrent-ppo"):
        trained = rf"^  {algo}\s+R = 0.5 um: [\d,]+ decisions in \d+ s, ([\d,]+) decisions/s"
        rate = re.search(trained, out, re.M)
        assert rate and int(rate.group(1).replace(",", "")) > 0, out
    cartpole = r"^  PPO on CartPole-v1 \(16 envs, DummyVecEnv\): [\d,]+ decisions/s"
    assert re.search(cartpole, out, re.M), out
    reached = (
        r"^R = 0.5 um: gradient ([\d.]+) .* q_learning ([\d.]+) .* ppo ([\d.]+) "
        r".* recurrent-ppo ([\d.]+)"
    )
    shares = re.search(reached, out, re.M)
    assert shares and all(0.0 <= float(v) <= 1.0 for v in shares.groups()), out
    difference = (
        r"^  (ppo|recurrent-ppo) - (gradient|q_learning|turn_up_gradient): [+-][\d.]+ "
        r"\[[+-][\d.]+, [+-][\d.]+\].? p [\d.e-]+, Holm [\d.e-]+$"
    )
    baselines = 3 if steering == "continuous" else 2
    assert len(re.findall(difference, out, re.M)) == 2 * baselines, out
