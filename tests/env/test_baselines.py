"""Stable-Baselines3 through ``NanoNavVecEnv``: the same worlds as the Gymnasium vector env with
SB3's same-step reset and terminal observations, and a real learner's training run."""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
import pytest
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnvObs

from nanonav.env import NanoNavVectorEnv
from nanonav.env.baselines import NanoNavVecEnv

# short episodes, so that worlds end at different steps within a few dozen
SHORT: dict[str, Any] = {"preset": "paper-single", "learning": {"max_steps": 25}}
WORLDS = 4


def _action(world: int, episode: int, step: int, actions: int) -> int:
    return (7 * world + 13 * episode + 5 * step + step * step) % actions


Episode = list[tuple[list[float], float]]


def _episodes_gymnasium(steps: int) -> list[list[Episode]]:
    """Each world's finished episodes as (observation, reward) pairs, through Gymnasium's
    next-step reset (the step after an end draws the world afresh, its action unused)."""
    env = NanoNavVectorEnv(WORLDS, SHORT)
    obs, _ = env.reset(seed=11)
    episode = [0] * WORLDS
    step = [0] * WORLDS
    ended = np.zeros(WORLDS, dtype=bool)
    current: list[Episode] = [[(o.tolist(), 0.0)] for o in obs]
    done: list[list[Episode]] = [[] for _ in range(WORLDS)]
    assert isinstance(env.single_action_space, gymnasium.spaces.Discrete)
    n = int(env.single_action_space.n)
    for _ in range(steps):
        actions = np.array([_action(k, episode[k], step[k], n) for k in range(WORLDS)])
        obs, reward, terminated, truncated, _ = env.step(actions)
        for k in range(WORLDS):
            if ended[k]:  # this step drew world k afresh
                current[k] = [(obs[k].tolist(), 0.0)]
                continue
            current[k].append((obs[k].tolist(), float(reward[k])))
            step[k] += 1
            if terminated[k] or truncated[k]:
                done[k].append(current[k])
                episode[k] += 1
                step[k] = 0
        ended = terminated | truncated
    return done


def _episodes_sb3(steps: int) -> list[list[Episode]]:
    """The same, through SB3's same-step reset and ``terminal_observation``."""
    env = NanoNavVecEnv(WORLDS, SHORT)
    assert isinstance(env, VecEnv)
    env.seed(11)
    obs: VecEnvObs = env.reset()
    assert isinstance(obs, np.ndarray)
    episode = [0] * WORLDS
    step = [0] * WORLDS
    current: list[Episode] = [[(o.tolist(), 0.0)] for o in obs]
    done: list[list[Episode]] = [[] for _ in range(WORLDS)]
    n = int(env.action_space.n)  # type: ignore[attr-defined]
    for _ in range(steps):
        actions = np.array([_action(k, episode[k], step[k], n) for k in range(WORLDS)])
        obs, reward, dones, infos = env.step(actions)
        assert isinstance(obs, np.ndarray)
        for k in range(WORLDS):
            last = infos[k]["terminal_observation"] if dones[k] else obs[k]
            current[k].append((last.tolist(), float(reward[k])))
            step[k] += 1
            if dones[k]:
                done[k].append(current[k])
                current[k] = [(obs[k].tolist(), 0.0)]
                episode[k] += 1
                step[k] = 0
    return done


def test_sb3s_same_step_reset_meets_the_same_worlds_as_gymnasiums_next_step_reset() -> None:
    ours = _episodes_sb3(120)
    theirs = _episodes_gymnasium(120 + 10)  # each end costs Gymnasium's env one step more
    for k in range(WORLDS):
        assert len(ours[k]) >= 3, "a world should finish several short episodes"
        shared = min(len(ours[k]), len(theirs[k]))
        for a, b in zip(ours[k][:shared], theirs[k][:shared], strict=True):
            assert len(a) == len(b)
            np.testing.assert_allclose([o for o, _ in a], [o for o, _ in b], rtol=1e-6)
            np.testing.assert_allclose([r for _, r in a], [r for _, r in b], rtol=1e-6)


def test_a_time_limit_is_marked_and_each_info_names_the_state() -> None:
    env = NanoNavVecEnv(2, {**SHORT, "learning": {"max_steps": 3}})
    env.seed(0)
    env.reset()
    assert [set(i) for i in env.reset_infos] == [{"state"}, {"state"}]
    for _ in range(3):
        obs, _, dones, infos = env.step(np.zeros(2, dtype=np.int64))
    assert isinstance(obs, np.ndarray)
    assert obs.dtype == np.float32 and env.observation_space.contains(obs[0])
    assert dones.all()
    assert all(i["TimeLimit.truncated"] for i in infos if "terminal_observation" in i)
    assert all(0 <= i["state"] < len(env.state_labels) for i in infos)


def test_an_action_outside_the_set_is_refused() -> None:
    env = NanoNavVecEnv(2, SHORT)
    env.reset()
    with pytest.raises(ValueError, match="not in the action set"):
        env.step(np.array([0, 99]))


HELD: dict[str, Any] = {
    "preset": "tumour-microswimmers",
    "physics": {"time_limit_s": 3.0},
    "learning": {"decision_interval_s": 0.5},
}


@pytest.mark.parametrize("scenario", [SHORT, HELD], ids=["lattice", "active_brownian held 0.5 s"])
def test_ppo_trains_on_it_and_acts(scenario: dict[str, Any]) -> None:
    """A real learner's run, a few hundred decisions long: SB3 accepts the env, learns from
    it, and its policy picks actions of the set."""
    env = NanoNavVecEnv(4, scenario)
    model = PPO("MlpPolicy", env, n_steps=32, batch_size=64, n_epochs=2, seed=0, device="cpu")
    model.learn(total_timesteps=256)
    assert model.num_timesteps == 256
    obs = env.reset()
    actions, _ = model.predict(obs, deterministic=True)
    assert actions.shape == (4,)
    assert all(0 <= a < len(env.action_labels) for a in actions)
