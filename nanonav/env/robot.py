"""Gymnasium environments over the engine: ``NanoNavEnv``, one robot in a scenario's world, and
``NanoNavVectorEnv``, many such worlds stepped in one compiled call."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, SupportsFloat

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from numpy.typing import NDArray

from nanonav.engine.observations import (
    action_labels,
    as_scenario,
    observation_of,
    state_labels,
    with_robots,
)
from nanonav.engine.worlds import Worlds
from nanonav.scenario import Scenario, Steering

ScenarioLike = Scenario | Mapping[str, Any] | None


def action_space_of(worlds: Worlds) -> spaces.Discrete | spaces.Box:
    """One robot's actions: ``Discrete`` over the action set, or steering continuously a
    ``Box`` of a turn (side, up) in the body frame, each -1 .. 1 of the largest turn a step
    allows (float32, as learners' continuous policies give it)."""
    if worlds.continuous:
        return spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
    return spaces.Discrete(worlds.actions)


def turn_of(action: Any) -> NDArray[np.float64]:
    """A continuous action as the (side, up) turn ``Worlds`` takes, refused unless it is two
    finite numbers (a number beyond -1 .. 1 is clipped, as a learner's sample may be)."""
    try:
        turn = np.asarray(action, dtype=np.float64).reshape(2)
    except (TypeError, ValueError):
        raise ValueError(f"action {action!r} is not a turn (side, up) of two numbers") from None
    if not np.isfinite(turn).all():
        raise ValueError(f"action {action!r} is not a turn of two finite numbers")
    return turn


class NanoNavEnv(gymnasium.Env[NDArray[np.float64], np.int64]):
    """One robot hunting the cells of a scenario's world (the scenario's other robots are a
    swarm's: ``NanoNavParallelEnv``; here ``robots.count`` is 1).

    ## Observation

    A ``Box`` of float64s: what the robot senses this step, in the scenario's units (lattice:
    its concentration and length units; active_brownian: nM, nM/µm, µm). ``observation_labels``
    names the columns the scenario fills, in this order:

    | label              | what it is                                         | units (AB) |
    |--------------------|----------------------------------------------------|------------|
    | reading            | the count-based reading, noisy; 0 below threshold  | nM         |
    | reading_change     | minus the last reading (AB: minus its memory)      | nM         |
    | gradient_x, _y, _z | the sensed gradient (AB: steering continuously)    | nM/µm      |
    | obstacle           | distance to an obstacle (AB: 1 if a move stopped)  | 1          |
    | cell               | distance to the nearest untreated cell, capped     | µm         |
    | signal             | the net signal read, or 1 while a message waits    | nM         |
    | signal_change      | minus the last net signal (a chemical signal only) | nM         |

    (AB: active_brownian; the lattice's columns are in its own units.) Distances are capped at
    the sensors' ranges, the cap reading as none sensed; the signal columns are there only with
    a communication model; the lattice's obstacle column is the distance to the nearest
    obstacle's surface.

    ## Actions

    ``Discrete`` over the scenario's action set (``action_labels``). With
    ``steering="continuous"`` (active_brownian only): a ``Box`` turn (side, up) in the robot's
    body frame, each -1 .. 1 of the largest turn a step allows
    (``physics.max_turn_rate_rad_s``), held over the decision interval as a steady turn; the
    gradient columns are then ``gradient_forward``, ``_side``, ``_up``, read each step along
    the robot's axes and averaged over the steps since its last decision.

    ## Rewards

    The scenario's ``rewards`` (the paper's eq. 2.7), each step: ``step`` (a cost), plus
    ``collision`` when a move is stopped by an obstacle (active_brownian: per second stopped),
    plus ``approach`` per unit of distance moved toward the nearest untreated cell, plus
    ``reach`` on arriving at one. Held over a decision interval, the steps' rewards are summed.

    ## Episode end

    Terminated when the robot reaches a cell (delivers its payload); truncated at
    ``learning.max_steps`` or once every cell is treated.

    ## Reset and info

    ``reset(seed=s)`` draws, episode after episode, the worlds a job of seed s evaluates in;
    ``reset()`` goes on to the next world; before any seed, the scenario's seed is used. Reset
    takes no options (any given are ignored, as PettingZoo's checker expects).
    ``info["state"]`` is the tabular state the engine's learner would see (``state_labels``
    names them), so that a table from ``/qtable`` can act here.
    """

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012 (gymnasium's own layout)

    def __init__(self, scenario: ScenarioLike = None, *, steering: Steering = "discrete") -> None:
        self.scenario = with_robots(as_scenario(scenario), 1)
        self._worlds = Worlds(self.scenario, 1, "simultaneous", steering=steering)
        self._seen = observation_of(self.scenario, steering)
        self.observation_space = spaces.Box(self._seen.low, self._seen.high, dtype=np.float64)
        self.action_space = action_space_of(self._worlds)  # type: ignore[assignment]
        self.observation_labels = self._seen.labels
        self.action_labels = action_labels(self.scenario, steering)
        self.state_labels = state_labels(self.scenario)
        self._fresh = np.ones(1, dtype=np.bool_)
        self._stale = np.zeros(1, dtype=np.bool_)
        self._actions = np.zeros((1, 1), dtype=np.int64)
        self._turns = np.zeros((1, 1, 2))
        self._ended = True

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float64], dict[str, Any]]:
        super().reset(seed=seed)
        if seed is not None:
            self._worlds.seed([seed])
        self._worlds.step(None, self._fresh)
        self._ended = False
        return self._worlds.obs[0, 0, self._seen.columns], self._info()

    def step(
        self, action: np.int64 | int
    ) -> tuple[NDArray[np.float64], SupportsFloat, bool, bool, dict[str, Any]]:
        if self._ended:
            raise RuntimeError("the episode is over (or never began): call reset()")
        w = self._worlds
        if w.continuous:
            self._turns[0, 0] = turn_of(action)
            w.step(self._turns, self._stale, checked=True)
        else:
            chosen = int(action) if isinstance(action, (int, np.integer)) else -1
            if not 0 <= chosen < w.actions:
                raise ValueError(f"action {action!r} is not in {self.action_space}")
            self._actions[0, 0] = chosen
            w.step(self._actions, self._stale, checked=True)
        terminated = not bool(w.active[0, 0])
        truncated = bool(w.over[0]) and not terminated
        self._ended = terminated or truncated
        return (
            w.obs[0, 0, self._seen.columns],
            float(w.reward[0, 0]),
            terminated,
            truncated,
            self._info(),
        )

    def _info(self) -> dict[str, Any]:
        return {"state": int(self._worlds.state[0, 0]), "step": self._worlds.steps(0)}


