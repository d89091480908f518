"""The swarm as PettingZoo agents: ``NanoNavParallelEnv`` (every robot perceives, then every
robot acts: the simultaneous schedule) and ``SwarmSpaces``, the agents, spaces and labels it
shares with ``turns.NanoNavAECEnv`` (one robot at a time: the sequential schedule)."""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray
from pettingzoo import ParallelEnv

from nanonav.engine.observations import action_labels, as_scenario, observation_of, state_labels
from nanonav.engine.worlds import Worlds
from nanonav.env.robot import ScenarioLike, action_space_of, turn_of
from nanonav.scenario import Schedule, Steering


class SwarmSpaces:
    """Every robot of a scenario an agent (``robot_0`` ... in index order) in one world stepped
    under ``schedule``, observing and acting as ``NanoNavEnv``'s one robot (its docstring says
    what the observation means, and ``steering``): the agents, their spaces (one object per
    agent, made once) and the labels of observations, actions and tabular states."""

    def __init__(
        self, scenario: ScenarioLike, schedule: Schedule, steering: Steering = "discrete"
    ) -> None:
        self.scenario = as_scenario(scenario)
        self._worlds = Worlds(self.scenario, 1, schedule, steering=steering)
        n = self.scenario.robots.count
        self.possible_agents = [f"robot_{i}" for i in range(n)]
        self._index = {agent: i for i, agent in enumerate(self.possible_agents)}
        self.agents: list[str] = []
        self._seen = observation_of(self.scenario, steering)
        self._observation_spaces: dict[str, spaces.Box] = {}
        self._action_spaces: dict[str, spaces.Discrete | spaces.Box] = {}
        self.observation_labels = self._seen.labels
        self.action_labels = action_labels(self.scenario, steering)
        # what a step's actions are: action numbers, or a turn (side, up) per robot
        self._actions = self._worlds.blank_actions()
        self.state_labels = state_labels(self.scenario)

    def observation_space(self, agent: str) -> spaces.Box:
        space = self._observation_spaces.get(agent)
        if space is None:
            self._index_of(agent)
            space = spaces.Box(self._seen.low, self._seen.high, dtype=np.float64)
            self._observation_spaces[agent] = space
        return space

    def action_space(self, agent: str) -> spaces.Discrete | spaces.Box:
        space = self._action_spaces.get(agent)
        if space is None:
            self._index_of(agent)
            space = action_space_of(self._worlds)
            self._action_spaces[agent] = space
        return space

    def _index_of(self, agent: str) -> int:
        index = self._index.get(agent)
        if index is None:
            raise KeyError(f"{agent!r} is not one of this swarm's agents (robot_0 ...)")
        return index


