"""``simulate`` and the environments run one step under two schedules: a greedy table trained by
``simulate``, driven from outside through the env of the scenario's schedule (``NanoNavAECEnv``
for the sequential one, ``NanoNavParallelEnv`` for the simultaneous one), reproduces
``simulate``'s evaluation of the same table world for world, in every preset and every
communication model of both physics, with noise, treatment and exclusion, and with decisions
held over an interval."""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray
from pettingzoo.test import api_test, seed_test

from nanonav.engine import simulate
from nanonav.engine.result import SimulationResult
from nanonav.env import NanoNavAECEnv, NanoNavParallelEnv
from nanonav.scenario import PRESETS, Scenario, deep_merge

pytestmark = pytest.mark.timeout(600)

SHORT: dict[str, Any] = {"learning": {"episodes": 3, "max_steps": 80}, "evaluation": {"worlds": 3}}
SHORT_SI: dict[str, Any] = {
    "physics": {"time_limit_s": 10.0},
    "learning": {"episodes": 2},
    "evaluation": {"worlds": 2},
    # a small space, where swimmers reach the cell (and bind, and signal) in a short run
    "space": {"size": 40.0},
    "obstacles": {"count": 1},
}
SWARM: dict[str, Any] = {"robots": {"count": 6}, "cells": {"count": 2, "capacity": 1}}


def _merge(*parts: dict[str, Any]) -> dict[str, Any]:
    return functools.reduce(deep_merge, parts, {})


def _cases() -> dict[str, dict[str, Any]]:
    cases: dict[str, dict[str, Any]] = {}
    for name, preset in PRESETS.items():
        brownian = preset.get("physics", {}).get("model") == "active_brownian"
        robots = min(preset.get("robots", {}).get("count", 1), 8)
        short = SHORT_SI if brownian else SHORT
        cases[name] = _merge(
            {"preset": name}, short, {"robots": {"count": robots, "policy": "q_learning"}}
        )
    for physics, short in (("lattice", SHORT), ("active_brownian", SHORT_SI)):
        base = {"physics": {"model": physics}}
        for model in ("attractant", "attractant_repellent", "broadcast"):
            cases[f"{physics} {model}"] = _merge(
                base, short, SWARM, {"communication": {"model": model}}
            )
        cases[f"{physics} exclusion, noise, per-robot tables"] = _merge(
            base,
            short,
            SWARM,
            {
                # crowded, so that robots bump
                "robots": {"count": 16, "exclusion": True},
                "space": {"size": 10.0 if physics == "lattice" else 25.0},
                "learning": {"shared_table": False},
                "biomarker": {"noise_floor": 0.05} if physics == "lattice" else {},
                "cells": {"motion_std": 0.1} if physics == "lattice" else {},
            },
        )
    # decisions held over an interval: the robots keep to their actions between decisions
    held = {"learning": {"decision_interval_s": 0.1}}
    cases["active_brownian decision interval, exclusion"] = _merge(
        {"physics": {"model": "active_brownian"}}, SHORT_SI, SWARM, held,
        {"robots": {"count": 16, "exclusion": True}, "space": {"size": 25.0}},
    )  # fmt: skip
    cases["active_brownian decision interval, attractant"] = _merge(
        {"physics": {"model": "active_brownian"}}, SHORT_SI, SWARM, held,
        {"communication": {"model": "attractant"}},
    )  # fmt: skip
    cases["tumour-microswimmers decision interval"] = _merge(
        cases["tumour-microswimmers"], {"learning": {"decision_interval_s": 0.5}}
    )
    return cases


CASES = _cases()


def _greedy(scenario: Scenario) -> NDArray[np.float64]:
    """A table trained by ``simulate``, made greedy without ties (its first best action 1, the
    rest 0): the engine breaks ties at random, from a generator no agent outside shares."""
    table = simulate(scenario).qtable
    assert table is not None
    values = np.asarray(table.values)
    greedy = np.zeros_like(values)
    np.put_along_axis(greedy, values.argmax(axis=-1)[..., None], 1.0, axis=-1)
    return greedy