class NanoNavVectorEnv(VectorEnv[NDArray[np.float64], NDArray[np.int64], NDArray[Any]]):
    """``num_envs`` worlds of one robot (as ``NanoNavEnv``, ``steering`` too), stepped in one
    compiled call.

    World k reset with seed s + k (``reset(seed=s)``), or with a seed each; a world whose
    episode ended is drawn afresh at the next step (Gymnasium's next-step autoreset: that step's
    action is unused, its reward 0). ``infos["state"]`` holds each world's tabular state.
    """

    metadata: dict[str, Any] = {  # noqa: RUF012 (gymnasium's own layout)
        "autoreset_mode": AutoresetMode.NEXT_STEP,
        "render_modes": [],
    }

    def __init__(
        self, num_envs: int = 1, scenario: ScenarioLike = None, *, steering: Steering = "discrete"
    ) -> None:
        if num_envs < 1:
            raise ValueError("num_envs must be at least 1")
        self.scenario = with_robots(as_scenario(scenario), 1)
        self.num_envs = num_envs
        self._worlds = Worlds(self.scenario, num_envs, "simultaneous", steering=steering)
        self._seen = observation_of(self.scenario, steering)
        self.observation_labels = self._seen.labels
        self.single_observation_space = spaces.Box(
            self._seen.low, self._seen.high, dtype=np.float64
        )
        self.single_action_space = action_space_of(self._worlds)
        self.observation_space = gymnasium.vector.utils.batch_space(
            self.single_observation_space, num_envs
        )
        self.action_space = gymnasium.vector.utils.batch_space(self.single_action_space, num_envs)
        self.action_labels = action_labels(self.scenario, steering)
        self.state_labels = state_labels(self.scenario)
        self._all = np.ones(num_envs, dtype=np.bool_)
        self._ended = np.zeros(num_envs, dtype=np.bool_)

    def reset(
        self, *, seed: int | Sequence[int] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float64], dict[str, Any]]:
        if seed is not None:
            seeds = [seed + k for k in range(self.num_envs)] if isinstance(seed, int) else seed
            self._worlds.seed(list(seeds))
            self._np_random, self._np_random_seed = gymnasium.utils.seeding.np_random(seeds[0])
        self._worlds.step(None, self._all)
        self._ended[:] = False
        return self._worlds.obs[:, 0][:, self._seen.columns], self._infos()

    def step(
        self, actions: NDArray[np.int64]
    ) -> tuple[NDArray[np.float64], NDArray[Any], NDArray[Any], NDArray[Any], dict[str, Any]]:
        w = self._worlds
        given = np.asarray(actions).reshape(w.action_shape)
        fresh = self._ended.copy()
        w.step(given, fresh)
        terminated = ~w.active[:, 0] & ~fresh
        truncated = w.over & ~terminated & ~fresh
        self._ended = terminated | truncated
        obs = w.obs[:, 0][:, self._seen.columns]
        return obs, w.reward[:, 0].copy(), terminated, truncated, self._infos()

    def _infos(self) -> dict[str, Any]:
        return {"state": self._worlds.state[:, 0].copy()}
