"""How often should an active Brownian learner decide? The tabular learner in
'tumour-microswimmers' (20 robots, one tumour cell, 60 s) at each decision interval, learning-rate
schedule and training length, against always steering up the sensed gradient on the same seeds.

    python benchmarks/decision_interval.py [--seeds-from S] [--seeds N] [--radii 1,2,5]
        [--intervals step,0.1,0.5,1] [--exponents 1,0.6] [--episodes 20,50] [--gammas 0.9]
        [--sensor counted|each_step]

Run on design seeds (the default, 5000 on) to choose the defaults; report on others. For every
radius, each setting's share of robots that reach the cell (mean over seeds of each run's mean
over its evaluation worlds, with the 95 % interval) and its difference from 'gradient', paired by
seed. The table makes one comparison per setting: with m settings, about 0.05 m of the intervals
that exclude 0 are expected by chance.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

from physical_question import PRESET, design_arguments, floats, in_parallel, paired, reached
from science import mean_ci

from nanonav.scenario import preset_scenario

# (radius, interval in s or "step" (every step of dt_s) or "gradient" (the rule), alpha exponent,
# episodes, gamma, seed, worlds, sensor)
Job = tuple[float, str, float, int, float, int, int, str]


def step_s(radius: float) -> float:
    """The preset's step dt_s at this robot radius, s."""
    scenario = preset_scenario(
        PRESET, physics={"model": "active_brownian", "robot_radius_um": radius}
    )
    return scenario.physics.step_s


def run_one(job: Job) -> float:
    radius, interval, exponent, episodes, gamma, seed, worlds, sensor = job
    physics = {"sensor": sensor}
    if interval == "gradient":
        return reached(radius, seed, worlds, "gradient", physics)
    learning = {
        "episodes": episodes, "alpha_exponent": exponent, "gamma": gamma,
        "decision_interval_s": step_s(radius) if interval == "step" else float(interval),
    }  # fmt: skip
    return reached(radius, seed, worlds, "q_learning", physics, learning)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    design_arguments(parser, radii="2")
    parser.add_argument("--intervals", default="step,0.1,0.5,1,2", help="s, or step (every step)")
    parser.add_argument("--exponents", default="1,0.6", help="alpha / N**exponent")
    parser.add_argument("--episodes", default="50")
    parser.add_argument("--gammas", default="0.9", help="discount per decision")
    args = parser.parse_args(argv)
    seeds = range(args.seeds_from, args.seeds_from + args.seeds)
    settings = [
        (interval, exponent, int(episodes), gamma)
        for interval in args.intervals.split(",")
        for exponent in floats(args.exponents)
        for episodes in floats(args.episodes)
        for gamma in floats(args.gammas)
    ]
    rule = ("gradient", 1.0, 0, 0.9)
    jobs = [
        (radius, *setting, seed, args.worlds, args.sensor)
        for radius in floats(args.radii)
        for setting in [rule, *settings]
        for seed in seeds
    ]
    started = time.perf_counter()
    done = in_parallel(run_one, jobs)
    print(
        f"{PRESET}: seeds {seeds.start}-{seeds.stop - 1} x {args.worlds} worlds; the share of "
        f"robots that reach the cell; {len(settings)} settings, each paired with 'gradient' "
        "(* = the 95 % interval excludes 0)\n"
    )
    for radius in floats(args.radii):
        bar = [done[(radius, *rule, s, args.worlds, args.sensor)] for s in seeds]
        print(f"R = {radius} um: gradient {mean_ci(bar)}")
        print("  interval_s  alpha exponent  episodes  gamma  reached             minus gradient")
        for interval, exponent, episodes, gamma in settings:
            key = (radius, interval, exponent, episodes, gamma)
            got = [done[(*key, s, args.worlds, args.sensor)] for s in seeds]
            print(
                f"  {interval:<10}  {exponent:<14}  {episodes:<8}  {gamma:<5}  "
                f"{mean_ci(got):<18}  {paired(got, bar)}"
            )
        print()
    print(f"({time.perf_counter() - started:.0f} s on {os.cpu_count()} cores)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
