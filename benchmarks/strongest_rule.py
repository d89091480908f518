"""The strongest fixed rule when molecules are counted: each candidate rule's success on design
seeds, the best chosen there at each radius, then that choice against the plain rules on seeds
the choice never saw, paired by seed, with Holm over the comparisons.

    python benchmarks/strongest_rule.py [--seeds N] [--report-seeds N] [--report-from S]
                                        [--worlds N] [--radii R,R] [--quick]

The world is 'tumour-microswimmers' (one cell among 40 tissue obstacles, 20 robots at 10 um/s,
60 s) with sensor 'counted'. A candidate is a policy ('gradient' or 'steer_and_tumble'), how
long the gradient a robot steers by remembers its counts (``physics.gradient_memory_s``, 0:
the last count's alone) and how fast it may turn (``physics.max_turn_rate_rad_s``: a slower
turn follows a noisy estimate by less). 'run_and_tumble' (temporal sensing alone), the robot
that does not steer, and the exact gradient (an upper bound no robot has) are printed beside.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from typing import Any

from physical_question import DESIGN_SEEDS, floats, in_parallel, paired, reached
from science import mean_ci

from nanonav import stats

RADII = "1,2,5"
STEERING = ("gradient", "steer_and_tumble")
MEMORIES_S = (0.0, 0.5, 2.0, 8.0)
TURN_RATES_RAD_S = (1.0, 3.0, 10.0)
BESIDE = ("uncontrolled", "run_and_tumble", "exact_gradient")
# seeds no document has reported on (the tables use 0-99 and 5000-5099, convergence 7000-7019)
REPORT_SEEDS = 7100

Rule = tuple[str, float, float]  # policy, gradient memory s, turn rate rad/s
Job = tuple[float, Rule, int, int]


def label(rule: Rule) -> str:
    policy, memory, turn = rule
    if policy not in STEERING:
        return policy
    return f"{policy}, memory {memory:g} s, turn {turn:g} rad/s"


def run_one(job: Job) -> float:
    radius, (policy, memory, turn), seed, worlds = job
    physics: dict[str, Any] = {"sensor": "counted", "max_turn_rate_rad_s": turn}
    if policy in STEERING:
        physics["gradient_memory_s"] = memory
    return reached(radius, seed, worlds, policy, physics)


def candidates(quick: bool) -> list[Rule]:
    memories = (0.0, 2.0) if quick else MEMORIES_S
    turns = (1.0, 10.0) if quick else TURN_RATES_RAD_S
    return [(p, m, t) for p in STEERING for m in memories for t in turns]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10, help="design seeds")
    parser.add_argument("--seeds-from", type=int, default=DESIGN_SEEDS)
    parser.add_argument("--report-seeds", type=int, default=20)
    parser.add_argument("--report-from", type=int, default=REPORT_SEEDS)
    parser.add_argument("--worlds", type=int, default=4, help="evaluation worlds per run")
    parser.add_argument("--radii", default=RADII, help="robot radii, um")
    parser.add_argument("--quick", action="store_true", help="a smoke run: 2 seeds, 1 radius")
    args = parser.parse_args(argv)
    design = range(args.seeds_from, args.seeds_from + (2 if args.quick else args.seeds))
    report = range(args.report_from, args.report_from + (2 if args.quick else args.report_seeds))
    radii = (2.0,) if args.quick else tuple(floats(args.radii))
    worlds = 1 if args.quick else args.worlds
    rules = candidates(args.quick)
    beside: list[Rule] = [(p, 0.0, 10.0) for p in BESIDE]
    plain: Rule = ("gradient", 0.0, 10.0)
    started = time.perf_counter()

    done = in_parallel(run_one, [(r, rule, s, worlds) for r in radii for rule in rules + beside
                                 for s in design])  # fmt: skip
    print(
        f"Design seeds {design.start}-{design.stop - 1} x {worlds} worlds, sensor 'counted': "
        "share of robots that reach the cell (mean [95 % interval])\n"
    )
    best: dict[float, Rule] = {}
    for radius in radii:
        print(f"radius {radius:g} um")
        scored = [(sum(done[(radius, rule, s, worlds)] for s in design) / len(design), rule)
                  for rule in rules]  # fmt: skip
        best[radius] = max(scored)[1]
        for rule in rules + beside:
            shares = [done[(radius, rule, s, worlds)] for s in design]
            mark = "  <- chosen" if rule == best[radius] else ""
            print(f"  {label(rule):48s} {mean_ci(shares)}{mark}")
        print()

    tumbling: Rule = ("steer_and_tumble", 0.0, 10.0)
    jobs = {(r, rule, s, worlds) for r in radii for rule in (best[r], plain, tumbling, *beside)
            for s in report}  # fmt: skip
    fresh = in_parallel(run_one, sorted(jobs))
    comparisons = len(radii) * 2
    print(
        f"Report seeds {report.start}-{report.stop - 1} x {worlds} worlds: the rule chosen on "
        f"the design seeds against 'gradient' as it was (memory 0, 10 rad/s) and against "
        f"'steer_and_tumble' (the same); Holm over {comparisons} comparisons\n"
    )
    rows: list[tuple[float, str, str, float]] = []
    for radius in radii:
        chosen = [fresh[(radius, best[radius], s, worlds)] for s in report]
        for other in (plain, tumbling):
            theirs = [fresh[(radius, other, s, worlds)] for s in report]
            p_value = stats.paired(chosen, theirs).p_value
            rows.append((radius, label(other), paired(chosen, theirs),
                         1.0 if p_value is None else p_value))  # fmt: skip
    adjusted = stats.holm([r[3] for r in rows])
    for radius in radii:
        print(f"radius {radius:g} um: chosen {label(best[radius])}")
        for rule in dict.fromkeys((best[radius], plain, tumbling, *beside)):
            shares = [fresh[(radius, rule, s, worlds)] for s in report]
            print(f"  {label(rule):48s} {mean_ci(shares)}")
        for (r, name, diff, _), holm_p in zip(rows, adjusted, strict=True):
            if r == radius:
                print(f"  chosen - {name:44s} {diff}  Holm p {holm_p:.3g}")
        print()
    print(f"({time.perf_counter() - started:.0f} s on {os.cpu_count()} cores)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
