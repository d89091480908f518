"""``NanoNavArrayEnv``: many worlds of one robot as bare arrays, what NanoNav's own trainer
(``nanonav.rl.ppo``) steps: no spaces, no dicts, no per-world Python.

A room of its own because at thousands of worlds a step's dicts (SB3's ``infos``) cost as
much as the learner's forward pass, and because a checkpoint needs each world's generators,
which this env makes and keeps, so that their states can be saved and put back.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from nanonav.engine.observations import (
    action_labels,
    as_scenario,
    observation_of,
    state_labels,
    with_robots,
)
from nanonav.engine.world import DYNAMICS_STREAM, EVALUATION_STREAM, TRAINING_STREAM, stream
from nanonav.engine.worlds import Worlds
from nanonav.env.robot import ScenarioLike
from nanonav.scenario import Steering


@dataclass(frozen=True)
class Transition:
    """What one step of every world gives: the next observations (a world that ended is
    already drawn afresh, its first observation here), the rewards, which worlds ended by
    reaching a cell (``terminated``) or by the time limit (``truncated``), and the last
    observation of each truncated world, in the order of ``np.flatnonzero(truncated)``."""

    obs: NDArray[np.float32]
    reward: NDArray[np.float32]
    terminated: NDArray[np.bool_]
    truncated: NDArray[np.bool_]
    final_obs: NDArray[np.float32]


class NanoNavArrayEnv:
    """``num_envs`` worlds of one robot (as ``NanoNavEnv``: its docstring says what the
    observation, the action and the reward are), stepped in one compiled call.

    Observations are float32 rows ``(num_envs, width)``; actions are action numbers
    ``(num_envs,)``, or steering continuously turns ``(num_envs, 2)`` (side, up; clipped to
    -1 .. 1). A finished world is drawn afresh within the step that ended it, as
    Stable-Baselines3's ``NanoNavVecEnv`` does, and the same worlds: ``reset(seed=s)`` draws
    world k from seed s + k. ``apart`` draws them instead from streams of their own, which no
    evaluation of any seed draws from (a job trains on them and is evaluated on its seed's
    evaluation worlds, as tabular learning is). Actions are not checked one by one: a
    trainer's sampled actions are in the action set by construction, and a turn that is not
    finite is taken as none.
    """

    def __init__(
        self,
        num_envs: int,
        scenario: ScenarioLike = None,
        *,
        steering: Steering = "discrete",
        apart: bool = False,
    ) -> None:
        if num_envs < 1:
            raise ValueError("num_envs must be at least 1")
        self.scenario = with_robots(as_scenario(scenario), 1)
        self.num_envs = num_envs
        self.steering = steering
        self._worlds = Worlds(self.scenario, num_envs, "simultaneous", steering=steering)
        self.continuous = self._worlds.continuous
        self._seen = observation_of(self.scenario, steering)
        self.observation_labels = list(self._seen.labels)
        self.action_labels = action_labels(self.scenario, steering)
        self.state_labels = state_labels(self.scenario)
        self.width = int(self._seen.columns.size)
        # how many numbers a decision is: one action number, or the two parts of a turn
        self.actions = len(self.action_labels)
        self._actions = self._worlds.blank_actions()
        self._all = np.ones(num_envs, dtype=np.bool_)
        self._none = np.zeros(num_envs, dtype=np.bool_)
        self._world_rngs: list[np.random.Generator] = []
        self._rngs: list[np.random.Generator] = []
        self.seed = self.scenario.seed
        self.apart = apart

    def reset(self, seed: int | None = None) -> NDArray[np.float32]:
        """Every world drawn afresh: world k from seed ``seed`` + k (the scenario's seed when
        None, the first time; else each world's next one)."""
        if seed is not None or not self._rngs:
            self._generators(self.scenario.seed if seed is None else seed)
        self._worlds.step(None, self._all)
        return self._observed()

    def _generators(self, seed: int) -> None:
        """World k's generators made anew from seed ``seed`` + k, and kept here."""
        self.seed = seed
        count = range(self.num_envs)
        if self.apart:
            self._world_rngs = [stream(seed, TRAINING_STREAM, k, 0) for k in count]
            self._rngs = [stream(seed, TRAINING_STREAM, k, 1) for k in count]
        else:
            self._world_rngs = [stream(seed + k, EVALUATION_STREAM) for k in count]
            self._rngs = [stream(seed + k, DYNAMICS_STREAM) for k in count]
        for k in count:
            self._worlds.use_generators(k, self._world_rngs[k], self._rngs[k])

    def step(self, actions: NDArray[Any]) -> Transition:
        w = self._worlds
        if self.continuous:
            turns = np.nan_to_num(np.asarray(actions, dtype=np.float64), nan=0.0)
            self._actions[:, 0] = np.clip(turns.reshape(self.num_envs, 2), -1.0, 1.0)
        else:
            self._actions[:, 0] = np.asarray(actions).reshape(self.num_envs)
        w.step(self._actions, self._none, checked=True)
        terminated = ~w.active[:, 0]
        truncated = w.over & ~terminated
        done = terminated | truncated
        reward = w.reward[:, 0].astype(np.float32)
        obs = self._observed()
        final_obs = obs[truncated]
        if done.any():
            w.redraw(done)
            obs[done] = self._observed()[done]
        return Transition(obs, reward, terminated, truncated, final_obs)

    def _observed(self) -> NDArray[np.float32]:
        observed: NDArray[np.float32] = self._worlds.obs[:, 0][:, self._seen.columns].astype(
            np.float32
        )
        return observed

    def generator_states(self) -> list[dict[str, Any]]:
        """Each world's two generators' states (worlds', then dynamics'), for a checkpoint."""
        return [dict(g.bit_generator.state) for g in (*self._world_rngs, *self._rngs)]

    def restore_generators(self, states: list[dict[str, Any]]) -> None:
        """Put back what ``generator_states`` gave, in place (the compiled step holds the
        generators' addresses, not copies); the next ``reset()`` draws every world afresh
        from them."""
        if not self._rngs:
            self._generators(self.scenario.seed)
        kept = [*self._world_rngs, *self._rngs]
        if len(states) != len(kept):
            raise ValueError(f"{len(states)} generator states for {len(kept)} generators")
        for generator, state in zip(kept, states, strict=True):
            generator.bit_generator.state = state
