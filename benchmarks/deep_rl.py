"""Deep learners in physical time: does PPO (Stable-Baselines3) or recurrent PPO (sb3-contrib)
beat the strongest fixed rule, or the tabular learner, for robots of what size?

    python benchmarks/deep_rl.py [--decisions N] [--recurrent-decisions N] [--seeds N]
                                 [--seeds-from S] [--worlds N] [--radii R,...]
                                 [--steering discrete|continuous] [--decision-interval-s S]
                                 [--preset NAME] [--gradient-memory-s S]
                                 [--sensor counted|each_step] [--quick]

The 'tumour-microswimmers' world (one tumour cell among 40 tissue obstacles, 20 robots
swimming at 10 um/s for 60 s), robots of radius 0.5, 1, 2 and 5 um. Every robot decides once a
second (the physics' default decision interval, or ``--decision-interval-s``) and holds its
action; the robots decide together (the simultaneous schedule), for every policy alike. The
deep learners choose among the steering actions, or with ``--steering continuous`` turn by a
continuous (side, up) command in the body frame, observing the gradient in that frame (the
mean of its readings over the interval); they are then compared with the gradient rule
written as such a turn too (``nanonav.rl.rules.TurnUpGradient``), run by the same path.

- Training, on design seeds (world k of the 16 trained together drawn from seed 5000 + k):
  PPO (MlpPolicy, the library's default hyperparameters) through ``NanoNavVecEnv``, one robot
  a world, for ``--decisions`` decisions, exported to ONNX; recurrent PPO (MlpLstmPolicy) for
  ``--recurrent-decisions``.
- Evaluation, on fresh seeds (9400 on), ``--worlds`` evaluation worlds a seed, every policy in
  the same worlds: both networks, exported to ONNX, by the service's own path
  (``nanonav.rl.evaluate`` with onnxruntime, as a worker runs a ``policy_from`` network; the
  recurrent one carrying each robot's memory from decision to decision); 'gradient' (steer up the
  sensed gradient: the strongest fixed rule, docs/explanation/learning.md) and 'q_learning'
  (the tabular learner, its default 50 training episodes a seed) by ``simulate``.

With ``--preset alonso-kirkegaard`` (one robot, 25.6 s, molecules counted: the setting where
Alonso & Kirkegaard found a recurrent policy beating the rules) and ``--gradient-memory-s 2``
(the strongest rule there, docs/explanation/sensing.md), every policy steers by the same
remembered gradient: the learners' action up the gradient as the rule.

Printed: the share of robots that reach the cell (mean over seeds, 95 % interval), each deep
learner minus 'gradient' and minus 'q_learning' paired by seed, with Wilcoxon's p and Holm's
over every comparison the table makes; and the training rate, decisions/s and robot-steps/s,
beside PPO's on CartPole-v1 with as many environments in the same run.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from science import mean_ci

from nanonav import stats
from nanonav.engine import simulate
from nanonav.engine.observations import action_labels, observation_of
from nanonav.rl.evaluate import evaluate
from nanonav.rl.onnx_policy import NetworkPolicy
from nanonav.rl.rules import TurnUpGradient
from nanonav.scenario import STEERINGS, Scenario, Steering, preset_scenario

PRESET = "tumour-microswimmers"
RADII = (0.5, 1.0, 2.0, 5.0)
DESIGN_SEEDS = 5000
FRESH_SEEDS = 9400
ENVS = 16
LEARNERS = ("ppo", "recurrent-ppo")
BASELINES = ("gradient", "q_learning")
# the gradient rule as a continuous turn (``nanonav.rl.rules``), beside learners that turn so
TURN_RULE = "turn_up_gradient"


PRESETS = ("tumour-microswimmers", "alonso-kirkegaard")
TIME_LIMIT_S = {"tumour-microswimmers": 60.0, "alonso-kirkegaard": 25.6}
# What every run shares, set by main and sent with every job to the processes that run it: the
# decision interval, s (None: the physics' default), the preset, the gradient memory, s, and the
# sensor (None: the preset's).
Setup = tuple[float | None, str, float, str | None]
SETUP: dict[str, Setup] = {"now": (None, PRESET, 0.0, None)}


def scenario(radius: float, seed: int, policy: str, worlds: int, episodes: int = 0) -> Scenario:
    """The preset with robots of ``radius`` um, over its time limit, deciding together."""
    interval, preset, memory, sensor = SETUP["now"]
    learning: dict[str, Any] = {"episodes": episodes}
    if interval is not None:
        learning["decision_interval_s"] = interval
    physics: dict[str, Any] = {"model": "active_brownian", "time_limit_s": TIME_LIMIT_S[preset],
                               "robot_radius_um": radius}  # fmt: skip
    if memory:
        physics["gradient_memory_s"] = memory
    if sensor is not None:
        physics["sensor"] = sensor
    return preset_scenario(
        preset, seed=seed, physics=physics,
        robots={"policy": policy, "schedule": "simultaneous"},
        learning=learning, evaluation={"worlds": worlds},
    )  # fmt: skip


def _quiet_torch() -> None:
    import torch

    torch.set_num_threads(1)


def train(job: tuple[str, float, int, str, bool, Steering, Setup]) -> dict[str, Any]:
    """Train ``algo`` at ``radius`` for ``decisions`` on the design seeds; returns its rate and
    where the trained policy is, exported to ONNX (recurrent PPO's with its memory). ``quick``:
    short rollouts (a smoke run; the figures use the library's defaults)."""
    algo, radius, decisions, out, quick, steering, setup = job
    SETUP["now"] = setup
    _quiet_torch()
    from sb3_contrib import RecurrentPPO
    from stable_baselines3 import PPO

    from nanonav.env.baselines import NanoNavVecEnv, export_onnx

    world = scenario(radius, DESIGN_SEEDS, "q_learning", 1)
    env = NanoNavVecEnv(ENVS, world, steering=steering)
    env.seed(DESIGN_SEEDS)
    rollout: dict[str, Any] = {"n_steps": 16, "batch_size": 64} if quick else {}
    if algo == "ppo":
        model: Any = PPO("MlpPolicy", env, seed=DESIGN_SEEDS, device="cpu", **rollout)
    else:
        model = RecurrentPPO("MlpLstmPolicy", env, seed=DESIGN_SEEDS, device="cpu", **rollout)
    started = time.perf_counter()
    model.learn(total_timesteps=decisions)
    seconds = time.perf_counter() - started
    where = str(Path(out) / f"{algo}-{radius}.onnx")
    export_onnx(model, Path(where), observation=env.observation_labels, actions=env.action_labels)
    done = int(model.num_timesteps)
    return {"decisions": done, "seconds": seconds, "steps_per_decision": world.decision_steps,
            "where": where}  # fmt: skip


def run_one(job: tuple[str, float, int, int, str, Steering, Setup]) -> float:
    """The share of robots that reach the cell in one evaluation run."""
    policy, radius, seed, worlds, where, steering, setup = job
    SETUP["now"] = setup
    if policy == TURN_RULE:
        s = scenario(radius, seed, "q_learning", worlds)
        rule = TurnUpGradient(s)
        return float(evaluate(s, rule, steering="continuous").summary["success_rate"])
    if policy in BASELINES:
        episodes = 50 if policy == "q_learning" else 0
        return float(
            simulate(scenario(radius, seed, policy, worlds, episodes)).summary["success_rate"]
        )
    s = scenario(radius, seed, "q_learning", worlds)
    model = Path(where).read_bytes()
    width = observation_of(s, steering).columns.size
    with NetworkPolicy(
        model, width, len(action_labels(s, steering)), max_bytes=len(model),
        continuous=steering == "continuous",
    ) as decide:  # fmt: skip
        return float(evaluate(s, decide, steering=steering).summary["success_rate"])


def cartpole_rate(decisions: int, quick: bool = False) -> float:
    """PPO's training decisions/s on CartPole-v1 with ``ENVS`` environments (SB3's own
    DummyVecEnv, the ecosystem's usual case), with the same rollouts as NanoNav's."""
    _quiet_torch()
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env

    env = make_vec_env("CartPole-v1", n_envs=ENVS, seed=0)
    rollout: dict[str, Any] = {"n_steps": 16, "batch_size": 64} if quick else {}
    model = PPO("MlpPolicy", env, seed=0, device="cpu", **rollout)
    started = time.perf_counter()
    model.learn(total_timesteps=decisions)
    return int(model.num_timesteps) / (time.perf_counter() - started)


def _paired(treated: list[float], baseline: list[float]) -> stats.PairedComparison:
    return stats.paired(treated, baseline)


# long: a benchmark's command line and its printed table, in order
def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--decisions", type=int, default=300_000, help="PPO's training")
    parser.add_argument("--recurrent-decisions", type=int, default=100_000)
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--seeds-from", type=int, default=FRESH_SEEDS)
    parser.add_argument("--worlds", type=int, default=5, help="evaluation worlds per run")
    parser.add_argument("--radii", help="comma-separated robot radii, um (default: 0.5,1,2,5)")
    parser.add_argument("--steering", choices=STEERINGS, default="discrete")
    parser.add_argument("--decision-interval-s", type=float, help="default: the physics'")
    parser.add_argument("--preset", choices=PRESETS, default=PRESET)
    parser.add_argument(
        "--gradient-memory-s", type=float, default=0.0,
        help="physics.gradient_memory_s of every policy (sensor 'counted' only)",
    )  # fmt: skip
    parser.add_argument(
        "--sensor", choices=("counted", "each_step"), help="physics.sensor (default: the preset's)"
    )
    parser.add_argument("--quick", action="store_true", help="a smoke run")
    args = parser.parse_args(argv)
    steering = args.steering
    setup: Setup = (args.decision_interval_s, args.preset, args.gradient_memory_s, args.sensor)
    baselines = (*BASELINES, TURN_RULE) if steering == "continuous" else BASELINES
    radii = tuple(float(r) for r in args.radii.split(",")) if args.radii else RADII
    decisions = {"ppo": args.decisions, "recurrent-ppo": args.recurrent_decisions}
    seeds = range(args.seeds_from, args.seeds_from + args.seeds)
    worlds = args.worlds
    if args.quick:
        radii, seeds, worlds = radii[:1], range(args.seeds_from, args.seeds_from + 2), 1
        decisions = {"ppo": 512, "recurrent-ppo": 256}
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as out, ProcessPoolExecutor(os.cpu_count() or 1) as pool:
        training_jobs = [
            (algo, r, decisions[algo], out, args.quick, steering, setup)
            for algo in LEARNERS
            for r in radii
        ]
        trained = dict(zip(training_jobs, pool.map(train, training_jobs), strict=True))
        where = {(job[0], job[1]): found["where"] for job, found in trained.items()}
        jobs = [
            (policy, r, seed, worlds, where.get((policy, r), ""), steering, setup)
            for r in radii
            for policy in (*baselines, *LEARNERS)
            for seed in seeds
        ]
        reached = dict(zip(jobs, pool.map(run_one, jobs), strict=True))
        cartpole = pool.submit(cartpole_rate, min(decisions["ppo"], 100_000), args.quick).result()
    SETUP["now"] = setup
    shown = scenario(radii[0], 0, "gradient", 1)
    every = shown.decision_steps * shown.physics.step_s
    memory = f", gradient memory {args.gradient_memory_s:g} s" if args.gradient_memory_s else ""
    print(
        f"{args.preset}: {shown.robots.count} robot(s), {shown.physics.time_limit_s:g} s"
        f"{memory}, a decision every {every:g} s (the deep "
        f"learners steering {steering}ly); trained on design "
        f"seeds {DESIGN_SEEDS}.. ({ENVS} worlds of one robot), evaluated on seeds "
        f"{seeds.start}..{seeds.stop - 1} x {worlds} worlds; * = the 95 % interval excludes 0\n"
    )
    print("Training rate (one core each):")
    for (algo, r, *_), found in trained.items():
        rate = found["decisions"] / found["seconds"]
        robot_steps = rate * found["steps_per_decision"]
        print(f"  {algo:14} R = {r:g} um: {found['decisions']:,} decisions in "
              f"{found['seconds']:.0f} s, {rate:,.0f} decisions/s ({robot_steps:,.0f} "
              "robot-steps/s)")  # fmt: skip
    print(f"  PPO on CartPole-v1 ({ENVS} envs, DummyVecEnv): {cartpole:,.0f} decisions/s\n")

    def shares(policy: str, r: float) -> list[float]:
        return [
            reached[(policy, r, seed, worlds, where.get((policy, r), ""), steering, setup)]
            for seed in seeds
        ]

    comparisons = [(r, learner, base) for r in radii for learner in LEARNERS for base in baselines]
    found = {c: _paired(shares(c[1], c[0]), shares(c[2], c[0])) for c in comparisons}
    adjusted = dict(
        zip(comparisons, stats.holm([found[c].p_value or 1.0 for c in comparisons]), strict=True)
    )
    print(f"Share reached, and each deep learner minus each baseline ({len(comparisons)} "
          "comparisons; Holm's p over all of them):")  # fmt: skip
    for r in radii:
        cells = "  ".join(f"{p} {mean_ci(shares(p, r))}" for p in (*baselines, *LEARNERS))
        print(f"R = {r:g} um: {cells}")
        for learner in LEARNERS:
            for base in baselines:
                d = found[(r, learner, base)]
                if d.mean_difference is None or d.ci_low is None or d.ci_high is None:
                    continue
                mark = "*" if d.ci_low > 0 or d.ci_high < 0 else " "
                print(f"  {learner} - {base}: {d.mean_difference:+.2f} [{d.ci_low:+.2f}, "
                      f"{d.ci_high:+.2f}]{mark} p {d.p_value:.3g}, Holm "
                      f"{adjusted[(r, learner, base)]:.3g}")  # fmt: skip
    print(f"\n({time.perf_counter() - started:.0f} s on {os.cpu_count()} cores)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
