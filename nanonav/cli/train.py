"""``nanonav train``: a deep learner trained on a scenario's worlds. By default NanoNav's own
PPO (``nanonav.rl.ppo``: thousands of worlds at once, an optional GRU memory, checkpoints a
run resumes from); with ``--library sb3`` Stable-Baselines3's PPO, sb3-contrib's recurrent
PPO or DQN through ``nanonav.env.baselines.NanoNavVecEnv``, as before.

Needs the ``rl`` extra. Its libraries (and torch) are imported when the subcommand runs, so that
every other command starts without them.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from nanonav.cli.common import EXIT_OK, Subcommands, UsageError, add_set_option, positive
from nanonav.cli.run import load_scenario
from nanonav.scenario import PRESETS, STEERINGS

ALGOS = ("ppo", "recurrent-ppo", "dqn")
LIBRARIES = ("nanonav", "sb3")
MEMORIES = ("none", "gru")
RL_EXTRA = "pip install torch==2.13.0, then pip install 'nanonav[rl]'"
# Stable-Baselines3's worlds and rollout when none are given (what `nanonav train` used)
SB3_ENVS = 8
# Our trainer's options that set a field of its config of the same name (each None unless given)
CONFIG_OPTIONS = (
    "envs",
    "rollout",
    "epochs",
    "minibatch",
    "learning_rate",
    "gamma",
    "gae_lambda",
    "entropy",
    "bptt",
    "layers",
    "actor",
    "critic",
    "activation",
    "overlap",
)
# What a resumed run takes from its folder: given with --resume, each is refused
RUN_OPTIONS = ("preset", "scenario", "seed", "memory", "memory_units", *CONFIG_OPTIONS)


def _layers(text: str) -> tuple[int, ...]:
    """Hidden layers as their widths, comma-separated (``64,64``); empty for none."""
    try:
        widths = tuple(int(part) for part in text.split(",") if part.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"not widths separated by commas: {text!r}") from None
    if any(w < 1 for w in widths):
        raise argparse.ArgumentTypeError(f"a layer's width must be at least 1: {text!r}")
    return widths


def _share(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"must lie in 0 .. 1, not {value}")
    return value


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not value > 0.0:
        raise argparse.ArgumentTypeError(f"must be above 0, not {value}")
    return value


# long: the command's flags, one after another, each with its help
def add_train(subcommands: Subcommands) -> None:
    train = subcommands.add_parser(
        "train",
        help="train a deep learner on a scenario's worlds",
        description="Train a deep learner on one robot per world of the scenario, --envs "
        "worlds stepped together (world k drawn from seed + k), for --steps decisions in all. "
        "By default NanoNav's own PPO, fast for many worlds (one batched forward a decision, "
        "large minibatches, one torch thread): it writes policy.onnx (observation -> action "
        "logits, or the turn; with a memory, the memory in and out), model.pt (the weights), "
        "checkpoint.pt (what --resume DIR takes up), scenario.json and training.json into "
        "--out, and prints its progress as it goes. --library sb3 trains Stable-Baselines3's "
        "PPO, sb3-contrib's recurrent PPO or DQN instead, writing model.zip, checkpoints/ and "
        "tensorboard/ too. "
        f"Needs the rl extra ({RL_EXTRA}).",
    )
    train.add_argument("--preset", choices=sorted(PRESETS), help="base values of the scenario")
    train.add_argument("--scenario", type=Path, metavar="FILE.json", help="scenario as JSON")
    train.add_argument(
        "--seed", type=int, metavar="N",
        help="the first training world's seed (train on seeds you will not evaluate on)",
    )  # fmt: skip
    add_set_option(train, "the scenario file's")
    train.add_argument(
        "--algo", choices=ALGOS, default="ppo",
        help="the learner (default: ppo); recurrent-ppo is ppo with a memory (--memory gru); "
        "dqn is Stable-Baselines3's",
    )  # fmt: skip
    train.add_argument(
        "--library", choices=LIBRARIES,
        help="whose trainer: nanonav (the default; ppo and recurrent-ppo) or sb3 "
        "(Stable-Baselines3 and sb3-contrib; the default for dqn)",
    )  # fmt: skip
    train.add_argument(
        "--steering", choices=STEERINGS, default="discrete",
        help="active_brownian: by the action set (default), or by a continuous turn (side, up) "
        "in the robot's body frame, observing its sensed gradient in that frame (ppo and "
        "recurrent-ppo; policy.onnx then gives the turn)",
    )  # fmt: skip
    train.add_argument(
        "--steps", type=positive, required=True,
        help="decisions, all worlds (with --resume: in all, those done included)",
    )  # fmt: skip
    train.add_argument(
        "--envs", type=positive, help="worlds stepped together (default: 1024; sb3's 8)"
    )
    train.add_argument(
        "--rollout", type=positive, metavar="STEPS",
        help="ppo and recurrent-ppo: decisions each world takes between two updates (default "
        "64; sb3's n_steps, 2048, so that a run is at least 2048 x --envs decisions)",
    )  # fmt: skip
    learning = train.add_argument_group(
        "NanoNav's trainer", "what it learns with (defaults: the fast settings, "
        "docs/explanation/speed.md); a resumed run keeps its own",
    )  # fmt: skip
    learning.add_argument(
        "--memory", choices=MEMORIES,
        help="a GRU memory carried from decision to decision (default: none for ppo, gru for "
        "recurrent-ppo)",
    )  # fmt: skip
    learning.add_argument(
        "--memory-units", type=positive, metavar="N", help="the GRU's units (default 25)"
    )
    learning.add_argument(
        "--layers", type=_layers, metavar="W,W",
        help="hidden layers the actor and the critic share, after the memory (default 64,64; "
        "'' for none)",
    )  # fmt: skip
    learning.add_argument(
        "--actor", type=_layers, metavar="W,W", help="the actor's own hidden layers (default none)"
    )
    learning.add_argument(
        "--critic", type=_layers, metavar="W,W",
        help="the critic's own hidden layers (default none; Alonso & Kirkegaard's: --layers '' "
        "--actor 64,64 --critic 128,128)",
    )  # fmt: skip
    learning.add_argument(
        "--activation", choices=("relu", "tanh"),
        help="between hidden layers (default relu; tanh, the anchor's, costs a fifth more here)",
    )  # fmt: skip
    learning.add_argument(
        "--overlap", action=argparse.BooleanOptionalAction,
        help="collect the next rollout in a second process while learning from the last, its "
        "policy one update behind (the default; --no-overlap: in turn, in one process)",
    )  # fmt: skip
    learning.add_argument("--epochs", type=positive, help="passes over a rollout (default 4)")
    learning.add_argument(
        "--minibatch", type=positive, metavar="DECISIONS", help="a gradient step's (default 8192)"
    )
    learning.add_argument(
        "--bptt", type=positive, metavar="DECISIONS",
        help="with a memory: the decisions gradients flow back through (default 16)",
    )  # fmt: skip
    learning.add_argument(
        "--learning-rate", type=_positive_float, metavar="RATE", help="Adam's (default 3e-4)"
    )
    learning.add_argument("--gamma", type=_share, help="the discount a decision (default 0.99)")
    learning.add_argument("--gae-lambda", type=_share, help="GAE's lambda (default 0.95)")
    learning.add_argument("--entropy", type=_share, help="the entropy bonus (default 0.01)")
    learning.add_argument(
        "--threads", type=positive, default=1,
        help="torch threads (default 1: a second one gains little here and collapses when the "
        "cores are shared)",
    )  # fmt: skip
    learning.add_argument(
        "--device", default="auto", help="torch's device: auto (a GPU where there is one), cpu, "
        "cuda, cuda:1, ...",
    )  # fmt: skip
    learning.add_argument(
        "--resume", type=Path, metavar="DIR",
        help="go on with the run in DIR from its checkpoint (its scenario and settings) until "
        "--steps decisions in all, writing into DIR",
    )  # fmt: skip
    train.add_argument(
        "--checkpoint-every", type=positive, metavar="STEPS",
        help="decisions between two checkpoints (default: a quarter of --steps)",
    )  # fmt: skip
    train.add_argument("--out", type=Path, metavar="DIR", help="where the run is written")
    train.add_argument("--no-progress", action="store_true", help="no progress printed")
    train.add_argument(
        "--progress-every", type=_positive_float, default=5.0, metavar="SECONDS",
        help="seconds between two lines of progress (default 5), each flushed as it is "
        "written, to a file or a pipe too",
    )  # fmt: skip
    train.set_defaults(handler=_train)


def _model(algo: str, env: Any, seed: int, logs: Path, rollout: int | None) -> Any:
    """Stable-Baselines3's learner, with the library's default hyperparameters but ``rollout``
    (a first run to compare with the rules; tune them on design seeds)."""
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
    library = args.library or ("sb3" if args.algo == "dqn" else "nanonav")
    if library == "nanonav" and args.algo == "dqn":
        raise UsageError(["--algo dqn is Stable-Baselines3's: --library sb3"])
    if args.resume is not None:
        return _resume(args, library)
    if args.out is None:
        raise UsageError(["--out DIR: where the run is written (or --resume DIR)"])
    scenario = load_scenario(args.scenario, preset=args.preset, seed=args.seed,
                             settings=args.settings)  # fmt: skip
    if args.steering == "continuous":
        if args.algo == "dqn":
            raise UsageError(["--steering continuous: dqn chooses among actions; use ppo"])
        if scenario.physics.model != "active_brownian":
            raise UsageError(["--steering continuous needs physics.model 'active_brownian'"])
    if args.rollout is not None and args.algo == "dqn":
        raise UsageError(["--rollout: dqn learns from a replay buffer, not from rollouts"])
    if library == "sb3":
        ours = [name for name in ("memory", "memory_units", *CONFIG_OPTIONS[2:])
                if getattr(args, name) is not None]  # fmt: skip
        if ours:
            flags = ", ".join("--" + name.replace("_", "-") for name in ours)
            raise UsageError([f"{flags}: NanoNav's trainer's, not --library sb3's"])
        return _train_sb3(args, scenario)
    return _train_nanonav(args, scenario)


def _config(args: argparse.Namespace, seed: int) -> Any:
    from nanonav.rl.ppo import PPOConfig

    memory = args.memory or ("gru" if args.algo == "recurrent-ppo" else "none")
    if args.algo == "recurrent-ppo" and memory == "none":
        raise UsageError(["--algo recurrent-ppo learns with a memory: drop --memory none"])
    if memory == "none" and args.memory_units is not None:
        raise UsageError(["--memory-units: with a memory only (--memory gru)"])
    given = {
        name: getattr(args, name) for name in CONFIG_OPTIONS if getattr(args, name) is not None
    }
    units = (args.memory_units or 25) if memory == "gru" else 0
    try:
        return PPOConfig(**given, memory_units=units, seed=seed)
    except ValueError as error:
        raise UsageError([str(error)]) from None


def _settings(args: argparse.Namespace) -> Any:
    from nanonav.rl.training import RunSettings, device_of

    try:
        device_of(args.device)
    except RuntimeError as error:
        raise UsageError([f"--device {args.device}: {error}"]) from None
    return RunSettings(
        threads=args.threads, device=args.device, checkpoint_every=args.checkpoint_every,
        progress=None if args.no_progress else sys.stdout, progress_every_s=args.progress_every,
    )  # fmt: skip


def _import_trainer() -> Any:
    try:
        from nanonav.rl import training
    except ImportError as missing:
        raise UsageError([f"training needs the rl extra ({RL_EXTRA}): {missing}"]) from None
    return training


def _train_nanonav(args: argparse.Namespace, scenario: Any) -> int:
    training = _import_trainer()
    config = _config(args, scenario.seed)
    settings = _settings(args)
    report = training.train(
        args.out, args.steps, scenario=scenario, config=config, steering=args.steering,
        settings=settings, labels={"algo": args.algo},
    )  # fmt: skip
    _say_trained(args.algo, report, args.out)
    return EXIT_OK


def _resume(args: argparse.Namespace, library: str) -> int:
    if library != "nanonav":
        raise UsageError(["--resume takes up a run of NanoNav's trainer, not --library sb3's"])
    given = [name for name in RUN_OPTIONS if getattr(args, name) is not None]
    given += ["set"] if args.settings else []
    if given:
        flags = ", ".join("--" + name.replace("_", "-") for name in given)
        raise UsageError([f"{flags}: a resumed run keeps its scenario and settings"])
    folder: Path = args.resume
    if args.out is not None and args.out.resolve() != folder.resolve():
        raise UsageError(["--resume DIR writes into DIR: drop --out"])
    training = _import_trainer()
    if not (folder / "checkpoint.pt").is_file() or not (folder / training.SCENARIO).is_file():
        raise UsageError([f"{folder} holds no run to resume (checkpoint.pt and scenario.json)"])
    report = training.train(folder, args.steps, resume=True, settings=_settings(args))
    _say_trained(report["algo"], report, folder)
    return EXIT_OK


def _say_trained(algo: str, report: dict[str, Any], out: Path) -> None:
    resumed = report.get("resumed_from")
    since = f" (from {resumed:,})" if resumed is not None else ""
    print(
        f"trained {algo} to {report['decisions']:,} decisions{since} in {report['seconds']:.1f} s "
        f"({report['decisions_per_s']:,.0f}/s, {report['envs']} worlds); wrote {out}"
    )


def _train_sb3(args: argparse.Namespace, scenario: Any) -> int:
    try:
        import torch
        from stable_baselines3.common.callbacks import CheckpointCallback

        from nanonav.env.baselines import NanoNavVecEnv, export_onnx
    except ImportError as missing:
        raise UsageError([f"training needs the rl extra ({RL_EXTRA}): {missing}"]) from None
    torch.set_num_threads(args.threads)
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    envs = args.envs or SB3_ENVS
    env = NanoNavVecEnv(envs, scenario, steering=args.steering)
    env.seed(scenario.seed)
    model = _model(args.algo, env, scenario.seed, out / "tensorboard", args.rollout)
    every = args.checkpoint_every or max(args.steps // 4, 1)
    checkpoints = CheckpointCallback(
        save_freq=max(every // envs, 1), save_path=str(out / "checkpoints"),
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
        "algo": args.algo, "library": "sb3", "decisions": done, "envs": envs,
        "seed": scenario.seed, "seconds": round(seconds, 3),
        "decisions_per_s": round(done / max(seconds, 1e-9), 1),
        "decision_interval_steps": scenario.decision_steps, "steering": args.steering,
        "threads": args.threads, "onnx": exported,
    }  # fmt: skip
    (out / "training.json").write_text(json.dumps(report, indent=1) + "\n")
    _say_trained(args.algo, report, out)
    return EXIT_OK
