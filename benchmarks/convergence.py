"""Does a physical result move with the time step? Each fixed rule's success, and the exact
gradient's bound, at dt, dt/2 and dt/4, with each sensor, at robot radii 1, 2 and 5 um, in the
'tumour-microswimmers' world (one cell, 40 obstacles, 20 robots, 60 s), paired by seed; or in
another preset's, such as 'tumour-signals' (robots bound to a cell call the others with an
attractant that they count as they count the biomarker).

    python benchmarks/convergence.py [--preset P] [--seeds N] [--seeds-from S] [--worlds N]
                                     [--sensors S,S] [--radii R,R] [--policies P,P]
                                     [--dt DT,DT,...] [--quick]

A result that has converged moves, from dt to dt/4 (the first step given to the last), by less
than its interval's half-width at dt: each row prints the share of robots that reach the cell
at each step (mean over seeds of each run's mean over its worlds, with the 95 % interval), the
paired difference dt/4 minus dt with its interval, and whether it holds. Sensor 'each_step'
reads the whole body over each step (a gamma draw, never 0), 'counted' counts molecules over
its integration time (``physics.integration_time_s``, filled in: 0.1 s, or r^2 / D_m where
that is longer).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from typing import Any

from physical_question import in_parallel, reached
from science import mean_ci

from nanonav import stats

PRESET = "tumour-microswimmers"
SENSORS = ("each_step", "counted")
RADII = (1.0, 2.0, 5.0)
POLICIES = ("gradient", "run_and_tumble", "steer_and_tumble", "exact_gradient")
DT_S = (0.01, 0.005, 0.0025)
# seeds no document has reported on (the documentation's tables use 0-99 and 5000-5099)
FRESH_SEEDS = 7000

Job = tuple[str, float, str, float, int, int, str]


def run_one(job: Job) -> float:
    """The share of robots that reach a cell in one run."""
    sensor, radius, policy, dt, seed, worlds, preset = job
    return reached(radius, seed, worlds, policy, {"dt_s": dt, "sensor": sensor}, preset=preset)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--preset", default=PRESET, help="the world (default: %(default)s)")
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--seeds-from", type=int, default=FRESH_SEEDS)
    parser.add_argument("--worlds", type=int, default=4, help="evaluation worlds per run")
    parser.add_argument("--sensors", default=",".join(SENSORS), help="physics.sensor")
    parser.add_argument("--radii", default=",".join(f"{r:g}" for r in RADII), help="um")
    parser.add_argument("--policies", default=",".join(POLICIES))
    parser.add_argument(
        "--dt", default=",".join(f"{dt:g}" for dt in DT_S), help="time steps, s, coarsest first"
    )
    parser.add_argument("--quick", action="store_true", help="a smoke run: 2 seeds, 1 radius")
    args = parser.parse_args(argv)
    seeds = range(args.seeds_from, args.seeds_from + (2 if args.quick else args.seeds))
    sensors = args.sensors.split(",")
    radii = (2.0,) if args.quick else tuple(float(r) for r in args.radii.split(","))
    policies = ("gradient", "exact_gradient") if args.quick else tuple(args.policies.split(","))
    steps = tuple(float(dt) for dt in args.dt.split(","))
    worlds = 1 if args.quick else args.worlds
    jobs: list[Job] = [
        (sensor, radius, policy, dt, seed, worlds, args.preset)
        for sensor in sensors for radius in radii for policy in policies for dt in steps
        for seed in seeds
    ]  # fmt: skip
    started = time.perf_counter()
    done = in_parallel(run_one, jobs)
    print(
        f"{args.preset}, 60 s: share of robots that reach a cell, {len(seeds)} seeds (from "
        f"{args.seeds_from}) x {worlds} worlds, paired by seed; the finest step minus the "
        "coarsest holds when within the half-width of the coarsest's 95 % interval\n"
    )
    moved_by = "dt/4 - dt" if steps == DT_S else f"dt {steps[-1]:g} - dt {steps[0]:g}"
    header = ("sensor", "radius", "policy", *(f"dt {dt:g} s" for dt in steps), moved_by,
              "holds")  # fmt: skip
    rows: list[tuple[str, ...]] = []
    held = 0
    for sensor in sensors:
        for radius in radii:
            for policy in policies:

                def shares(dt: float, key: Any = (sensor, radius, policy)) -> list[float]:
                    return [done[(*key, dt, seed, worlds, args.preset)] for seed in seeds]

                coarse, finest = shares(steps[0]), shares(steps[-1])
                moved = stats.paired(finest, coarse)
                spread = stats.describe(coarse, bounds=(0.0, 1.0))
                half = (
                    (spread.ci_high - spread.ci_low) / 2
                    if spread.ci_high is not None and spread.ci_low is not None
                    else float("nan")
                )
                diff = moved.mean_difference
                holds = diff is not None and abs(diff) <= half
                held += holds
                interval = (
                    f"{diff:+.2f} [{moved.ci_low:+.2f}, {moved.ci_high:+.2f}]"
                    if diff is not None and moved.ci_low is not None and moved.ci_high is not None
                    else "n/a"
                )
                rows.append((sensor, f"{radius:g} um", policy,
                             *(mean_ci(shares(dt)) for dt in steps), interval,
                             f"{'yes' if holds else 'NO'} (+-{half:.2f})"))  # fmt: skip
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(header)]
    print("  " + "  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)))
    for row in rows:
        print("  " + "  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)))
    print(f"\nheld: {held} of {len(rows)} rows")
    print(f"({time.perf_counter() - started:.0f} s on {os.cpu_count()} cores)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
