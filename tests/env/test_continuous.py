"""Continuous steering through the environments (active Brownian): a ``Box`` turn (side, up)
in the robot's body frame, the gradient observed in that frame; the ecosystem's checkers
accept it, the single, vector and SB3 envs step the same worlds, and a real PPO run's export
gives the model's own greedy turn."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env as gymnasium_check_env
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test, seed_test
from stable_baselines3 import PPO
from stable_baselines3.common.env_checker import check_env as sb3_check_env

from nanonav.engine.observations import observation_of
from nanonav.env import NanoNavAECEnv, NanoNavEnv, NanoNavParallelEnv, NanoNavVectorEnv
from nanonav.env.baselines import NanoNavVecEnv, export_onnx
from nanonav.rl.onnx_policy import NetworkPolicy
from nanonav.scenario import Scenario

SWIMMERS: dict[str, Any] = {
    "preset": "tumour-microswimmers",
    # cells secreting enough that a robot's counts are seldom all 0
    "physics": {"time_limit_s": 2.0, "secretion_molecules_s": 1e5},
    "learning": {"decision_interval_s": 0.1},
}


def test_the_checkers_accept_a_continuous_turn() -> None:
    env = NanoNavEnv(SWIMMERS, steering="continuous")
    assert env.action_space == spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
    assert env.action_labels == ["turn_side", "turn_up"]
    assert env.observation_labels[2:5] == ("gradient_forward", "gradient_side", "gradient_up")
    gymnasium_check_env(env, skip_render_check=True)
    sb3_check_env(NanoNavEnv(SWIMMERS, steering="continuous"), warn=False)


def test_the_single_and_vector_envs_step_the_same_worlds() -> None:
    single = NanoNavEnv(SWIMMERS, steering="continuous")
    vector = NanoNavVectorEnv(2, SWIMMERS, steering="continuous")
    obs, _ = single.reset(seed=40)
    batch, _ = vector.reset(seed=40)
    np.testing.assert_array_equal(batch[0], obs)
    rng = np.random.default_rng(0)
    for _ in range(15):
        turn = rng.uniform(-1.5, 1.5, size=2)  # beyond -1 .. 1 is clipped, in both
        # a turn: NanoNavEnv.step's annotation admits discrete actions only
        obs, reward, terminated, truncated, _ = single.step(turn)  # type: ignore[arg-type]
        batch, rewards, *_ = vector.step(np.stack([turn, -turn]))
        np.testing.assert_array_equal(batch[0], obs)
        assert rewards[0] == reward
        if terminated or truncated:
            break
    # what is not a turn of two finite numbers is refused
    for bad in ([np.nan, 0.0], [1.0, 2.0, 3.0], "left"):
        with pytest.raises(ValueError, match="turn"):
            single.step(bad)  # type: ignore[arg-type]  # refused on purpose
    with pytest.raises(ValueError, match="shape"):
        vector.step(np.zeros((2, 3)))  # type: ignore[arg-type]  # refused on purpose


# they draw nothing: the service draws a job's pictures
@pytest.mark.filterwarnings("ignore:Environment has not defined a render")
def test_the_swarm_envs_pass_pettingzoos_checkers_turning() -> None:
    swarm = {**SWIMMERS, "robots": {"count": 3}, "cells": {"count": 2}}
    parallel_api_test(NanoNavParallelEnv(swarm, steering="continuous"), num_cycles=50)
    parallel_seed_test(lambda: NanoNavParallelEnv(swarm, steering="continuous"), num_cycles=50)
    api_test(NanoNavAECEnv(swarm, steering="continuous"), num_cycles=50)
    seed_test(lambda: NanoNavAECEnv(swarm, steering="continuous"), num_cycles=50)
    env = NanoNavParallelEnv(swarm, steering="continuous")
    env.reset(seed=2)
    with pytest.raises(ValueError, match="robot_1's action"):
        env.step({"robot_0": [0.0, 1.0], "robot_1": [np.inf, 0.0], "robot_2": [0.0, 0.0]})
    # turns: step_arrays's annotation admits discrete actions only
    arrays = env.step_arrays(np.zeros((3, 2)))  # type: ignore[arg-type]
    assert arrays[0].shape == (3, len(env.observation_labels))


def test_a_lattice_has_no_continuous_turn() -> None:
    with pytest.raises(ValueError, match="active_brownian"):
        NanoNavEnv(None, steering="continuous")
    with pytest.raises(ValueError, match="active_brownian"):
        NanoNavVecEnv(2, None, steering="continuous")


@pytest.mark.parametrize("algo", ["ppo", "recurrent-ppo"])
def test_ppo_learns_a_turn_and_its_export_turns_as_it_does(algo: str, tmp_path: Path) -> None:
    """A real learner's run on the SB3 VecEnv; the exported ONNX gives the model's greedy
    turn (its mean, clipped to the box), as ``predict(deterministic=True)`` does."""
    env = NanoNavVecEnv(4, SWIMMERS, steering="continuous")
    assert env.action_space == spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
    options: dict[str, Any] = {"n_steps": 32, "batch_size": 64, "n_epochs": 2, "seed": 0}
    if algo == "ppo":
        model: Any = PPO("MlpPolicy", env, device="cpu", **options)
    else:
        from sb3_contrib import RecurrentPPO

        model = RecurrentPPO("MlpLstmPolicy", env, device="cpu", **options)
    model.learn(total_timesteps=256)
    path = tmp_path / "policy.onnx"
    export_onnx(model, path, observation=env.observation_labels, actions=env.action_labels)
    scenario = Scenario.model_validate(SWIMMERS)
    width = len(observation_of(scenario, "continuous").columns)
    rows = np.random.default_rng(1).normal(size=(6, width)) * 3.0
    rows[:, 0] = np.abs(rows[:, 0])
    with NetworkPolicy(path.read_bytes(), width, 2, max_bytes=10**7, continuous=True) as network:
        assert network.steering == "continuous"
        turns = network(rows)
    predicted, _ = model.predict(rows.astype(np.float32), deterministic=True)
    assert turns.shape == (6, 2) and np.all(np.abs(turns) <= 1.0)
    np.testing.assert_allclose(turns, predicted, atol=1e-5)
    assert gymnasium.spaces.Box(-1.0, 1.0, shape=(2,)).contains(turns[0].astype(np.float32))
