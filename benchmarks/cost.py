"""How well ``Scenario.work`` tracks run time: seconds per 10^9 work units over a spread of
scenarios (1 to 1,000 robots, 2 to 100,000 field sources, 0 to 1,000 obstacles, still or moving,
every policy), measured in one run.

    python benchmarks/cost.py            # the full table (about a minute)
    python benchmarks/cost.py --quick    # a smoke run: a tenth of the episodes, steps and worlds

``Scenario.work`` is a bound: every robot active for every step. Runs end early when robots reach
their cells, so each row divides the engine's time by the work of what actually ran
(``Scenario.work_for`` with the run's own counts); "bound" is how much of ``work`` it used. A
work unit is meant to be a nanosecond of one core here, so "s/1e9" near 1 means the weights fit
this machine; what matters is that it stays alike across rows (the max/min ratio). "C" is the
per-robot-step overhead, in units, that would make the row exact, shown where it is at least a
quarter of the work (``WORK_ROBOT_STEP`` holds C per policy).
"""

from __future__ import annotations

import argparse
import math
import os
from dataclasses import dataclass
from typing import Any

from nanonav.engine import simulate
from nanonav.scenario import Evaluation, Scenario

# A job may take this long on one core; the suggested budget follows from the dearest row.
TARGET_JOB_S = 600.0


def case(
    robots: int,
    episodes: int,
    *,
    max_steps: int = 1000,
    policy: str = "q_learning",
    actions: str = "behaviors",
    model: str = "gaussian",
    cells: int = 2,
    emitters: int = 50,
    obstacles: int = 10,
    obstacle_motion: float = 0.0,
) -> dict[str, Any]:
    """Scenario fields: the defaults but for what a row varies."""
    return {
        "robots": {"count": robots, "policy": policy},
        "cells": {"count": cells},
        "biomarker": {"model": model, "emitters_per_cell": emitters},
        "obstacles": {"count": obstacles, "motion_std": obstacle_motion},
        "learning": {"episodes": episodes, "max_steps": max_steps, "actions": actions},
    }


# Each run takes a quarter to half a second here (the cheapest robot-steps need about a million
# for that); the first eight rows are bound by the per-robot-step overhead.
SPREAD: list[tuple[str, dict[str, Any]]] = [
    ("1 robot", case(1, 8000)),
    ("15 robots", case(15, 900)),
    ("100 robots", case(100, 150)),
    ("1000 robots", case(1000, 8)),
    ("directions, 100", case(100, 16, actions="directions")),
    ("random, 1000", case(1000, 3, max_steps=400, policy="random")),
    ("gradient, 100", case(100, 50, policy="gradient")),
    ("run_and_tumble, 100", case(100, 40, policy="run_and_tumble")),
    ("inverse_square 2x1", case(10, 1500, model="inverse_square", emitters=1)),
    ("inverse_square 2x50", case(10, 1500, model="inverse_square")),
    ("inverse_square 10x100", case(10, 500, model="inverse_square", cells=10, emitters=100)),
    ("inverse_square 100x100", case(10, 120, model="inverse_square", cells=100, emitters=100)),
    (
        "inverse_square 100x1000",
        case(1, 30, max_steps=300, model="inverse_square", cells=100, emitters=1000),
    ),
    (
        "inverse_square 100x1000, 100",
        case(100, 0, max_steps=60, model="inverse_square", cells=100, emitters=1000),
    ),
    ("gaussian 100 cells", case(100, 40, max_steps=500, cells=100)),
    ("diffusion 100 cells", case(100, 80, max_steps=500, model="diffusion", cells=100)),
    ("gaussian 100x1000 emitters", case(1, 80, cells=100, emitters=1000)),
    ("100 obstacles", case(100, 60, obstacles=100)),
    ("1000 obstacles", case(100, 6, obstacles=1000)),
    ("1000 obstacles, 1 robot", case(1, 900, obstacles=1000)),
    ("1000 moving obstacles", case(100, 3, obstacles=1000, obstacle_motion=0.1)),
    (
        "1000 moving obstacles, 1000",
        case(1000, 0, max_steps=150, obstacles=1000, obstacle_motion=0.1),
    ),
    ("100 cells, 1000 obstacles", case(1, 50, cells=100, obstacles=1000)),
]