class NanoNavParallelEnv(SwarmSpaces, ParallelEnv[str, NDArray[np.float64], Any]):
    """Every robot of a scenario an agent (``robot_0`` ... in index order), observing, acting
    and rewarded as ``NanoNavEnv``'s one robot (its docstring says what the observation means);
    a robot that reaches a cell is terminated and leaves ``agents`` (it stays bound to the cell,
    in the way of others and releasing its signal); the rest are truncated at the step limit or
    once every cell is treated.

    All robots perceive, then all act on their actions, in index order (the simultaneous
    schedule, whatever the scenario's: ``engine.stepping``);
    ``infos[agent]["state"]`` is the agent's tabular state. ``step_arrays`` takes and gives
    arrays indexed by robot instead of dicts, for swarms too large for dicts each step.
    """

    metadata: dict[str, Any] = {"name": "nanonav_swarm_v0", "render_modes": []}  # noqa: RUF012

    def __init__(self, scenario: ScenarioLike = None, *, steering: Steering = "discrete") -> None:
        SwarmSpaces.__init__(self, scenario, "simultaneous", steering)
        # the robots of ``agents``, in order: what a step gives back is read at these
        self._live = np.zeros(0, dtype=np.int64)
        self._fresh = np.ones(1, dtype=np.bool_)
        self._stale = np.zeros(1, dtype=np.bool_)

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, NDArray[np.float64]], dict[str, dict[str, Any]]]:
        self._begin(seed)
        agents = self.agents
        w = self._worlds
        observations = dict(zip(agents, w.obs[0][:, self._seen.columns], strict=True))
        return observations, self._infos(w.state[0].tolist())

    def step(self, actions: dict[str, Any]) -> tuple[
        dict[str, NDArray[np.float64]], dict[str, float], dict[str, bool], dict[str, bool],
        dict[str, dict[str, Any]],
    ]:  # fmt: skip
        agents, live = self.agents, self._live
        self._actions[0, live] = self._chosen(actions, agents)
        ended, over = self._advance()
        w = self._worlds
        observations = dict(zip(agents, w.obs[0, live][:, self._seen.columns], strict=True))
        rewards = dict(zip(agents, w.reward[0, live].tolist(), strict=True))
        infos = self._infos(w.state[0, live].tolist())
        # most agents are neither terminated nor truncated: those few are set after
        terminated = dict.fromkeys(agents, False)
        truncated = dict.fromkeys(agents, True) if over else terminated.copy()
        for i in np.flatnonzero(ended).tolist():
            terminated[agents[i]] = True
            truncated[agents[i]] = False
        self._leave(ended, over)
        return observations, rewards, terminated, truncated, infos

    def _chosen(self, actions: dict[str, Any], agents: list[str]) -> NDArray[Any]:
        """The live agents' actions, in order, as integers of the action set, or steering
        continuously as turns (a missing one, or one that is not such, is refused naming its
        agent)."""
        if self._worlds.continuous:
            turns = []
            for agent in agents:
                if agent not in actions:
                    raise ValueError(f"no action for live agent {agent}")
                try:
                    turns.append(turn_of(actions[agent]))
                except ValueError as error:
                    raise ValueError(f"{agent}'s {error}") from None
            return np.array(turns).reshape(len(agents), 2)
        if len(actions) == len(agents) and list(actions) == agents:
            given = np.array(list(actions.values()))  # the usual dict, keyed as agents are
        else:
            try:
                given = np.array(list(map(actions.__getitem__, agents)))
            except KeyError:
                missing = [a for a in agents if a not in actions]
                raise ValueError(f"no action for live agent(s) {missing[:5]}") from None
        if not self._worlds.in_action_set(given):
            count = self._worlds.actions
            for agent in agents:
                action = actions[agent]
                if not isinstance(action, (int, np.integer)) or not 0 <= action < count:
                    raise ValueError(
                        f"{agent}'s action {action!r} is not an integer of 0..{count - 1}"
                    )
        return given.astype(np.int64, copy=False)

    def _infos(self, states: list[int]) -> dict[str, dict[str, Any]]:
        return {agent: {"state": state} for agent, state in zip(self.agents, states, strict=True)}

    def _begin(self, seed: int | None) -> None:
        if seed is not None:
            self._worlds.seed([seed])
        self._worlds.step(None, self._fresh)
        self._live = np.arange(len(self.possible_agents))
        self.agents = self.possible_agents[:]

    def _advance(self) -> tuple[NDArray[np.bool_], bool]:
        """Step the world on ``_actions``; returns which live agents (in ``agents``' order)
        reached a cell this step, and whether the episode is over."""
        if not self.agents:
            raise RuntimeError("every agent is done (or the swarm never began): call reset()")
        w = self._worlds
        w.step(self._actions, self._stale, checked=True)
        ended: NDArray[np.bool_] = ~w.active[0, self._live]
        return ended, bool(w.over[0])

    def _leave(self, ended: NDArray[np.bool_], over: bool) -> None:
        """Agents that reached a cell, or all once the episode is over, leave ``agents``."""
        if over:
            self._live = self._live[:0]
            self.agents = []
        elif ended.any():
            self._live = self._live[~ended]
            self.agents = list(map(self.possible_agents.__getitem__, self._live.tolist()))

    def reset_arrays(self, seed: int | None = None) -> tuple[NDArray[Any], ...]:
        """``reset`` in arrays indexed by robot: (observations, rewards, terminated,
        truncated), the last three all zero."""
        self._begin(seed)
        n = len(self.possible_agents)
        zeros = np.zeros(n, dtype=np.bool_)
        return self._worlds.obs[0][:, self._seen.columns], np.zeros(n), zeros, zeros.copy()

    def step_arrays(self, actions: NDArray[np.int64]) -> tuple[NDArray[Any], ...]:
        """``step`` in arrays indexed by robot: ``actions[i]`` robot i's (unused for a robot
        that is done; steering continuously, ``actions`` is robots x 2 turns); returns
        (observations, rewards, terminated, truncated) of every robot, of which those live
        before the step count."""
        given = np.asarray(actions)
        n = len(self.possible_agents)
        self._worlds.check(given, self._worlds.action_shape[1:])
        self._actions[0] = given
        live = self._live
        ended, over = self._advance()
        w = self._worlds
        terminated = np.zeros(n, dtype=np.bool_)
        terminated[live[ended]] = True
        truncated = np.zeros(n, dtype=np.bool_)
        if over:
            truncated[live[~ended]] = True
        rewards = np.zeros(n)
        rewards[live] = w.reward[0, live]
        self._leave(ended, over)
        return w.obs[0][:, self._seen.columns], rewards, terminated, truncated
