"""``nanonav train``: a deep learner of Stable-Baselines3 (PPO, recurrent PPO from sb3-contrib,
DQN) trained on a scenario's worlds through ``nanonav.env.baselines.NanoNavVecEnv``, with a
progress bar, TensorBoard logs and checkpoints.

Needs the ``rl`` extra. Its libraries (and torch) are imported when the subcommand runs, so that
every other command starts without them.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

from nanonav.cli.common import EXIT_OK, Subcommands, UsageError, positive
from nanonav.cli.run import load_scenario
from nanonav.scenario import PRESETS, STEERINGS

ALGOS = ("ppo", "recurrent-ppo", "dqn")
RL_EXTRA = "pip install torch==2.13.0, then pip install 'nanonav[rl]'"


def add_train(subcommands: Subcommands) -> None:
    train = subcommands.add_parser(
        "train",
        help="train a deep learner (Stable-Baselines3) on a scenario's worlds",
        description="Train PPO, recurrent PPO or DQN on one robot per world of the scenario, "
        "--envs worlds stepped together (world k drawn from seed + k), for --steps decisions "
        "in all. Writes model.zip (Stable-Baselines3's own file, for your own use), policy.onnx "
        "(observation -> action logits; recurrent PPO's with its memory in and out), "
        "checkpoints/, tensorboard/ (tensorboard --logdir DIR/tensorboard), scenario.json and "
        "training.json into --out. "
        f"Needs the rl extra ({RL_EXTRA}).",
    )
    train.add_argument("--preset", choices=sorted(PRESETS), help="base values of the scenario")
    train.add_argument("--scenario", type=Path, metavar="FILE.json", help="scenario as JSON")
    train.add_argument(
        "--seed", type=int, metavar="N",
        help="the first training world's seed (train on seeds you will not evaluate on)",
    )  # fmt: skip
    train.add_argument("--algo", choices=ALGOS, default="ppo", help="the learner (default: ppo)")
    train.add_argument(
        "--steering", choices=STEERINGS, default="discrete",
        help="active_brownian: by the action set (default), or by a continuous turn (side, up) "
        "in the robot's body frame, observing its sensed gradient in that frame (ppo and "
        "recurrent-ppo; policy.onnx then gives the turn)",
    )  # fmt: skip
    train.add_argument("--steps", type=positive, required=True, help="decisions, all worlds")
    train.add_argument("--envs", type=positive, default=8, help="worlds stepped together")
    train.add_argument(
        "--rollout", type=positive, metavar="STEPS",
        help="ppo and recurrent-ppo: decisions each world takes between two updates "
        "(Stable-Baselines3's n_steps; default 2048, so that a run is at least 2048 x --envs "
        "decisions)",
    )  # fmt: skip
    train.add_argument(
        "--checkpoint-every", type=positive, metavar="STEPS",
        help="decisions between two checkpoints (default: a quarter of --steps)",
    )  # fmt: skip
    train.add_argument("--out", type=Path, required=True, metavar="DIR")
    train.add_argument("--no-progress", action="store_true", help="no progress bar")
    train.set_defaults(handler=_train)


def _model(algo: str, env: Any, seed: int, logs: Path, rollout: int | None) -> Any:
    """The learner, with the library's default hyperparameters but ``rollout`` (a first run to
    compare with the rules; tune them on design seeds)."""
    from stable_baselines3 import DQN, PPO

    common: dict[str, Any] = {"seed": seed, "tensorboard_log": str(logs), "device": "cpu"}
    if algo == "dqn":
        return DQN("MlpPolicy", env, **common)
    if rollout is not None:
        # a minibatch of 64 (the default) or the whole rollout, if that is smaller
        common |= {"n_steps": rollout, "batch_size": min(64, rollout * env.num_envs)}
    if algo == "ppo":
        return PPO("MlpPolicy", env, **common)
    from sb3_contrib import RecurrentPPO

    return RecurrentPPO("MlpLstmPolicy", env, **common)


def _train(args: argparse.Namespace) -> int:
    scenario = load_scenario(args.scenario, preset=args.preset, seed=args.seed)
    if args.steering == "continuous":
        if args.algo == "dqn":
            raise UsageError(["--steering continuous: dqn chooses among actions; use ppo"])
        if scenario.physics.model != "active_brownian":
            raise UsageError(["--steering continuous needs physics.model 'active_brownian'"])
    if args.rollout is not None and args.algo == "dqn":
        raise UsageError(["--rollout: dqn learns from a replay buffer, not from rollouts"])
    try:
        from stable_baselines3.common.callbacks import CheckpointCallback

        from nanonav.env.baselines import NanoNavVecEnv, export_onnx
    except ImportError as missing:
        raise UsageError([f"training needs the rl extra ({RL_EXTRA}): {missing}"]) from None
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    env = NanoNavVecEnv(args.envs, scenario, steering=args.steering)
    env.seed(scenario.seed)
    model = _model(args.algo, env, scenario.seed, out / "tensorboard", args.rollout)
    every = args.checkpoint_every or max(args.steps // 4, 1)
    checkpoints = CheckpointCallback(
        save_freq=max(every // args.envs, 1), save_path=str(out / "checkpoints"),
        name_prefix=args.algo,
    )  # fmt: skip
    started = time.perf_counter()
    model.learn(
        total_timesteps=args.steps, callback=checkpoints, progress_bar=not args.no_progress,
        tb_log_name=args.algo,
    )  # fmt: skip
    seconds = time.perf_counter() - started
    model.save(out / "model.zip")
    exported = "policy.onnx"
    export_onnx(
        model, out / "policy.onnx", observation=env.observation_labels,
        actions=env.action_labels,
    )  # fmt: skip
    (out / "scenario.json").write_text(scenario.model_dump_json(indent=1) + "\n")
    done = int(model.num_timesteps)
    report = {
        "algo": args.algo, "decisions": done, "envs": args.envs, "seed": scenario.seed,
        "seconds": round(seconds, 3), "decisions_per_s": round(done / max(seconds, 1e-9), 1),
        "decision_interval_steps": scenario.decision_steps, "steering": args.steering,
        "onnx": exported,
    }  # fmt: skip
    (out / "training.json").write_text(json.dumps(report, indent=1) + "\n")
    print(
        f"trained {args.algo} for {done:,} decisions in {seconds:.1f} s "
        f"({report['decisions_per_s']:,.0f}/s, {args.envs} worlds); wrote {out}"
    )
    return EXIT_OK
