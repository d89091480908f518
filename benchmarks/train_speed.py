"""How fast a deep learner trains on NanoNav: decisions a second end to end (stepping the worlds,
deciding, learning, checkpointing) of ``nanonav train``, NanoNav's own trainer beside the old
one (Stable-Baselines3's) in one run, beside the raw env's rate with random actions.

    python benchmarks/train_speed.py               # about six minutes
    python benchmarks/train_speed.py --libraries   # the maintained libraries at our settings
    python benchmarks/train_speed.py --gru         # the recurrent update, old GRU and new
    python benchmarks/train_speed.py --quick       # a smoke run

The world is 'alonso-kirkegaard' (one robot, a decision every 0.1 s = 10 engine steps, three
observations, four actions). Each case runs in a fresh process (``--measure CASE``), so that
its threads, its start and its peak memory are its own; its figure is what ``training.json``
says: decisions over the wall-clock seconds of the training loop.

- raw env: ``NanoNavArrayEnv`` stepped with random actions, 1,024 and 4,096 worlds.
- new: ``nanonav train`` with its defaults (an MLP of 64x64 shared by actor and critic; GRU-25:
  ``--algo recurrent-ppo``; the next rollout collected in a second process while the learner
  learns from the last), 1,024 and 4,096 worlds, one torch thread a process; and at 1,024
  worlds ``--no-overlap`` (rollout and update in turn, in one process, as before overlap).
- old: ``nanonav train --library sb3`` (PPO and recurrent PPO with the library's defaults,
  8 worlds; recurrent PPO's rollout cut to 256 decisions a world so that it ends in seconds).
- under load: a busy process on every core while ``nanonav train`` runs with one thread and
  with two.
- ``--libraries``: Stable-Baselines3's PPO and sb3-contrib's RecurrentPPO given our settings
  (1,024 worlds, 64-decision rollouts, 4 epochs, minibatches of 8,192; an LSTM of 25), and
  TorchRL's PPO loss and GAE (``ClipPPOLoss``, ``GAE``) learning from our rollouts (its
  collector not used: an upper bound on its rate), where TorchRL is installed.
- ``--gru``: one recurrent update (GRU-25, 1,024 worlds, a 64-decision rollout) with the
  GRU stepped by ``nanonav.rl.gru`` and by ``nn.GRUCell`` in a loop (as before it), the two
  alternated six times in one process on the same rollout: the seconds of each (median).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

PRESET = "alonso-kirkegaard"
SEED = 5000
TARGET = 100_000  # decisions a second, end to end, idle


def _steps(worlds: int, rollouts: int) -> int:
    return worlds * 64 * rollouts


def _cli(args: list[str]) -> dict[str, Any]:
    """``nanonav train ARGS`` in this process, into a temporary folder: its training.json."""
    from nanonav.cli import main

    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "run"
        common = ["train", "--preset", PRESET, "--seed", str(SEED), "--no-progress"]
        code = main([*common, *args, "--out", str(out)])
        if code != 0:
            raise SystemExit(f"nanonav train {' '.join(args)} exited {code}")
        report: dict[str, Any] = json.loads((out / "training.json").read_text())
        return report


def raw_env(worlds: int, seconds: float) -> dict[str, Any]:
    import numpy as np

    from nanonav.env.arrays import NanoNavArrayEnv
    from nanonav.scenario import preset_scenario

    env = NanoNavArrayEnv(worlds, preset_scenario(PRESET, seed=SEED))
    env.reset()
    rng = np.random.default_rng(0)
    env.step(rng.integers(0, env.actions, worlds))
    done = 0
    started = time.perf_counter()
    while time.perf_counter() - started < seconds:
        env.step(rng.integers(0, env.actions, worlds))
        done += worlds
    return {"decisions_per_s": done / (time.perf_counter() - started)}


def _sb3_large(recurrent: bool, worlds: int, rollouts: int) -> dict[str, Any]:
    """SB3's PPO (or sb3-contrib's RecurrentPPO, an LSTM of 25) given our settings."""
    import torch

    torch.set_num_threads(1)
    from sb3_contrib import RecurrentPPO
    from stable_baselines3 import PPO

    from nanonav.env.baselines import NanoNavVecEnv
    from nanonav.scenario import preset_scenario

    env = NanoNavVecEnv(worlds, preset_scenario(PRESET, seed=SEED))
    env.seed(SEED)
    settings: dict[str, Any] = {"n_steps": 64, "batch_size": 8192, "n_epochs": 4, "seed": SEED,
                                "device": "cpu", "ent_coef": 0.01}  # fmt: skip
    if recurrent:
        model: Any = RecurrentPPO("MlpLstmPolicy", env, policy_kwargs={"lstm_hidden_size": 25},
                                  **settings)  # fmt: skip
    else:
        model = PPO("MlpPolicy", env, **settings)
    model.learn(total_timesteps=worlds * 64)  # the first rollout: start-up
    started = time.perf_counter()
    model.learn(total_timesteps=_steps(worlds, rollouts), reset_num_timesteps=False)
    seconds = time.perf_counter() - started
    return {"decisions_per_s": _steps(worlds, rollouts) / seconds}


def _torchrl(worlds: int, rollouts: int) -> dict[str, Any]:
    """TorchRL's ClipPPOLoss and GAE learning from our rollouts, at our settings."""
    import torch

    torch.set_num_threads(1)
    from tensordict import TensorDict
    from tensordict.nn import TensorDictModule
    from torch import nn
    from torchrl.modules import ProbabilisticActor, ValueOperator
    from torchrl.objectives import ClipPPOLoss
    from torchrl.objectives.value import GAE

    from nanonav.env.arrays import NanoNavArrayEnv
    from nanonav.rl.ppo import PPO as OurPPO
    from nanonav.rl.ppo import PPOConfig
    from nanonav.scenario import preset_scenario

    env = NanoNavArrayEnv(worlds, preset_scenario(PRESET, seed=SEED))
    ours = OurPPO(env, PPOConfig(envs=worlds, overlap=False))
    collector = ours._collector
    width, actions = env.width, env.actions

    def mlp(out: int) -> nn.Module:
        return nn.Sequential(nn.Linear(width, 64), nn.Tanh(), nn.Linear(64, 64), nn.Tanh(),
                             nn.Linear(64, out))  # fmt: skip

    actor = ProbabilisticActor(
        TensorDictModule(mlp(actions), in_keys=["observation"], out_keys=["logits"]),
        in_keys=["logits"], distribution_class=torch.distributions.Categorical,
        return_log_prob=True,
    )  # fmt: skip
    critic = ValueOperator(mlp(1), in_keys=["observation"])
    loss = ClipPPOLoss(actor, critic, clip_epsilon=0.2, entropy_coeff=0.01)
    advantage = GAE(gamma=0.99, lmbda=0.95, value_network=critic, average_gae=True)
    optimizer = torch.optim.Adam(loss.parameters(), lr=3e-4)
    r = ours._rollout

    def rollout() -> TensorDict:
        collector.collect(r)  # our stepping and sampling; the learning below is TorchRL's
        assert collector.obs is not None
        shape = (worlds, 64)
        done = r.dones.T.bool().unsqueeze(-1)
        nxt = torch.cat([r.obs[1:], collector.obs.unsqueeze(0)]).transpose(0, 1)
        return TensorDict({
            "observation": r.obs.transpose(0, 1), "action": r.actions.T.long(),
            "action_log_prob": r.log_probs.T,
            "next": {"observation": nxt, "reward": r.rewards.T.unsqueeze(-1), "done": done,
                     "terminated": done},
        }, batch_size=shape)  # fmt: skip

    def learn() -> None:
        data = rollout()
        for _ in range(4):
            with torch.no_grad():
                advantage(data)
            flat = data.reshape(-1)
            order = torch.randperm(flat.shape[0])
            for at in range(0, flat.shape[0], 8192):
                losses = loss(flat[order[at : at + 8192]])
                total = losses["loss_objective"] + losses["loss_critic"] + losses["loss_entropy"]
                optimizer.zero_grad()
                total.backward()
                torch.nn.utils.clip_grad_norm_(loss.parameters(), 0.5)
                optimizer.step()

    learn()
    started = time.perf_counter()
    for _ in range(rollouts):
        learn()
    return {"decisions_per_s": _steps(worlds, rollouts) / (time.perf_counter() - started)}


