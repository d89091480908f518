"""A network a job trains: trained for the scenario's decisions, stopped when told, its
checkpoints handed over and taken up again, its curve whole across a resume."""

from __future__ import annotations

import numpy as np
import onnxruntime as ort
import pytest

from nanonav.env.arrays import NanoNavArrayEnv
from nanonav.rl.job import Checkpoint, train_network
from nanonav.scenario import Scenario, preset_scenario

ROLLOUT = 1024 * 64  # the trainer's default worlds x decisions a rollout


def scenario(policy: str = "ppo", **learning: int) -> Scenario:
    return preset_scenario(
        "alonso-kirkegaard",
        robots={"policy": policy},
        learning={"decisions": 2 * ROLLOUT, **learning},
        evaluation={"worlds": 2},
    )


def test_a_job_trains_its_network_for_its_decisions_and_gives_a_curve() -> None:
    kept: list[Checkpoint] = []
    asked: list[int] = []

    def keep_going(decisions: int) -> bool:
        asked.append(decisions)
        return True

    trained = train_network(scenario(), keep_going=keep_going, keep=kept.append, overlap=False)
    assert trained is not None
    assert asked == [ROLLOUT, 2 * ROLLOUT]
    assert kept == []  # no checkpoint before the run's end at the default interval
    assert trained.report["decisions"] == 2 * ROLLOUT
    assert trained.resumed_from is None
    assert [row["decisions"] for row in trained.curve] == [ROLLOUT, 2 * ROLLOUT]
    ended = sum(row["episodes"] for row in trained.curve)
    assert ended > 0
    assert all(0.0 <= row["success_rate"] <= 1.0 for row in trained.curve if row["episodes"])
    # the model runs and chooses among the scenario's actions from what its robot observes
    env = NanoNavArrayEnv(1, scenario().network_scenario())
    assert trained.observation == env.observation_labels
    assert trained.actions == env.action_labels
    session = ort.InferenceSession(trained.model)
    logits = session.run(None, {"observation": np.zeros((3, env.width), np.float32)})[0]
    assert logits.shape == (3, len(env.action_labels))


def test_a_job_stops_between_rollouts_when_told() -> None:
    trained = train_network(
        scenario(), keep_going=lambda decisions: False, keep=lambda c: None, overlap=False
    )
    assert trained is None


def test_a_resumed_job_goes_on_from_its_checkpoint_with_its_curve_whole() -> None:
    run = scenario("recurrent_ppo", decisions=3 * ROLLOUT, checkpoint_decisions=ROLLOUT)
    kept: list[Checkpoint] = []

    def stop_after_first(decisions: int) -> bool:
        return decisions < 2 * ROLLOUT

    assert train_network(run, keep_going=stop_after_first, keep=kept.append) is None
    assert [c.decisions for c in kept] == [ROLLOUT]
    assert [row["decisions"] for row in kept[0].curve] == [ROLLOUT]
    trained = train_network(run, keep_going=lambda d: True, keep=kept.append, resume=kept[0])
    assert trained is not None
    assert trained.resumed_from == ROLLOUT
    assert trained.report["decisions"] == 3 * ROLLOUT
    assert trained.memory == 25
    assert [row["decisions"] for row in trained.curve] == [ROLLOUT, 2 * ROLLOUT, 3 * ROLLOUT]
    assert [c.decisions for c in kept] == [ROLLOUT, 2 * ROLLOUT]


def test_a_policy_that_trains_no_network_is_refused() -> None:
    with pytest.raises(ValueError, match="trains no network"):
        train_network(
            preset_scenario("alonso-kirkegaard"), keep_going=lambda d: True, keep=lambda c: None
        )
