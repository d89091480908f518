"""A training run's checkpoint: written whole (no temporary file left behind), it holds the
networks, the optimiser, every random stream and the decisions done, and a learner given it
takes up the run there."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest
import torch

from nanonav.env.arrays import NanoNavArrayEnv
from nanonav.rl.checkpoint import CHECKPOINT, load_checkpoint, save_checkpoint
from nanonav.rl.ppo import PPO, PPOConfig
from nanonav.scenario import preset_scenario

WORLD = preset_scenario("paper-single", seed=5000, learning={"max_steps": 50})
CONFIG = PPOConfig(envs=8, rollout=16, minibatch=64, memory_units=4, bptt=8, seed=2)


def test_a_checkpoint_is_written_whole_and_read_back(tmp_path: Path) -> None:
    with PPO(NanoNavArrayEnv(8, WORLD), CONFIG) as learner:
        learner.learn(2 * CONFIG.batch)
        save_checkpoint(tmp_path, learner.state_dict())
    assert [p.name for p in tmp_path.iterdir()] == [CHECKPOINT]
    state = load_checkpoint(tmp_path)
    assert state["decisions"] == 2 * CONFIG.batch and state["updates"] == 2
    assert len(state["env_rngs"]) == 2 * 8  # each world's two generators
    for name, weights in learner.net.state_dict().items():
        torch.testing.assert_close(state["net"][name], weights)


@pytest.mark.parametrize("overlap", [True, False])
def test_a_resumed_learner_goes_on_as_the_one_that_wrote_it(tmp_path: Path,
                                                            overlap: bool) -> None:  # fmt: skip
    torch.set_num_threads(1)
    config = replace(CONFIG, overlap=overlap)
    with PPO(NanoNavArrayEnv(8, WORLD), config) as first:
        first.learn(2 * config.batch)
        save_checkpoint(tmp_path, first.state_dict())
        with PPO(NanoNavArrayEnv(8, WORLD), config) as resumed:
            resumed.load_state_dict(load_checkpoint(tmp_path))
            assert resumed.decisions == first.decisions
            # both draw every world afresh from the generators as they were, and learn alike
            first.load_state_dict(first.state_dict())
            first.learn(3 * config.batch)
            resumed.learn(3 * config.batch)
    assert resumed.decisions == first.decisions == 3 * config.batch
    for name, weights in first.net.state_dict().items():
        torch.testing.assert_close(resumed.net.state_dict()[name], weights)


def test_a_checkpoint_of_other_settings_is_refused(tmp_path: Path) -> None:
    learner = PPO(NanoNavArrayEnv(8, WORLD), CONFIG)
    other = PPO(NanoNavArrayEnv(8, WORLD), PPOConfig(envs=8, rollout=16, minibatch=64))
    with pytest.raises(ValueError, match="other settings"):
        other.load_state_dict(learner.state_dict())