def gru_update(worlds: int, repeats: int) -> dict[str, list[float]]:
    """Seconds of one recurrent update, the GRU stepped by ``nanonav.rl.gru`` ("new") and by
    ``nn.GRUCell`` in a loop ("old"), alternated on the same rollout."""
    import torch

    import nanonav.rl.networks as networks
    from nanonav.env.arrays import NanoNavArrayEnv
    from nanonav.rl.ppo import PPO, PPOConfig
    from nanonav.rl.training import keep_freed_memory
    from nanonav.scenario import preset_scenario

    torch.set_num_threads(1)
    keep_freed_memory()

    def cell_loop(cell: Any, x: Any, memory: Any, starts: Any) -> Any:
        keep = (~starts).unsqueeze(-1).to(x.dtype)
        outputs, h = [], memory
        for t in range(x.shape[1]):
            h = cell(x[:, t], h * keep[:, t])
            outputs.append(h)
        return torch.stack(outputs, dim=1)

    env = NanoNavArrayEnv(worlds, preset_scenario(PRESET, seed=SEED))
    learner = PPO(env, PPOConfig(envs=worlds, memory_units=25, overlap=False))
    learner.learn(worlds * 64)
    learner._collector.collect(learner._rollout)
    ways = {"new": networks.gru_sequence, "old": cell_loop}
    seconds: dict[str, list[float]] = {name: [] for name in ways}
    try:
        for _ in range(repeats):
            for name, way in ways.items():
                networks.gru_sequence = way
                started = time.perf_counter()
                learner._update(learner._rollout)
                seconds[name].append(time.perf_counter() - started)
    finally:
        networks.gru_sequence = ways["new"]
    return seconds


