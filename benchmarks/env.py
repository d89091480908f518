"""NanoNav through the RL interfaces: env-steps per second of the single env stepped from a
Python loop (the ecosystem's usual case) beside a bare Gymnasium env (CartPole) in the same run,
of the vector env at N = 1, 100 and 1,000 worlds, and of the swarm env at 1,000 robots (through
PettingZoo's dicts and through its arrays), all with random actions, on one core.

    python benchmarks/env.py            # about two minutes
    python benchmarks/env.py --quick    # a smoke run
    python benchmarks/env.py --against REV   # old (a git revision) and new side by side

``--against`` measures, case by case, the revision and this tree alternately in one run
(``against.py``): the vector env at 1,000 worlds, the swarm env's ``step_arrays`` at 1,000
robots, and ``simulate``'s own loop with one robot and with 1,000 (random behaviours).

Worlds: the single env and the vector env's are 'paper-single' (one robot, one cell, ten
obstacles, the paper's behaviours); the swarm's is 'paper-swarm' with 1,000 robots. A robot that
reaches its cell leaves; a finished world is drawn afresh. A robot-step is one robot moved one
step; figures are medians of 3 repeats, each timing only steps (no numba start-up). Beside
them, ``simulate``'s own compiled loop in the same worlds with behaviours chosen at random, as
the env's random agent chooses them: what stepping from outside costs.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import gymnasium
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from against import side_by_side

from nanonav.engine import simulate
from nanonav.env import NanoNavEnv, NanoNavParallelEnv, NanoNavVectorEnv
from nanonav.scenario import Scenario

SINGLE = {"preset": "paper-single"}
SWARM = {"preset": "paper-swarm", "robots": {"count": 1000}}
VECTOR_WORLDS = (1, 100, 1000)
SWARM_ROBOTS = 1000
TARGET_RATE = 1_000_000  # robot-steps/s: the vector env and the swarm env at 1,000
REPEATS = 3
MAX_CALLS = 50_000  # vector-env steps a repeat: one world's rate settles long before 2 M


def median_rate(run: Callable[[], tuple[int, float]]) -> float:
    """Median over repeats of (robot-steps / seconds) that ``run`` measured."""
    rates = []
    for _ in range(REPEATS):
        steps, seconds = run()
        rates.append(steps / seconds)
    return statistics.median(rates)


def single_env(env: gymnasium.Env, steps: int) -> Callable[[], tuple[int, float]]:
    """A Python loop of ``steps`` env-steps with random actions, resetting as episodes end."""
    actions = np.random.default_rng(0).integers(0, env.action_space.n, steps)  # type: ignore[attr-defined]

    def run() -> tuple[int, float]:
        env.reset(seed=0)
        started = time.perf_counter()
        for action in actions:
            _, _, terminated, truncated, _ = env.step(int(action))
            if terminated or truncated:
                env.reset()
        return steps, time.perf_counter() - started

    return run


def vector_env(
    worlds: int, robot_steps: int, scenario: dict[str, object] = SINGLE
) -> Callable[[], tuple[int, float]]:
    """``robot_steps`` robot-steps (at most MAX_CALLS calls) of the vector env over ``worlds``
    worlds of ``scenario``, random actions drawn each call."""
    env = NanoNavVectorEnv(worlds, scenario)
    rng = np.random.default_rng(0)
    n = env.single_action_space.n

    def run() -> tuple[int, float]:
        env.reset(seed=0)
        calls = max(1, min(robot_steps // worlds, MAX_CALLS))
        started = time.perf_counter()
        for _ in range(calls):
            env.step(rng.integers(0, n, worlds))
        return calls * worlds, time.perf_counter() - started

    return run


def swarm_env(robot_steps: int, arrays: bool) -> Callable[[], tuple[int, float]]:
    env = NanoNavParallelEnv(SWARM)
    rng = np.random.default_rng(0)
    n = len(env.action_labels)

    def run() -> tuple[int, float]:
        env.reset(seed=0)
        done = 0
        started = time.perf_counter()
        while done < robot_steps:
            if not env.agents:
                env.reset()
            live = len(env.agents)
            if arrays:
                env.step_arrays(rng.integers(0, n, SWARM_ROBOTS))
            else:
                choice = rng.integers(0, n, live).tolist()
                env.step(dict(zip(env.agents, choice, strict=True)))
            done += live
        return done, time.perf_counter() - started

    return run


def engine_rate(world: dict[str, object], robot_steps: int) -> float:
    """``simulate``'s own compiled loop in the same world, its robots choosing behaviours at
    random (Q-learning at epsilon 1): what the engine does without an agent outside."""
    robots = int(world.get("robots", {}).get("count", 1))  # type: ignore[attr-defined]
    scenario = Scenario.model_validate(
        {
            **world,
            "learning": {"episodes": max(1, robot_steps // (robots * 1000)), "max_steps": 1000,
                         "epsilon_start": 1.0, "epsilon_end": 1.0},
            "evaluation": {"worlds": 1},
        }
    )  # fmt: skip
    work = simulate(scenario).work
    return float(work["robot_steps"]) / float(work["engine_s"])


# old and new side by side: the figure of each, robot-steps/s
COMPARED: dict[str, Callable[[], float]] = {
    "vector env, 1,000 worlds": lambda: median_rate(vector_env(1000, 2_000_000)),
    "swarm env, step_arrays, 1,000 robots": lambda: median_rate(swarm_env(2_000_000, True)),
    "simulate, one robot, random": lambda: engine_rate(SINGLE, 500_000),
    "simulate, 1,000 robots, random": lambda: engine_rate(SWARM, 2_000_000),
}


def _warm_up() -> None:
    """Compile (or load numba's cache) before any timing."""
    warm = NanoNavVectorEnv(2, SINGLE)
    warm.reset(seed=0)
    warm.step(np.zeros(2, dtype=np.int64))
    engine_rate(SINGLE, 1000)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small workloads")
    parser.add_argument("--against", metavar="REV", help="old (REV) and new side by side, only")
    parser.add_argument("--measure", help=argparse.SUPPRESS)  # one case of --against, as JSON
    args = parser.parse_args(argv)
    if args.measure:
        _warm_up()
        print(COMPARED[args.measure]())
        return 0
    if args.against:
        figures = side_by_side(Path(__file__).resolve(), list(COMPARED), args.against)
        vector = figures["vector env, 1,000 worlds"][1]
        lone = figures["simulate, one robot, random"][1]
        status = "meets" if vector >= lone else "BELOW"
        print(f"{status} target: the vector env at 1,000 worlds, {vector:,.0f}, reaches "
              f"simulate's one-robot speed, {lone:,.0f}")  # fmt: skip
        arrays = figures["swarm env, step_arrays, 1,000 robots"][0]
        own = figures["simulate, 1,000 robots, random"][1]
        status = "meets" if own >= arrays else "BELOW"
        print(f"{status} target: simulate at 1,000 robots, random, {own:,.0f}, reaches what "
              f"step_arrays reached at {args.against}, {arrays:,.0f}")  # fmt: skip
        return 0
    scale = 10 if args.quick else 1
    single_steps = 20_000 // scale
    robot_steps = 2_000_000 // scale

    _warm_up()

    nanonav = median_rate(single_env(NanoNavEnv(SINGLE), single_steps))
    cartpole = median_rate(single_env(gymnasium.make("CartPole-v1").unwrapped, single_steps))
    print("single env, a Python loop (env-steps per second, and the time per step)")
    print(f"  {'NanoNavEnv (paper-single)':32s} {nanonav:>12,.0f}  {1e6 / nanonav:7.1f} us")
    print(f"  {'CartPole-v1 (bare gymnasium)':32s} {cartpole:>12,.0f}  {1e6 / cartpole:7.1f} us")
    print(f"  NanoNav's step costs x{cartpole / nanonav:.1f} CartPole's")
    print()
    print("vector env (robot-steps per second; one robot a world)")
    verdicts = []
    lone = engine_rate(SINGLE, robot_steps // 4)
    for worlds in VECTOR_WORLDS:
        rate = median_rate(vector_env(worlds, robot_steps))
        print(f"  {worlds:>6,} worlds {rate:>14,.0f}  {rate / lone:5.2f} of the engine's own")
        if worlds == 1000:
            verdicts.append(("vector env, 1,000 worlds", rate))
    print(f"  {'simulate, one world':13s} {lone:>14,.0f}  (its own loop, random behaviours)")
    print()
    print(f"swarm env ({SWARM_ROBOTS:,} robots of paper-swarm; robot-steps per second)")
    own = engine_rate(SWARM, robot_steps)
    for label, arrays in (("PettingZoo dicts", False), ("step_arrays", True)):
        rate = median_rate(swarm_env(robot_steps, arrays))
        print(f"  {label:20s} {rate:>14,.0f}  {rate / own:5.2f} of the engine's own")
        verdicts.append((f"swarm env, {SWARM_ROBOTS:,} robots, {label}", rate))
    print(f"  {'simulate':20s} {own:>14,.0f}  (its own loop, random behaviours)")
    print()
    for what, rate in verdicts:
        status = "meets" if rate >= TARGET_RATE else "BELOW"
        print(f"{status} target: {what}, {rate:,.0f} vs {TARGET_RATE:,} robot-steps/s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
