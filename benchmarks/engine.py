"""Engine throughput: robot-steps per second of ``simulate`` for swarms of 1, 15, 100 and 1,000
robots under each field model, beside a naive per-robot Python loop of the same physics, measured
in the same run so that every ratio compares like with like.

    python benchmarks/engine.py            # the full tables (about four minutes)
    python benchmarks/engine.py --quick    # a smoke run with small workloads
    python benchmarks/engine.py --against REV   # old (a git revision) and new side by side

``--against`` measures, case by case, the revision and this tree alternately in one run
(``against.py``): ``simulate`` at 15 and 1,000 robots in both physics and for each kind of
policy, and the swarm with exclusion at 10,000 robots.

The third table is the swarm's: robots that take up space (exclusion), and exclusion with
signalling (an attractant and a repellent on the grid, or broadcast), from 100 to 100,000
robots at the same density (the cube grows with the swarm), 20 cells that can be treated.

Scenario: 2 cells x 50 emitters, 10 obstacles, q_learning with the paper's behaviours, 1,000-step
episodes. Figures are medians over repeats; ``engine_s`` excludes numba's start-up.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from against import side_by_side
from naive import naive_robot_steps_per_second

from nanonav.engine import simulate
from nanonav.scenario import Physics, Scenario

MODELS = ("gaussian", "inverse_square", "diffusion")
SWARMS = (1, 15, 100, 1000)
# Targets on one core: absolute at 1,000 robots, ratios to the naive loop at 15 and 1.
TARGET_RATE_1000 = 1_000_000
TARGET_RATIO = {15: 300, 1: 50}
# The swarm's targets: 1 M robot-steps/s at 10,000 robots with exclusion; within a factor of 2
# from 1,000 to 100,000 robots (the cost per robot-step does not grow with the swarm).
SWARM_SIZES = (100, 1_000, 10_000, 100_000)
TARGET_SWARM_RATE = 1_000_000
TARGET_SWARM_SPREAD = 2.0
SWARM_CONFIGS = {
    "exclusion": {},
    "exclusion + attractant_repellent": {"communication": {"model": "attractant_repellent"}},
    "exclusion + broadcast": {"communication": {"model": "broadcast"}},
}


def bench_scenario(model: str, robots: int, robot_steps: int) -> Scenario:
    episodes = max(1, robot_steps // (robots * 150))
    return Scenario.model_validate(
        {
            "cells": {"count": 2},
            "biomarker": {"model": model, "emitters_per_cell": 50},
            "obstacles": {"count": 10},
            "robots": {"count": robots, "policy": "q_learning"},
            "learning": {"episodes": episodes, "max_steps": 1000},
            # one greedy evaluation world, as the speed figures were first measured
            "evaluation": {"worlds": 1},
        }
    )


def brownian_scenario(policy: str, robots: int, robot_steps: int) -> Scenario:
    """The same swarm and world sizes in the active Brownian physics: 1 um robots swimming at
    10 um/s among 10 obstacles of 5 um, 2 cells, a 200 um cube, 1,000 steps of 0.01 s."""
    episodes = max(1, robot_steps // (robots * 150))
    physics = {"model": "active_brownian"}
    if "sensor" in Physics.model_fields:
        # a reading each step, as in every revision measured beside this one and in the naive
        # loop and the C program: the same work whichever the default sensor
        physics["sensor"] = "each_step"
    return Scenario.model_validate(
        {
            "physics": physics,
            "space": {"size": 200.0},
            "cells": {"count": 2},
            "obstacles": {"count": 10, "radius": 5.0},
            "robots": {"count": robots, "policy": policy},
            "learning": {"episodes": episodes, "max_steps": 1000},
            "evaluation": {"worlds": 1},
        }
    )


def swarm_scenario(config: str, robots: int, robot_steps: int) -> Scenario:
    """Q-learning robots (the paper's behaviours, a shared table) that take up space, in a
    cube whose volume grows with the swarm (50 units a side at 1,000 robots), 20 cells each
    treated by 10 payloads, 100-step episodes (fewer when every cell is treated)."""
    size = min(1000.0, 50.0 * (robots / 1000) ** (1 / 3))
    episodes = max(1, robot_steps // (robots * 100))
    return Scenario.model_validate(
        {
            "space": {"size": size},
            "cells": {"count": 20, "capacity": 10},
            "obstacles": {"count": 10},
            "robots": {"count": robots, "policy": "q_learning", "exclusion": True},
            "learning": {"episodes": episodes, "max_steps": 100},
            "evaluation": {"worlds": 1},
            **SWARM_CONFIGS[config],
        }
    )


def with_policy(scenario: Scenario, policy: str) -> Scenario:
    data = scenario.model_dump(mode="json")
    data["robots"]["policy"] = policy
    return Scenario.model_validate(data)


# old and new side by side: the figure of each, robot-steps/s
COMPARED = {
    "lattice, q_learning, 15 robots": lambda: bench_scenario("gaussian", 15, 400_000),
    "lattice, q_learning, 1,000 robots": lambda: bench_scenario("gaussian", 1000, 400_000),
    "lattice, rule, 1,000 robots": lambda: with_policy(
        bench_scenario("gaussian", 1000, 400_000), "rule"
    ),
    "lattice, random, 1,000 robots": lambda: with_policy(
        bench_scenario("gaussian", 1000, 400_000), "random"
    ),
    "active_brownian, q_learning, 15 robots": lambda: brownian_scenario("q_learning", 15, 400_000),
    "active_brownian, q_learning, 1,000": lambda: brownian_scenario("q_learning", 1000, 400_000),
    "active_brownian, run_and_tumble, 1,000": lambda: brownian_scenario(
        "run_and_tumble", 1000, 400_000
    ),
    "active_brownian, gradient, 1,000": lambda: brownian_scenario("gradient", 1000, 400_000),
    "exclusion, 10,000 robots": lambda: swarm_scenario("exclusion", 10_000, 3_000_000),
}


def engine_rate(scenario: Scenario, repeats: int) -> tuple[float, int]:
    rates = []
    steps = 0
    for seed in range(repeats):
        result = simulate(scenario.model_copy(update={"seed": seed}))
        rates.append(result.work["robot_steps"] / result.work["engine_s"])
        steps = result.work["robot_steps"]
    return statistics.median(rates), steps


# long: a benchmark's command line and its printed table, in order
def main(argv: list[str] | None = None) -> int:  # noqa: C901  # a flag a branch, read in order
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small workloads, one repeat")
    parser.add_argument("--models", default=",".join(MODELS), help="comma-separated models")
    parser.add_argument(
        "--robots", default=",".join(map(str, SWARMS)), help="comma-separated swarm sizes"
    )
    parser.add_argument(
        "--swarm-robots",
        default=",".join(map(str, SWARM_SIZES)),
        help="comma-separated sizes of the swarm's table",
    )
    parser.add_argument("--skip-fields", action="store_true", help="only the swarm's table")
    parser.add_argument("--against", metavar="REV", help="old (REV) and new side by side, only")
    parser.add_argument("--measure", help=argparse.SUPPRESS)  # one case of --against, as JSON
    args = parser.parse_args(argv)
    if args.measure:
        simulate(bench_scenario("gaussian", 1, 1000))  # start-up, not timed
        print(engine_rate(COMPARED[args.measure](), 3)[0])
        return 0
    if args.against:
        figures = side_by_side(Path(__file__).resolve(), list(COMPARED), args.against)
        new = figures["exclusion, 10,000 robots"][1]
        status = "meets" if new >= TARGET_SWARM_RATE else "BELOW"
        print(f"{status} target: exclusion, 10,000 robots, {new:,.0f} vs {TARGET_SWARM_RATE:,}")
        slower = [case for case, (o, n) in figures.items() if n < o]
        print(f"slower than {args.against}: {', '.join(slower) or 'none'}")
        return 0
    models = args.models.split(",")
    swarms = [int(n) for n in args.robots.split(",")]
    workload = 20_000 if args.quick else 400_000
    repeats = 1 if args.quick else 3
    naive_seconds = 0.2 if args.quick else 1.0

    simulate(bench_scenario("gaussian", 1, 1000))  # start-up: compile or load numba's cache
    print(f"cpu cores visible: {os.cpu_count()}, numba threads: 1 (the engine is single-threaded)")
    header = f"{'model':<15}{'robots':>7}{'engine rs/s':>14}{'naive rs/s':>12}{'ratio':>9}"
    verdicts: list[tuple[str, int, str, float, int]] = []
    if args.skip_fields:
        models = []
    else:
        print(header)
        print("-" * len(header))
    for model in models:
        for robots in swarms:
            scenario = bench_scenario(model, robots, workload)
            rate, _ = engine_rate(scenario, repeats)
            naive = naive_robot_steps_per_second(scenario, naive_seconds)
            ratio = rate / naive
            print(f"{model:<15}{robots:>7}{rate:>14,.0f}{naive:>12,.0f}{ratio:>8,.0f}x")
            if robots == 1000:
                verdicts.append((model, robots, "rate", rate, TARGET_RATE_1000))
            if robots in TARGET_RATIO:
                verdicts.append((model, robots, "ratio", ratio, TARGET_RATIO[robots]))
    # the second physics beside the first, in the same run
    beside = [] if args.skip_fields else [n for n in swarms if n in (15, 1000)] or swarms[-1:]
    if beside:
        print()
        print(f"{'physics, policy':<34}{'robots':>7}{'engine rs/s':>14}{'vs lattice':>12}")
        print("-" * 67)
    for robots in beside:
        lattice, _ = engine_rate(bench_scenario("diffusion", robots, workload), repeats)
        print(f"{'lattice, q_learning (diffusion)':<34}{robots:>7}{lattice:>14,.0f}{'1.00':>12}")
        for policy in ("q_learning", "run_and_tumble", "gradient"):
            rate, _ = engine_rate(brownian_scenario(policy, robots, workload), repeats)
            label = f"active_brownian, {policy}"
            print(f"{label:<34}{robots:>7}{rate:>14,.0f}{rate / lattice:>12.2f}")
            if robots == 1000:
                verdicts.append((label, robots, "rate", rate, TARGET_RATE_1000))
    print()
    print(f"{'the swarm':<34}{'robots':>7}{'engine rs/s':>14}")
    print("-" * 55)
    sizes = [int(n) for n in args.swarm_robots.split(",")]
    spreads: list[tuple[str, float]] = []
    if args.quick:
        sizes = [n for n in sizes if n <= 10_000]
    for config in SWARM_CONFIGS:
        rates = {}
        for robots in sizes:
            load = max(workload, 3 * robots * 100)  # three training episodes at least
            rate, _ = engine_rate(swarm_scenario(config, robots, load), repeats)
            rates[robots] = rate
            print(f"{config:<34}{robots:>7}{rate:>14,.0f}")
            if robots == 10_000 and config == "exclusion":
                verdicts.append((config, robots, "rate", rate, TARGET_SWARM_RATE))
        if 1_000 in rates and 100_000 in rates:
            spread = max(rates[1_000], rates[100_000]) / min(rates[1_000], rates[100_000])
            print(f"{'':<34}{'1,000 vs 100,000: x':>21}{spread:.2f}")
            spreads.append((config, spread))
    print()
    for model, robots, kind, value, target in verdicts:
        status = "meets" if value >= target else "BELOW"
        print(f"{status} target: {model}, {robots} robots, {kind} {value:,.0f} vs {target:,}")
    for config, spread in spreads:
        status = "meets" if spread <= TARGET_SWARM_SPREAD else "BELOW"
        print(f"{status} target: {config}, 1,000 to 100,000 robots within x{spread:.2f} "
              f"(at most x{TARGET_SWARM_SPREAD:g})")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
