"""The strongest rule, and the best learner, when molecules are counted: each candidate's
success on design seeds, the best fixed rule and the best learner chosen there at each radius,
then the rule against plain 'gradient', against not steering and against the blind tumbler
(the searcher that uses no information, 'blind_tumble', at the tumble rate of 0.25, 0.5 or
1 /s that did best on the design seeds: a rule that beats it steers, rather than only
reorients), and the learner against the rule, on seeds the choice never saw, twice (the
second set replicates the first), paired by seed, with Holm over each set's comparisons.

    python benchmarks/strongest_rule.py [--preset NAME] [--seeds N] [--report-seeds N]
                                        [--report-from S,S] [--worlds N] [--episodes N]
                                        [--radii R,R] [--quick]

'tumour-microswimmers' (the default; one cell among 40 tissue obstacles, 20 robots at 10 um/s,
60 s, with sensor 'counted'): a candidate is 'gradient' or 'steer_and_tumble', with a memory of
the counts' gradient (``physics.gradient_memory_s``, 0: the last count's alone) and a turn rate
(``physics.max_turn_rate_rad_s``: a slower turn follows a noisy estimate by less); a learner is
the default Q-learner (a decision a second, 50 episodes), with a short memory of its readings
or not, a memory of the gradient or not, and a turn rate of 3 or 10 rad/s.

'alonso-kirkegaard' (one robot of 0.5-3.4 um at 5 um/s, 13 molecules a count 50 um from the
source, 25.6 s): temporal sensing on two time scales as well, the rules that tumble and the
Q-learner comparing the mean of the last ``physics.short_memory_s`` with that of the last
``physics.memory_s``; the Q-learner trains 400 episodes.

'run_and_tumble' (temporal sensing alone, at its defaults), the robot that does not steer and
the exact gradient (an upper bound no robot has) are printed beside.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

from physical_question import DESIGN_SEEDS, floats, in_parallel, paired, reached
from science import mean_ci

from nanonav import stats

PRESETS = ("tumour-microswimmers", "alonso-kirkegaard")
RADII = {"tumour-microswimmers": "0.5,1,2,5", "alonso-kirkegaard": "0.5,1,2,3.4"}
TIME_LIMIT_S = {"tumour-microswimmers": 60.0, "alonso-kirkegaard": 25.6}
WORLDS = {"tumour-microswimmers": 4, "alonso-kirkegaard": 20}
# the learner's training: the project's default for the tissue (50 episodes of 60 s, 20 robots
# sharing a table), longer for one robot's 25.6 s
EPISODES = {"tumour-microswimmers": 50, "alonso-kirkegaard": 400}
BESIDE = ("uncontrolled", "run_and_tumble", "exact_gradient")

# seeds no document has reported on (the tables use 0-99 and 5000-5099, convergence 7000-7019)
REPORT_SEEDS = 7100
REPLICATE_SEEDS = 7200

Setting = tuple[tuple[str, float], ...]  # physics fields and their values
Rule = tuple[str, Setting]  # a policy and its setting
Job = tuple[str, float, Rule, int, int, int]  # preset, radius, rule, seed, worlds, episodes
# searchers that use no information, tumbling at the rates the rules tumble at: the strongest of
# them on the design seeds is the baseline a rule's steering is measured against
BLIND: tuple[Rule, ...] = tuple(
    ("blind_tumble", (("tumble_rate_s", rate),)) for rate in (0.25, 0.5, 1.0)
)


def label(rule: Rule) -> str:
    policy, setting = rule
    names = {"gradient_memory_s": "gradient memory", "max_turn_rate_rad_s": "turn",
             "short_memory_s": "short", "memory_s": "long", "tumble_rate_s": "tumble",
             "tumble_rate_rising_s": "rising"}  # fmt: skip
    return ", ".join([policy, *(f"{names[k]} {v:g}" for k, v in setting)])


def run_one(job: Job) -> float:
    """The share of robots that reach the cell in one run."""
    preset, radius, (policy, setting), seed, worlds, episodes = job
    return reached(
        radius, seed, worlds, policy, {"sensor": "counted", **dict(setting)},
        {"episodes": episodes if policy == "q_learning" else 0},
        preset=preset, time_limit_s=TIME_LIMIT_S[preset],
    )  # fmt: skip


def candidates(preset: str, quick: bool) -> list[Rule]:
    """The fixed rules and the learners tried on the design seeds."""
    if preset == "tumour-microswimmers":
        memories = (0.0, 2.0) if quick else (0.0, 0.5, 2.0, 8.0)
        turns = (1.0, 10.0) if quick else (1.0, 3.0, 10.0)
        fixed: list[Rule] = [
            (p, (("gradient_memory_s", m), ("max_turn_rate_rad_s", t)))
            for p in ("gradient", "steer_and_tumble")
            for m in memories
            for t in turns
        ]
        # the default learner (a decision a second), with readings on two time scales or not,
        # and its action up the gradient steering by the last count's or a remembered one, at
        # the rules' turn rates
        return fixed + [
            ("q_learning",
             (("short_memory_s", s), ("gradient_memory_s", g), ("max_turn_rate_rad_s", t)))
            for s in ((0.0,) if quick else (0.0, 0.3))
            for g in ((0.5,) if quick else (0.0, 0.5))
            for t in ((3.0,) if quick else (3.0, 10.0))
        ]  # fmt: skip
    shorts = (0.0, 0.5) if quick else (0.0, 0.3, 1.0)
    longs = (2.0,) if quick else (2.0, 5.0)
    rates = ((1.0, 0.25),) if quick else ((1.0, 0.25), (0.5, 0.05))
    rules: list[Rule] = [
        (p, (("short_memory_s", s), ("memory_s", m), ("tumble_rate_s", tumble),
             ("tumble_rate_rising_s", rising)))
        for p in ("run_and_tumble", "steer_and_tumble") for s in shorts for m in longs
        for tumble, rising in rates
    ]  # fmt: skip
    rules += [("gradient", (("gradient_memory_s", m),))
              for m in ((0.0, 2.0) if quick else (0.0, 0.5, 2.0, 4.0, 8.0))]  # fmt: skip
    # the learner's action 'up the gradient' steers by the same held gradient as the rule
    gradients = (2.0,) if quick else (0.0, 2.0)
    rules += [("q_learning", (("short_memory_s", s), ("memory_s", m), ("gradient_memory_s", g)))
              for s in shorts for m in longs for g in gradients]  # fmt: skip
    return rules


# long: a benchmark's command line and its printed table, in order
def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--preset", choices=PRESETS, default=PRESETS[0])
    parser.add_argument("--seeds", type=int, default=10, help="design seeds")
    parser.add_argument("--seeds-from", type=int, default=DESIGN_SEEDS)
    parser.add_argument("--report-seeds", type=int, default=20, help="seeds of each report")
    parser.add_argument(
        "--report-from", default=f"{REPORT_SEEDS},{REPLICATE_SEEDS}",
        help="the first seed of each report (the second replicates the first)",
    )  # fmt: skip
    parser.add_argument("--worlds", type=int, help="evaluation worlds per run")
    parser.add_argument("--episodes", type=int, help="q_learning's training episodes")
    parser.add_argument("--radii", help="robot radii, um")
    parser.add_argument("--quick", action="store_true", help="a smoke run: 2 seeds, 1 radius")
    args = parser.parse_args(argv)
    preset = args.preset
    design = range(args.seeds_from, args.seeds_from + (2 if args.quick else args.seeds))
    count = 2 if args.quick else args.report_seeds
    reports = [range(int(f), int(f) + count) for f in args.report_from.split(",")]
    radii = tuple(floats(args.radii or RADII[preset]))[: 1 if args.quick else None]
    worlds = 1 if args.quick else (args.worlds or WORLDS[preset])
    episodes = 2 if args.quick else (args.episodes or EPISODES[preset])
    tried = candidates(preset, args.quick)
    beside: list[Rule] = [(p, ()) for p in BESIDE] + list(BLIND[:1] if args.quick else BLIND)
    plain: Rule = ("gradient", ())
    uncontrolled: Rule = ("uncontrolled", ())
    started = time.perf_counter()

    def job(radius: float, rule: Rule, seed: int) -> Job:
        return (preset, radius, rule, seed, worlds, episodes)

    done = in_parallel(run_one, [job(r, rule, s) for r in radii for rule in tried + beside
                                 for s in design])  # fmt: skip
    print(
        f"{preset}, sensor 'counted': share of robots that reach the cell (mean [95 % "
        f"interval]); design seeds {design.start}-{design.stop - 1} x {worlds} worlds; "
        f"q_learning trains {episodes} episodes\n"
    )

    def best_of(radius: float, rules: list[Rule]) -> Rule | None:
        if not rules:
            return None
        scored = [(sum(done[job(radius, rule, s)] for s in design), -i)
                  for i, rule in enumerate(rules)]  # fmt: skip
        return rules[-max(scored)[1]]

    chosen: dict[float, list[Rule]] = {}
    blind: dict[float, Rule | None] = {}
    for radius in radii:
        rule = best_of(radius, [r for r in tried if r[0] != "q_learning"])
        learner = best_of(radius, [r for r in tried if r[0] == "q_learning"])
        chosen[radius] = [r for r in (rule, learner) if r is not None]
        blind[radius] = best_of(radius, [r for r in beside if r[0] == "blind_tumble"])
        print(f"radius {radius:g} um")
        for candidate in tried + beside:
            shares = [done[job(radius, candidate, s)] for s in design]
            mark = "  <- chosen" if candidate in chosen[radius] else ""
            print(f"  {label(candidate):72s} {mean_ci(shares)}{mark}")
        print()

    for report in reports:
        jobs = {job(r, rule, s) for r in radii for rule in (*chosen[r], plain, *beside)
                for s in report}  # fmt: skip
        fresh = in_parallel(run_one, sorted(jobs))
        rows: list[tuple[float, str, str, float]] = []
        for radius in radii:
            rule, *learner = chosen[radius]
            pairs: list[tuple[str, Rule, Rule]] = [
                ("strongest rule - plain gradient", rule, plain),
                ("strongest rule - uncontrolled", rule, uncontrolled),
            ]
            tumbler = blind[radius]
            pairs += [("strongest rule - blind tumbler", rule, tumbler)] if tumbler else []
            pairs += [("learner - strongest rule", learner[0], rule)] if learner else []
            for name, a, b in pairs:
                ours = [fresh[job(radius, a, s)] for s in report]
                theirs = [fresh[job(radius, b, s)] for s in report]
                p_value = stats.paired(ours, theirs).p_value
                rows.append((radius, name, paired(ours, theirs),
                             1.0 if p_value is None else p_value))  # fmt: skip
        adjusted = stats.holm([r[3] for r in rows])
        print(
            f"Report seeds {report.start}-{report.stop - 1} x {worlds} worlds, which the choice "
            f"never saw; Holm over {len(rows)} comparisons\n"
        )
        for radius in radii:
            print(f"radius {radius:g} um")
            for rule in dict.fromkeys((*chosen[radius], plain, *beside)):
                shares = [fresh[job(radius, rule, s)] for s in report]
                print(f"  {label(rule):72s} {mean_ci(shares)}")
            for (r, name, diff, _), holm_p in zip(rows, adjusted, strict=True):
                if r == radius:
                    print(f"  {name:40s} {diff}  Holm p {holm_p:.3g}")
            print()
    print(f"({time.perf_counter() - started:.0f} s on {os.cpu_count()} cores)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
