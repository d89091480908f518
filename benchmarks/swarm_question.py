"""The swarm's question: does signalling help a swarm treat a diffuse tumour, where, and does
learning to use signals beat a rule that uses them? The 'diffuse-tumour' world (cells that each
need 3 payloads, a faint short-range marker, robots that take up space), communication model x
number of cells x swarm size, every combination on the same seeds; each model paired by seed
with 'none'.

    python benchmarks/swarm_question.py [--seeds N] [--seeds-from S] [--worlds N] [--quick]

Per combination: the share of cells treated and the step the last was treated (the 1,000-step
limit if one was left), the mean over seeds of each run's mean over its evaluation worlds with
the 95 % interval, and the model minus 'none', paired by seed. Then, at 20 cells and 100 robots,
Q-learning (which sees what it receives and may follow it) trained on each model, against the
rule that uses the same signals, paired by seed. Last, each family of comparisons (treated
minus none, steps minus none, q_learning minus rule) with Holm's adjustment over its members:
the differences that stay resolved when the family's size is counted.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np
from physical_question import paired
from science import mean_ci

from nanonav import stats
from nanonav.engine import simulate
from nanonav.scenario import preset_scenario

MODELS = ("none", "attractant", "attractant_repellent", "broadcast")
CELLS = (1, 5, 20)
SWARMS = (10, 100, 1000)
PRESET = "diffuse-tumour"
METRICS = ("treated_fraction", "time_to_treat_all")


def run_one(job: tuple[str, int, int, str, int, int, int]) -> dict[str, Any]:
    model, cells, robots, policy, episodes, seed, worlds = job
    scenario = preset_scenario(
        PRESET, seed=seed, cells={"count": cells}, communication={"model": model},
        robots={"count": robots, "policy": policy}, learning={"episodes": episodes},
        evaluation={"worlds": worlds},
    )  # fmt: skip
    summary = simulate(scenario).summary
    return {key: summary[key] for key in METRICS}


def idle_robots(job: tuple[str, int]) -> dict[str, float]:
    """Where the robots that delivered nothing are at the end of the first evaluation world, at
    20 cells and 100 robots: within 10 units of a treated cell, and how far they moved in the
    last 200 steps (a robot that searches in straight lines covers up to 100)."""
    model, seed = job
    scenario = preset_scenario(PRESET, seed=seed, communication={"model": model},
                               evaluation={"worlds": 1})  # fmt: skip
    t = simulate(scenario).trajectory
    assert t is not None and t.cell_loads is not None and t.delivered_to is not None
    idle = t.delivered_to < 0
    capacity = scenario.cells.capacity or 0
    treated = t.cell_loads[-1] >= capacity
    ends = t.robots[-1][idle]
    gaps = np.linalg.norm(ends[:, None, :] - t.cells[-1][None, treated, :], axis=2)
    before = int(np.searchsorted(t.step, t.step[-1] - 200))
    moved = np.linalg.norm(ends - t.robots[before][idle], axis=1)
    return {
        "near_treated": float((gaps <= 10.0).any(axis=1).mean()) if idle.any() else 0.0,
        "moved": float(moved.mean()) if idle.any() else 0.0,
    }


def table(header: tuple[str, ...], rows: Sequence[Sequence[str]]) -> None:
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(header)]
    print("  " + "  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)))
    for row in rows:
        print("  " + "  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)))
    print()


def holm_resolved(family: str, members: list[tuple[str, list[float], list[float]]]) -> None:
    """The family's comparisons whose Holm-adjusted Wilcoxon p stays below 0.05 (those with
    every difference 0 count in the family, at p 1)."""
    found = [stats.paired(a, b) for _, a, b in members]
    adjusted = stats.holm([f.p_value if f.p_value is not None else 1.0 for f in found])
    print(f"{family}: {len(members)} comparisons; resolved after Holm's adjustment:")
    kept = [
        f"  {where}: {f.mean_difference:+.2f} (p {f.p_value:.4f}, Holm {p:.3f})"
        for (where, _, _), f, p in zip(members, found, adjusted, strict=True)
        if p < 0.05 and f.mean_difference is not None and f.p_value is not None
    ]
    print("\n".join(kept) if kept else "  none")
    print()


# long: a benchmark's command line and its printed table, in order
def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument(
        "--seeds-from", type=int, default=0,
        help="the first seed (the documentation's figures: 0; replicate on seeds of your own)",
    )  # fmt: skip
    parser.add_argument("--worlds", type=int, default=3, help="evaluation worlds per run")
    parser.add_argument("--episodes", type=int, default=40, help="q_learning's training")
    parser.add_argument("--quick", action="store_true", help="a smoke run: 2 seeds, small")
    args = parser.parse_args(argv)
    seeds = range(args.seeds_from, args.seeds_from + (2 if args.quick else args.seeds))
    families: dict[str, list[tuple[str, list[float], list[float]]]] = {
        "treated minus none": [], "steps minus none": [], "q_learning minus rule": [],
    }  # fmt: skip
    worlds = 1 if args.quick else args.worlds
    swarms = (10, 100) if args.quick else SWARMS
    episodes = 2 if args.quick else args.episodes
    jobs = [
        (model, cells, robots, "rule", 0, seed, worlds)
        for model in MODELS for cells in CELLS for robots in swarms for seed in seeds
    ] + [
        (model, 20, 100, "q_learning", episodes, seed, worlds) for model in MODELS for seed in seeds
    ]  # fmt: skip
    started = time.perf_counter()
    with ProcessPoolExecutor(os.cpu_count() or 1) as pool:
        done = dict(zip(jobs, pool.map(run_one, jobs), strict=True))
    print(
        f"{PRESET}: cells need 3 payloads each; 'rule' robots; {len(seeds)} seeds x {worlds} "
        "worlds; * = the 95 % interval excludes 0\n"
    )

    def runs(model: str, cells: int, robots: int, policy: str = "rule") -> list[dict[str, Any]]:
        e = 0 if policy == "rule" else episodes
        return [done[(model, cells, robots, policy, e, s, worlds)] for s in seeds]

    limit = (0.0, float("inf"))
    for cells in CELLS:
        for robots in swarms:
            print(f"{cells} cells, {robots} robots")
            rows: list[tuple[str, ...]] = []
            base = runs("none", cells, robots)
            for model in MODELS:
                found = runs(model, cells, robots)
                share = [r["treated_fraction"] for r in found]
                steps = [float(r["time_to_treat_all"]) for r in found]
                if model != "none":
                    where = f"{model}, {cells} cells, {robots} robots"
                    families["treated minus none"].append(
                        (where, share, [r["treated_fraction"] for r in base])
                    )
                    families["steps minus none"].append(
                        (where, steps, [float(r["time_to_treat_all"]) for r in base])
                    )
                rows.append((
                    model, mean_ci(share), mean_ci(steps, 0, limit),
                    paired(share, [r["treated_fraction"] for r in base]) if model != "none" else "",
                    paired(steps, [float(r["time_to_treat_all"]) for r in base])
                    if model != "none" else "",
                ))  # fmt: skip
            table(("model", "treated", "steps to treat all", "treated minus none",
                   "steps minus none"), rows)  # fmt: skip
    print(f"learning to use signals: 20 cells, 100 robots, q_learning trained {episodes} episodes")
    rows = []
    for model in MODELS:
        learned = runs(model, 20, 100, "q_learning")
        rule = runs(model, 20, 100)
        share = [r["treated_fraction"] for r in learned]
        families["q_learning minus rule"].append(
            (model, share, [r["treated_fraction"] for r in rule])
        )
        rows.append((
            model, mean_ci(share), mean_ci([r["treated_fraction"] for r in rule]),
            paired(share, [r["treated_fraction"] for r in rule]),
        ))  # fmt: skip
    table(("model", "q_learning treated", "rule treated", "q_learning minus rule"), rows)
    with ProcessPoolExecutor(os.cpu_count() or 1) as pool:
        idle_jobs = [(model, seed) for model in MODELS for seed in seeds]
        idle = dict(zip(idle_jobs, pool.map(idle_robots, idle_jobs), strict=True))
    print("the robots that delivered nothing, 20 cells, 100 robots, the first world of each seed")
    rows = []
    for model in MODELS:
        found = [idle[(model, seed)] for seed in seeds]
        rows.append((
            model, mean_ci([f["near_treated"] for f in found]),
            mean_ci([f["moved"] for f in found], 1, (0.0, float("inf"))),
        ))  # fmt: skip
    table(("model", "within 10 of a treated cell", "moved in the last 200 steps"), rows)
    for family, members in families.items():
        holm_resolved(family, members)
    print(f"({time.perf_counter() - started:.0f} s on {os.cpu_count()} cores)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
