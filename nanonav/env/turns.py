"""The swarm as a PettingZoo ``AECEnv``: robots take turns, the sequential schedule that
``simulate`` runs by default (the paper's), so a policy trained here meets the order of draws
and moves the service evaluates it in."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from pettingzoo import AECEnv

from nanonav.env.robot import ScenarioLike, turn_of
from nanonav.env.swarm import SwarmSpaces
from nanonav.scenario import Steering


class NanoNavAECEnv(SwarmSpaces, AECEnv[str, NDArray[np.float64], Any]):
    """Every robot of a scenario an agent (``robot_0`` ... in index order), observing, acting
    and rewarded as ``NanoNavEnv``'s one robot, one at a time: the robot whose turn it is
    (``agent_selection``) has just perceived; it acts, then the next active robot perceives,
    seeing what the robots before it did in the same step (a cell treated, a message sent, a
    place taken). When the last robot of a step has acted the world's next step begins (cells
    drift, the field is read). This is the sequential schedule (``engine.stepping``), whatever
    the scenario's.

    ``rewards`` after a move: the mover's reward, and a reach reward for a robot a drifting
    cell arrived at while it waited; ``last()`` gives the selected agent's reward summed since
    its last turn. A robot that reaches a cell is terminated, the rest truncated at the step
    limit or once every cell is treated; as PettingZoo's AEC API asks, a done agent is stepped
    once with ``None`` to leave ``agents``. ``infos[agent]["state"]`` is the tabular state it
    perceived last, and ``observe(agent)`` what it perceived last (the selected agent's is of
    this turn).
    """

    metadata: dict[str, Any] = {"name": "nanonav_turns_v0", "render_modes": []}  # noqa: RUF012

    def __init__(self, scenario: ScenarioLike = None, *, steering: Steering = "discrete") -> None:
        SwarmSpaces.__init__(self, scenario, "sequential", steering)
        self._fresh = np.ones(1, dtype=np.bool_)
        self._stale = np.zeros(1, dtype=np.bool_)
        self.rewards: dict[str, float] = {}
        self._cumulative_rewards: dict[str, float] = {}
        self.terminations: dict[str, bool] = {}
        self.truncations: dict[str, bool] = {}
        self.infos: dict[str, dict[str, Any]] = {}
        self.agent_selection = ""

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None) -> None:
        w = self._worlds
        if seed is not None:
            w.seed([seed])
        w.step(None, self._fresh)
        self.agents = self.possible_agents[:]
        self.rewards = dict.fromkeys(self.agents, 0.0)
        self._cumulative_rewards = dict.fromkeys(self.agents, 0.0)
        self.terminations = dict.fromkeys(self.agents, False)
        self.truncations = dict.fromkeys(self.agents, False)
        self.infos = {agent: {"state": 0} for agent in self.agents}
        self._skip_agent_selection = None
        self._after_move()

    def observe(self, agent: str) -> NDArray[np.float64]:
        observed: NDArray[np.float64] = self._worlds.obs[0, self._index_of(agent)][
            self._seen.columns
        ]
        return observed

    def step(self, action: Any) -> None:
        agent = self.agent_selection
        if not self.agents:
            raise RuntimeError("every agent is done (or the swarm never began): call reset()")
        if self.terminations[agent] or self.truncations[agent]:
            self._was_dead_step(action)
            return
        i = self._index[agent]
        if self._worlds.continuous:
            try:
                self._actions[0, i] = turn_of(action)
            except ValueError as error:
                raise ValueError(f"{agent}'s {error}") from None
        else:
            count = self._worlds.actions
            if not isinstance(action, (int, np.integer)) or not 0 <= action < count:
                raise ValueError(f"{agent}'s action {action!r} is not an integer of 0..{count - 1}")
            self._actions[0, i] = action
        self._cumulative_rewards[agent] = 0.0
        self._worlds.step(self._actions, self._stale, checked=True)
        self._after_move()

    def _after_move(self) -> None:
        """Read the world after a move (or a reset): rewards, who is done, whose turn it is."""
        w = self._worlds
        over = bool(w.over[0])
        active = w.active[0]
        reward = w.reward[0]
        for agent in self.agents:
            if self.terminations[agent] or self.truncations[agent]:
                self.rewards[agent] = 0.0
                continue
            i = self._index[agent]
            self.rewards[agent] = float(reward[i])
            if not active[i]:
                self.terminations[agent] = True
            elif over:
                self.truncations[agent] = True
        self._accumulate_rewards()
        turn = w.turn(0)
        if turn >= 0:
            self.agent_selection = self.possible_agents[turn]
            self.infos[self.agent_selection] = {"state": int(w.state[0, turn])}
        self._deads_step_first()
