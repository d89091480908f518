"""The swarm as a PettingZoo ``ParallelEnv``: every robot of a scenario an agent, all stepped in
one compiled call."""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray
from pettingzoo import ParallelEnv

from nanonav.env.robot import ScenarioLike
from nanonav.env.worlds import (
    Worlds,
    action_labels,
    as_scenario,
    observation_of,
    state_labels,
)


class NanoNavParallelEnv(ParallelEnv[str, NDArray[np.float64], int]):
    """Every robot of a scenario an agent (``robot_0`` ... in index order), observing, acting
    and rewarded as ``NanoNavEnv``'s one robot (its docstring says what the observation means);
    a robot that reaches a cell is terminated and leaves ``agents`` (it stays bound to the cell,
    in the way of others and releasing its signal); the rest are truncated at the step limit or
    once every cell is treated.

    All robots perceive, then all act on their actions, in index order (``engine.stepping``);
    ``infos[agent]["state"]`` is the agent's tabular state. ``step_arrays`` takes and gives
    arrays indexed by robot instead of dicts, for swarms too large for dicts each step.
    """

    metadata: dict[str, Any] = {"name": "nanonav_swarm_v0", "render_modes": []}  # noqa: RUF012

    def __init__(self, scenario: ScenarioLike = None) -> None:
        self.scenario = as_scenario(scenario)
        self._worlds = Worlds(self.scenario, 1)
        n = self.scenario.robots.count
        self.possible_agents = [f"robot_{i}" for i in range(n)]
        self._index = {agent: i for i, agent in enumerate(self.possible_agents)}
        self.agents: list[str] = []
        self._seen = observation_of(self.scenario)
        self._observation_spaces: dict[str, spaces.Box] = {}
        self._action_spaces: dict[str, spaces.Discrete] = {}
        self.observation_labels = self._seen.labels
        self.action_labels = action_labels(self.scenario)
        self.state_labels = state_labels(self.scenario)
        self._live = np.zeros(n, dtype=np.bool_)
        self._actions = np.zeros((1, n), dtype=np.int64)
        self._fresh = np.ones(1, dtype=np.bool_)
        self._stale = np.zeros(1, dtype=np.bool_)

    def observation_space(self, agent: str) -> spaces.Box:
        space = self._observation_spaces.get(agent)
        if space is None:
            self._index_of(agent)
            space = spaces.Box(self._seen.low, self._seen.high, dtype=np.float64)
            self._observation_spaces[agent] = space
        return space

    def action_space(self, agent: str) -> spaces.Discrete:
        space = self._action_spaces.get(agent)
        if space is None:
            self._index_of(agent)
            space = spaces.Discrete(self._worlds.actions)
            self._action_spaces[agent] = space
        return space

    def _index_of(self, agent: str) -> int:
        index = self._index.get(agent)
        if index is None:
            raise KeyError(f"{agent!r} is not one of this swarm's agents (robot_0 ...)")
        return index

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, NDArray[np.float64]], dict[str, dict[str, Any]]]:
        obs, _, _, _ = self.reset_arrays(seed)
        infos = {
            a: {"state": s}
            for a, s in zip(self.agents, self._worlds.state[0].tolist(), strict=True)
        }
        return dict(zip(self.agents, obs, strict=True)), infos

    def step(self, actions: dict[str, int]) -> tuple[
        dict[str, NDArray[np.float64]], dict[str, float], dict[str, bool], dict[str, bool],
        dict[str, dict[str, Any]],
    ]:  # fmt: skip
        agents = self.agents
        given = np.zeros(len(self.possible_agents), dtype=np.int64)
        try:
            chosen = np.fromiter(map(actions.__getitem__, agents), np.int64, len(agents))
        except KeyError:
            missing = [a for a in agents if a not in actions]
            raise ValueError(f"no action for live agent(s) {missing[:5]}") from None
        live = np.flatnonzero(self._live)
        given[live] = chosen
        obs, rewards, terminated, truncated = self.step_arrays(given)
        states = self._worlds.state[0, live].tolist()
        # most agents are neither terminated nor truncated: those few are set after
        ended = dict.fromkeys(agents, False)
        cut = ended.copy()
        for i in np.flatnonzero(terminated).tolist():
            ended[self.possible_agents[i]] = True
        for i in np.flatnonzero(truncated).tolist():
            cut[self.possible_agents[i]] = True
        return (
            dict(zip(agents, obs[live], strict=True)),
            dict(zip(agents, rewards[live].tolist(), strict=True)),
            ended,
            cut,
            {a: {"state": s} for a, s in zip(agents, states, strict=True)},
        )

    def reset_arrays(self, seed: int | None = None) -> tuple[NDArray[Any], ...]:
        """``reset`` in arrays indexed by robot: (observations, rewards, terminated,
        truncated), the last three all zero."""
        if seed is not None:
            self._worlds.seed([seed])
        w = self._worlds
        w.step(None, self._fresh)
        self._live[:] = True
        self.agents = self.possible_agents[:]
        n = len(self.possible_agents)
        zeros = np.zeros(n, dtype=np.bool_)
        return w.obs[0][:, self._seen.columns], np.zeros(n), zeros, zeros.copy()

    def step_arrays(self, actions: NDArray[np.int64]) -> tuple[NDArray[Any], ...]:
        """``step`` in arrays indexed by robot: ``actions[i]`` robot i's (unused for a robot
        that is done); returns (observations, rewards, terminated, truncated) of every robot,
        of which those live before the step count."""
        if not self.agents:
            raise RuntimeError("every agent is done (or the swarm never began): call reset()")
        self._actions[0] = actions
        w = self._worlds
        w.step(self._actions, self._stale)
        live = self._live
        terminated = live & ~w.active[0]
        truncated = live & w.active[0] & w.over[0]
        done = terminated | truncated
        if done.any():
            self._live = live & ~done
            self.agents = list(
                map(self.possible_agents.__getitem__, np.flatnonzero(self._live).tolist())
            )
        return (
            w.obs[0][:, self._seen.columns],
            np.where(live, w.reward[0], 0.0),
            terminated,
            truncated,
        )