def _choice(table: NDArray[np.float64], robot: int, state: int) -> int:
    row = table[robot, state] if table.ndim == 3 else table[state]
    return int(row.argmax())


def _evaluated(scenario: Scenario, table: NDArray[np.float64]) -> SimulationResult:
    evaluated = scenario.model_copy(
        update={"learning": scenario.learning.model_copy(update={"episodes": 0})}
    )
    return simulate(evaluated, policy=table)


def _turns(scenario: Scenario, table: NDArray[np.float64], worlds: int) -> list[NDArray[Any]]:
    """Each robot's return in each world, the table acting through the AEC env."""
    env = NanoNavAECEnv(scenario)
    out = []
    for k in range(worlds):
        env.reset(seed=scenario.seed) if k == 0 else env.reset()
        returns = np.zeros(len(env.possible_agents))
        for agent in env.agent_iter():
            _, reward, terminated, truncated, info = env.last()
            i = env.possible_agents.index(agent)
            returns[i] += reward
            done = terminated or truncated
            env.step(None if done else _choice(table, i, info["state"]))
        out.append(returns)
    return out


def _parallel(scenario: Scenario, table: NDArray[np.float64], worlds: int) -> list[NDArray[Any]]:
    """Each robot's return in each world, the table acting through the parallel env."""
    env = NanoNavParallelEnv(scenario)
    out = []
    for k in range(worlds):
        _, infos = env.reset(seed=scenario.seed) if k == 0 else env.reset()
        returns = np.zeros(len(env.possible_agents))
        while env.agents:
            actions = {
                a: _choice(table, env.possible_agents.index(a), infos[a]["state"])
                for a in env.agents
            }
            _, rewards, _, _, infos = env.step(actions)
            for agent, reward in rewards.items():
                returns[env.possible_agents.index(agent)] += reward
        out.append(returns)
    return out


@pytest.mark.parametrize("schedule", ["sequential", "simultaneous"])
@pytest.mark.parametrize("case", sorted(CASES))
def test_a_greedy_table_through_the_env_of_its_schedule_reproduces_simulate(
    case: str, schedule: str
) -> None:
    scenario = Scenario.model_validate(deep_merge(CASES[case], {"robots": {"schedule": schedule}}))
    table = _greedy(scenario)
    result = _evaluated(scenario, table)
    drive = _turns if schedule == "sequential" else _parallel
    returns = drive(scenario, table, len(result.worlds))
    for k, (world, got) in enumerate(zip(result.worlds, returns, strict=True)):
        assert float(np.mean(got)) == pytest.approx(world["mean_return"], rel=1e-12, abs=1e-12), k
    # robot for robot in the first world
    for robot, got in zip(result.robots, returns[0], strict=True):
        assert got == pytest.approx(robot["return"], rel=1e-12, abs=1e-12), robot["robot"]


def test_the_cases_reach_cells_treat_them_and_bump() -> None:
    """The comparison above means something: robots reach cells in most cases, the swarms
    treat cells (and so signal), and robots that take up space bump."""
    worlds = {case: simulate(Scenario.model_validate(CASES[case])).worlds for case in CASES}
    reached = {case: sum(w["reached"] for w in got) for case, got in worlds.items()}
    assert sum(1 for n in reached.values() if n > 0) >= 12, reached
    for case, got in worlds.items():
        if "capacity" in CASES[case].get("cells", {}):
            assert sum(w["cells_treated"] for w in got) > 0, case
        if "exclusion" in case:
            assert sum(w["bumps"] for w in got) > 0, case


# it draws nothing: the service draws a job's pictures
@pytest.mark.filterwarnings("ignore:Environment has not defined a render")
def test_the_aec_env_passes_pettingzoos_checkers() -> None:
    scenario = _merge(CASES["lattice attractant"], {"learning": {"max_steps": 40}})
    api_test(NanoNavAECEnv(scenario), num_cycles=200)
    seed_test(lambda: NanoNavAECEnv(scenario), num_cycles=100)