@dataclass(frozen=True)
class Row:
    """One measured run: its scenario, the robot-steps and episodes it ran, the engine's
    seconds, and the work of what it ran."""

    scenario: Scenario
    robot_steps: int
    episodes: int
    seconds: float
    done: int

    @property
    def seconds_per_unit(self) -> float:
        return self.seconds / self.done

    @property
    def charged_robot_steps(self) -> int:
        """Robot-steps charged the overhead C: every step, and every episode's closing one."""
        return self.robot_steps + self.episodes * self.scenario.robots.count

    @property
    def implied_overhead(self) -> str:
        """The overhead C that would make this row's work equal its time, where C is at least a
        quarter of the work (elsewhere it drowns in the other terms)."""
        c = self.scenario.robot_step_overhead
        if c * self.charged_robot_steps < self.done / 4:
            return ""
        return f"{c + (self.seconds * 1e9 - self.done) / self.charged_robot_steps:,.0f}"


def measure(fields: dict[str, Any], seed: int, shrink: int) -> Row:
    """One run of ``fields`` with ``seed``; ``shrink`` divides its episodes, steps and
    evaluation worlds."""
    learning = dict(fields.get("learning", {}))
    learning["episodes"] = learning.get("episodes", 50) // shrink
    learning["max_steps"] = max(20, learning.get("max_steps", 1000) // shrink)
    evaluation = dict(fields.get("evaluation", {}))
    worlds = evaluation.get("worlds", Evaluation.model_fields["worlds"].default)
    evaluation["worlds"] = max(1, worlds // shrink)
    scenario = Scenario.model_validate(
        {**fields, "learning": learning, "evaluation": evaluation, "seed": seed}
    )
    result = simulate(scenario)
    evaluation_steps = int(result.summary["total_steps"])
    steps = sum(int(e["steps"]) for e in result.episodes) + evaluation_steps
    robot_steps = int(result.work["robot_steps"])
    episodes = len(result.episodes) + 1
    done = scenario.work_for(robot_steps, steps, episodes, evaluation_steps)
    return Row(scenario, robot_steps, episodes, float(result.work["engine_s"]), done)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--quick",
        action="store_true",
        help="a tenth of the episodes, steps and evaluation worlds, one seed",
    )
    args = parser.parse_args(argv)
    shrink, seeds = (10, 1) if args.quick else (1, 7)

    simulate(Scenario.model_validate({"learning": {"episodes": 1, "max_steps": 10}}))
    print(f"cpu cores visible: {os.cpu_count()}, one used; median over {seeds} seed(s) per row")
    header = (
        f"{'scenario':<30}{'robots':>7}{'sources':>9}{'obst.':>6}{'robot-steps':>13}"
        f"{'rs/s':>12}{'units/s':>15}{'s/1e9':>7}{'bound':>7}{'C':>8}"
    )
    print(header)
    print("-" * len(header))
    per_unit = []
    for label, fields in SPREAD:
        runs = [measure(fields, seed, shrink) for seed in range(seeds)]
        row = sorted(runs, key=lambda r: r.seconds_per_unit)[len(runs) // 2]
        per_unit.append(row.seconds_per_unit)
        s = row.scenario
        print(
            f"{label:<30}{s.robots.count:>7}{s.sources:>9,}{s.obstacles.count:>6}"
            f"{row.robot_steps:>13,}{row.robot_steps / row.seconds:>12,.0f}"
            f"{row.done / row.seconds:>15,.0f}{row.seconds_per_unit * 1e9:>7.2f}"
            f"{row.done / s.work:>7.0%}{row.implied_overhead:>8}"
        )
    worst, best = max(per_unit), min(per_unit)
    budget = TARGET_JOB_S / worst
    rounded = 10 ** math.floor(math.log10(budget))
    print()
    print(
        f"seconds per 1e9 units: min {best * 1e9:.2f}, max {worst * 1e9:.2f}, "
        f"ratio {worst / best:.2f}"
    )
    print(
        f"a work budget of {budget:.3g} units keeps the dearest row's kind of job under "
        f"{TARGET_JOB_S:.0f} s here (suggested: {math.floor(budget / rounded) * rounded:.0e})"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