def _spin(stop: Any) -> None:
    while not stop.is_set():
        sum(range(10_000))


def under_load(args: list[str]) -> dict[str, Any]:
    """``nanonav train ARGS`` while a busy process runs on every core."""
    stop = multiprocessing.Event()
    spinners = [multiprocessing.Process(target=_spin, args=(stop,))
                for _ in range(os.cpu_count() or 1)]  # fmt: skip
    for p in spinners:
        p.start()
    try:
        return _cli(args)
    finally:
        stop.set()
        for p in spinners:
            p.join()


def cases(quick: bool) -> dict[str, tuple[str, Callable[[], dict[str, Any]]]]:
    """Every case by name: (its group, how it is measured)."""
    small, large = (64, 256) if quick else (1024, 4096)
    n = 2 if quick else 0
    few = 1 if quick else 3

    def new(worlds: int, rollouts: int, *extra: str) -> Callable[[], dict[str, Any]]:
        return lambda: _cli(["--envs", str(worlds), "--steps", str(_steps(worlds, rollouts)),
                             *extra])  # fmt: skip

    old_steps = "1024" if quick else "16384"
    old_recurrent = ["--rollout", "64" if quick else "256", "--steps", "512" if quick else "2048"]
    return {
        f"raw env, {small:,} worlds": ("env", lambda: raw_env(small, 0.5 if quick else 3.0)),
        f"raw env, {large:,} worlds": ("env", lambda: raw_env(large, 0.5 if quick else 3.0)),
        f"new, MLP, {small:,} worlds": ("new", new(small, n or 24)),
        # eight rollouts or more: a run's first is collected alone, and in a short run it
        # would weigh as it never does in a long one
        f"new, MLP, {large:,} worlds": ("new", new(large, n or 12)),
        f"new, GRU-25, {small:,} worlds": ("new", new(small, n or 16, "--algo", "recurrent-ppo")),
        f"new, GRU-25, {large:,} worlds": ("new", new(large, n or 8, "--algo", "recurrent-ppo")),
        f"new in turn (--no-overlap), MLP, {small:,} worlds": (
            "new", new(small, n or 24, "--no-overlap")),
        f"new in turn (--no-overlap), GRU-25, {small:,} worlds": (
            "new", new(small, n or 16, "--algo", "recurrent-ppo", "--no-overlap")),
        "old, SB3 PPO, 8 worlds": (
            "old", lambda: _cli(["--library", "sb3", "--steps", old_steps, "--threads", "1"])),
        "old, SB3 recurrent PPO, 8 worlds": (
            "old", lambda: _cli(["--library", "sb3", "--algo", "recurrent-ppo", "--threads", "1",
                                 *old_recurrent])),
        f"new, MLP, {small:,} worlds, 1 thread": (
            "load", lambda: under_load(["--envs", str(small), "--steps",
                                        str(_steps(small, n or 10))])),
        f"new in turn (--no-overlap), MLP, {small:,} worlds, 1 thread": (
            "load", lambda: under_load(["--envs", str(small), "--no-overlap", "--steps",
                                        str(_steps(small, n or 10))])),
        f"new, MLP, {small:,} worlds, 2 threads": (
            "load", lambda: under_load(["--envs", str(small), "--threads", "2", "--steps",
                                        str(_steps(small, n or 4))])),
        "SB3 PPO, our settings": ("library", lambda: _sb3_large(False, small, few)),
        "sb3-contrib RecurrentPPO, our settings (LSTM-25)": (
            "library", lambda: _sb3_large(True, small, 1)),
        "TorchRL ClipPPOLoss + GAE, our settings": ("library", lambda: _torchrl(small, few)),
    }  # fmt: skip


