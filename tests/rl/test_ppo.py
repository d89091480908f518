"""NanoNav's own PPO: GAE as a pure function, the return it improves within seconds on a world
where the fixed rule succeeds, and the rollout's sequences kept in the order their memories
are."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import numpy as np
import pytest
import torch

from nanonav.env.arrays import NanoNavArrayEnv
from nanonav.rl import collect
from nanonav.rl.collect import Collector, Rollout
from nanonav.rl.networks import ActorCritic
from nanonav.rl.ppo import PPO, PPOConfig, Update, gae
from nanonav.scenario import preset_scenario

# paper-single, where the rule reaches the cell (docs/explanation/learning.md), in short
# episodes so that an evaluation ends within a hundred decisions
SHORT = preset_scenario("paper-single", seed=5000, learning={"max_steps": 100})
CPU = torch.device("cpu")


def test_gae_with_lambda_and_gamma_one_is_the_return_to_go_less_the_value() -> None:
    rewards = torch.tensor([[1.0], [2.0], [3.0], [4.0]])
    values = torch.tensor([[0.5], [0.25], [1.0], [2.0]])
    dones = torch.tensor([[0.0], [1.0], [0.0], [0.0]])  # an episode ends at step 1
    after = torch.tensor([10.0])
    advantages = gae(rewards, values, dones, after, gamma=1.0, lam=1.0)
    expected = torch.tensor([[3.0 - 0.5], [2.0 - 0.25], [17.0 - 1.0], [14.0 - 2.0]])
    torch.testing.assert_close(advantages, expected)


def test_gae_discounts_each_decision_and_carries_nothing_across_an_end() -> None:
    rewards = torch.tensor([[1.0, 0.0], [1.0, 1.0]])
    values = torch.zeros(2, 2)
    dones = torch.tensor([[1.0, 0.0], [0.0, 0.0]])
    advantages = gae(rewards, values, dones, torch.tensor([0.0, 2.0]), gamma=0.5, lam=1.0)
    torch.testing.assert_close(advantages, torch.tensor([[1.0, 0.5 * (1.0 + 0.5 * 2.0)],
                                                         [1.0, 1.0 + 0.5 * 2.0]]))  # fmt: skip


def _mean_first_return(net: ActorCritic, worlds: int = 256, seed: int = 9000) -> float:
    """The mean return of each world's first episode, on seeds the training never met,
    decisions sampled from the policy."""
    env = NanoNavArrayEnv(worlds, SHORT)
    obs = torch.from_numpy(env.reset(seed=seed))
    memory = net.blank_memory(worlds)
    total = np.zeros(worlds)
    live = np.ones(worlds, dtype=bool)
    sampling = torch.Generator().manual_seed(0)
    while live.any():
        decision = net.act(obs, memory, sampling)
        step = env.step(decision.action.numpy())
        total += step.reward * live
        live &= ~(step.terminated | step.truncated)
        obs, memory = torch.from_numpy(step.obs), decision.memory
    return float(total.mean())


@pytest.mark.parametrize(("memory_units", "overlap"), [(0, False), (25, False), (0, True),
                                                        (25, True)])  # fmt: skip
def test_seconds_of_training_improve_the_return_where_the_rule_succeeds(
    memory_units: int, overlap: bool
) -> None:
    torch.set_num_threads(1)
    config = PPOConfig(envs=256, rollout=32, minibatch=2048, bptt=8, memory_units=memory_units,
                       seed=1, overlap=overlap)  # fmt: skip
    with PPO(NanoNavArrayEnv(256, SHORT), config) as learner:
        before = _mean_first_return(learner.net)
        seen: list[int] = []
        learner.learn(20 * config.batch, lambda update: seen.append(update.decisions))
    after = _mean_first_return(learner.net)
    assert seen == [config.batch * k for k in range(1, 21)]
    assert after > before + 3.0, (before, after)


def test_a_rollout_of_whole_sequences_is_required_with_a_memory() -> None:
    with pytest.raises(ValueError, match="whole sequences of 16"):
        PPOConfig(memory_units=25, rollout=40, bptt=16)
    assert PPOConfig(rollout=40).rollout == 40  # without a memory any rollout will do


def test_a_sequence_starts_from_the_memory_its_world_had_then() -> None:
    """The update judges each sequence from the memory kept at its first decision: run from
    there, the GRU gives back the memory the rollout carried at its last one."""
    torch.set_num_threads(1)
    env = NanoNavArrayEnv(4, SHORT)
    net = ActorCritic(env.width, env.actions, memory_units=5)
    collector = Collector(env, net, steps=8, bptt=4, gamma=0.99, seed=3, device=CPU)
    r = Rollout.allocated(8, 4, env, memory_units=5, bptt=4, device=CPU)
    collector.collect(r)
    assert net.memory is not None
    for chunk in range(2):
        for world in range(4):
            h = r.memories[chunk, world]
            for t in range(chunk * 4, chunk * 4 + 4):
                if r.starts[t, world]:
                    h = torch.zeros_like(h)
                with torch.no_grad():
                    h = net.memory(net.normaliser(r.obs[t, world : world + 1]), h[None])[0]
            if chunk == 0:
                expected = r.memories[1, world]
                torch.testing.assert_close(h * (~r.starts[4, world]), expected)


def _weights(net: ActorCritic) -> list[torch.Tensor]:
    return [value.clone() for value in net.state_dict().values()]


@pytest.mark.parametrize("memory_units", [0, 4])
def test_an_overlapped_run_is_the_same_run_each_time(memory_units: int) -> None:
    """The collector's process takes each rollout's weights at a fixed point of the schedule,
    whatever the two processes' timing: two runs of one seed end with the same weights, bit
    for bit."""
    torch.set_num_threads(1)
    config = PPOConfig(envs=16, rollout=16, minibatch=64, bptt=8, memory_units=memory_units,
                       seed=4, overlap=True)  # fmt: skip
    runs = []
    for _ in range(2):
        with PPO(NanoNavArrayEnv(16, SHORT), config) as learner:
            learner.learn(6 * config.batch)
            runs.append(_weights(learner.net))
    for first, second in zip(*runs, strict=True):
        assert torch.equal(first, second)


def test_an_overlapped_run_learns_the_same_whether_it_stops_for_checkpoints_or_not() -> None:
    """Each call of ``learn`` returns with the next rollout collected and the next call learns
    from it, so only a run's first rollout is collected alone: stretches that end at
    checkpoints neither cost the overlap nor change what the run learns."""
    torch.set_num_threads(1)
    config = PPOConfig(envs=16, rollout=16, minibatch=64, bptt=8, memory_units=4, seed=7,
                       overlap=True)  # fmt: skip
    runs, collected = [], []
    for stretches in ([6], [1, 2, 3, 5, 6]):
        updates: list[Update] = []
        with PPO(NanoNavArrayEnv(16, SHORT), config) as learner:
            for end in stretches:
                learner.learn(end * config.batch, updates.append)
                learner.state_dict()  # what a checkpoint reads between stretches
            runs.append(_weights(learner.net))
        collected.append(len(updates))
    assert collected == [6, 6]
    for whole, stopped in zip(*runs, strict=True):
        assert torch.equal(whole, stopped)


def test_the_collectors_shared_files_are_gone_once_it_has_started(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Both processes map the rollouts and the weights, then the files are removed: a run
    that is killed leaves nothing behind."""
    monkeypatch.setattr(collect, "SHARED_FOLDER", tmp_path)
    config = PPOConfig(envs=8, rollout=16, minibatch=64, seed=5, overlap=True)
    with PPO(NanoNavArrayEnv(8, SHORT), config) as learner:
        learner.learn(2 * config.batch)
        assert list(tmp_path.iterdir()) == []
        assert learner.decisions == 2 * config.batch


def test_a_collector_that_dies_ends_the_run_with_an_error_not_a_hang() -> None:
    config = PPOConfig(envs=8, rollout=16, minibatch=64, seed=6, overlap=True)
    with PPO(NanoNavArrayEnv(8, SHORT), config) as learner:
        learner.learn(config.batch)
        pid = learner.collector_pid()
        assert pid is not None
        os.kill(pid, signal.SIGKILL)
        with pytest.raises(RuntimeError, match="collector's process ended"):
            learner.learn(4 * config.batch)
