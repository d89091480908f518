"""``NanoNavArrayEnv``, the trainer's env: the same worlds, rewards and ends as
Stable-Baselines3's ``NanoNavVecEnv`` for the same seed and actions, and generators whose
states, put back, draw the same worlds again."""

from __future__ import annotations

from typing import Any

import numpy as np

from nanonav.env.arrays import NanoNavArrayEnv
from nanonav.env.baselines import NanoNavVecEnv

SHORT: dict[str, Any] = {"preset": "paper-single", "learning": {"max_steps": 25}}
WORLDS = 4


def test_it_steps_the_worlds_sb3s_env_steps() -> None:
    ours = NanoNavArrayEnv(WORLDS, SHORT)
    theirs = NanoNavVecEnv(WORLDS, SHORT)
    theirs.seed(11)
    np.testing.assert_array_equal(ours.reset(seed=11), theirs.reset())
    rng = np.random.default_rng(0)
    ended = 0
    for _ in range(80):
        actions = rng.integers(0, ours.actions, WORLDS)
        step = ours.step(actions)
        obs, reward, done, infos = theirs.step(actions)
        np.testing.assert_array_equal(step.obs, obs)
        np.testing.assert_array_equal(step.reward, reward)
        np.testing.assert_array_equal(step.terminated | step.truncated, done)
        cut = [k for k in range(WORLDS) if infos[k]["TimeLimit.truncated"]]
        np.testing.assert_array_equal(np.flatnonzero(step.truncated), cut)
        for row, k in zip(step.final_obs, cut, strict=True):
            np.testing.assert_array_equal(row, infos[k]["terminal_observation"])
        ended += int(done.sum())
    assert ended > WORLDS  # worlds ended and were drawn afresh within the run


def test_generators_put_back_draw_the_same_worlds() -> None:
    env = NanoNavArrayEnv(WORLDS, SHORT)
    env.reset(seed=3)
    kept = env.generator_states()
    first = env.reset()
    env.reset()
    again = NanoNavArrayEnv(WORLDS, SHORT)
    again.restore_generators(kept)
    np.testing.assert_array_equal(again.reset(), first)