def measure(case: str, quick: bool) -> dict[str, Any]:
    """``case`` in a fresh process: its figures, as JSON on its last line (a smoke run's in
    this one, where starting torch and the engine ten times would be most of its time)."""
    if quick:
        return cases(quick)[case][1]()
    command = [sys.executable, str(Path(__file__).resolve()), "--measure", case]
    done = subprocess.run(command + (["--quick"] if quick else []), capture_output=True,
                          text=True, check=False)  # fmt: skip
    if done.returncode != 0:
        return {"error": (done.stderr.strip().splitlines() or ["failed"])[-1]}
    found: dict[str, Any] = json.loads(done.stdout.strip().splitlines()[-1])
    return found


def _row(case: str, found: dict[str, Any], raw: float | None) -> str:
    if "error" in found:
        return f"  {case:<52} {'-':>10}  ({found['error'][:60]})"
    rate = found["decisions_per_s"]
    share = f"  {rate / raw:4.2f} of the raw env's" if raw else ""
    memory = f"  peak {found['peak_memory_mb']:,.0f} MB" if "peak_memory_mb" in found else ""
    return f"  {case:<52} {rate:>10,.0f}{share}{memory}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a smoke run")
    parser.add_argument("--libraries", action="store_true", help="the libraries, only")
    parser.add_argument("--gru", action="store_true", help="the recurrent update, old and new")
    parser.add_argument("--measure", help=argparse.SUPPRESS)  # one case, in this process
    args = parser.parse_args(argv)
    if args.gru:
        worlds = 64 if args.quick else 1024
        seconds = gru_update(worlds, 2 if args.quick else 6)
        print(f"one recurrent update (GRU-25, {worlds:,} worlds x 64 decisions), seconds, "
              "alternated in one process:")  # fmt: skip
        for name, found in seconds.items():
            way = "nanonav.rl.gru" if name == "new" else "nn.GRUCell in a loop"
            print(f"  {name} ({way}): median {statistics.median(found):.3f}  "
                  f"({', '.join(f'{x:.3f}' for x in found)})")  # fmt: skip
        return 0
    every = cases(args.quick)
    if args.measure:
        print(json.dumps(every[args.measure][1]()))
        return 0
    groups = ("library",) if args.libraries else ("env", "new", "old", "load")
    started = time.perf_counter()
    print(f"{PRESET}: decisions a second end to end, each case in its own process "
          f"(load average {os.getloadavg()[0]:.1f} at the start)")  # fmt: skip
    raw: dict[int, float] = {}
    every_small = "64 worlds" if args.quick else "1,024 worlds"
    titles = {"env": "raw env, random actions", "new": "nanonav train (NanoNav's trainer)",
              "old": "old nanonav train (--library sb3, the library's defaults)",
              "load": "under load (a busy process on each core)",
              "library": "the libraries at our settings (1 thread), beside ours"}  # fmt: skip
    for group in groups:
        print(titles[group])
        for case, (kind, _) in every.items():
            ours = group == "library" and kind == "new" and f"{every_small}" in case
            if kind != group and not ours:
                continue
            found = measure(case, args.quick)
            before = case.split(" worlds")[0].split()[-1] if " worlds" in case else "0"
            worlds = int(before.replace(",", ""))
            if group == "env" and "error" not in found:
                raw[worlds] = found["decisions_per_s"]
            print(_row(case, found, raw.get(worlds) if group == "new" else None), flush=True)
    if not args.libraries:
        print(f"target: {TARGET:,} decisions a second for MLP and GRU-25 on an idle machine")
    print(f"({time.perf_counter() - started:.0f} s; load average {os.getloadavg()[0]:.1f} at the "
          "end)")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
