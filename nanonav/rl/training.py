"""A training run of NanoNav's own trainer in a folder, as ``nanonav train`` runs it: the
worlds, the learner, a line of progress every few seconds, a checkpoint every so many
decisions, and at the end the network exported as ONNX and ``training.json``.

The folder holds everything a later ``--resume`` needs: ``scenario.json`` and
``checkpoint.pt`` (``nanonav.rl.checkpoint``). ``training.json`` says how fast the run went:
its decisions over the wall-clock seconds of its training loop (rollouts, updates and
checkpoints alike), and separately the seconds it took to start (the worlds drawn, the engine
loaded from numba's cache or compiled, the collector's process started).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import json
import resource
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

import torch

from nanonav.env.arrays import NanoNavArrayEnv
from nanonav.rl.checkpoint import load_checkpoint, save_checkpoint
from nanonav.rl.export import export_network
from nanonav.rl.ppo import PPO, PPOConfig, Update
from nanonav.scenario import Scenario, Steering

POLICY = "policy.onnx"
WEIGHTS = "model.pt"
REPORT = "training.json"
SCENARIO = "scenario.json"


@dataclass(frozen=True)
class RunSettings:
    """How a run runs, as against what it learns (``PPOConfig``): these may change when it
    resumes. ``checkpoint_every``: decisions between checkpoints (None: a quarter of the
    run); ``progress``: where the lines of progress go (None: nowhere)."""

    threads: int = 1
    device: str = "auto"
    checkpoint_every: int | None = None
    progress_every_s: float = 5.0
    progress: TextIO | None = sys.stdout


class TrainingStopped(Exception):
    """Raised by a hook to end a run between two rollouts (a cancel, a time limit, a
    shutdown); the run's folder keeps its last checkpoint."""


@dataclass(frozen=True)
class Hooks:
    """What a run tells the program that runs it (a worker's job): ``after`` each rollout's
    update (it may raise ``TrainingStopped``), and ``checkpointed`` with the file and the
    decisions done each time a checkpoint before the run's end is written."""

    after: Callable[[Update], None] | None = None
    checkpointed: Callable[[Path, int], None] | None = None


def device_of(name: str) -> torch.device:
    """``auto``: the GPU where torch sees one, else the CPU."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    return torch.device(name)


# glibc's mallopt parameters, and the most it takes for the first (32 MB on 64 bits)
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
MMAP_THRESHOLD_MAX = 32 * 1024 * 1024


def keep_freed_memory() -> bool:
    """Ask glibc to keep the memory a minibatch frees for the next one, rather than hand it
    back to the system and fault it in again, zeroed, page by page: a rollout of 1,024
    worlds took 51,000 page faults and 0.13 s of system time, and the run went a fifth
    faster without them. Tensors up to 32 MB come from the heap, whose top is not trimmed.
    False where the C library is not glibc (nothing is changed)."""
    name = ctypes.util.find_library("c")
    if name is None or not sys.platform.startswith("linux"):
        return False
    try:
        mallopt = ctypes.CDLL(name).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    kept = mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD_MAX)
    return bool(kept and mallopt(M_TRIM_THRESHOLD, 2**31 - 1))


def peak_memory_mb() -> float:
    """The most memory this process has held at once (its peak resident set), MB."""
    kilobytes = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return float(kilobytes) / 1024.0


class _Progress:
    """A line every ``every_s`` seconds (and the last): decisions, their rate since the
    run's loop began, the mean return of the episodes ended since the last line. Flushed,
    so that it is read as it goes when stdout is a file or a pipe."""

    def __init__(self, out: TextIO | None, every_s: float, goal: int, first: int) -> None:
        self.out = out
        self.every_s = every_s
        self.goal = goal
        self.first = first
        self.started = time.perf_counter()
        self.shown = self.started
        self.returns: list[tuple[float, int]] = []
        self.last: Update | None = None
        self.said = -1  # the decisions of the last line printed

    def __call__(self, update: Update, *, last: bool = False) -> None:
        if update is not self.last and update.mean_return is not None:
            self.returns.append((update.mean_return, update.episodes))
        self.last = update
        now = time.perf_counter()
        if self.out is None or self.said == update.decisions:
            return
        if now - self.shown < self.every_s and not last:
            return
        self.shown, self.said = now, update.decisions
        rate = (update.decisions - self.first) / max(now - self.started, 1e-9)
        episodes = sum(n for _, n in self.returns)
        ended = (
            f"mean return {sum(r * n for r, n in self.returns) / episodes:.3g} "
            f"({episodes:,} episodes)"
            if episodes
            else "no episode ended"
        )
        self.returns = []
        left = (self.goal - update.decisions) / rate if rate > 0 else 0.0
        print(
            f"{update.decisions:,}/{self.goal:,} decisions  {rate:,.0f}/s  {ended}  "
            f"entropy {update.entropy:.3f}  {now - self.started:.0f} s, {max(left, 0):.0f} s left",
            file=self.out,
            flush=True,
        )


# long: a run's life in order: resume, train in stretches, checkpoint, export, report
def train(
    out: Path,
    decisions: int,
    *,
    scenario: Scenario | None = None,
    config: PPOConfig | None = None,
    steering: Steering = "discrete",
    resume: bool = False,
    settings: RunSettings | None = None,
    labels: dict[str, Any] | None = None,
    apart: bool = False,
    hooks: Hooks | None = None,
) -> dict[str, Any]:
    """Train in ``out`` until ``decisions`` are done in all, and return what
    ``training.json`` says. A new run takes ``scenario``, ``config`` and ``steering`` (and
    writes ``scenario.json``); ``resume`` takes them from ``out`` and its checkpoint, and
    goes on from the decisions it holds. ``labels`` are written into the report as given.
    ``apart``: the worlds drawn apart from every evaluation's (``NanoNavArrayEnv``)."""
    began = time.perf_counter()
    settings = settings or RunSettings()
    torch.set_num_threads(settings.threads)
    keep_freed_memory()
    device = device_of(settings.device)
    state: dict[str, Any] | None = None
    if resume:
        state = load_checkpoint(out)
        scenario = Scenario.model_validate_json((out / SCENARIO).read_text())
        config = PPOConfig.of_json(state["config"])
        steering = state["steering"]
        apart = bool(state.get("apart", False))
    if scenario is None or config is None:
        raise ValueError("a new run needs its scenario and its config")
    out.mkdir(parents=True, exist_ok=True)
    if not resume:
        (out / SCENARIO).write_text(scenario.model_dump_json(indent=1) + "\n")
    env = NanoNavArrayEnv(config.envs, scenario, steering=steering, apart=apart)
    hooks = hooks or Hooks()
    with PPO(env, config, device=device) as learner:
        if state is not None:
            learner.load_state_dict(state)
        first = learner.decisions
        every = settings.checkpoint_every or max(decisions // 4, config.batch)
        learner.prepare()
        progress = _Progress(settings.progress, settings.progress_every_s, decisions, first)
        told = hooks.after

        def after(update: Update) -> None:
            progress(update)
            if told is not None:
                told(update)

        started = time.perf_counter()
        # in stretches that each end at a checkpoint: the learner's ``learn`` returns with no
        # rollout under way (with overlap, the next one collected and kept for the next
        # stretch, so that checkpoints neither stop the overlap nor change what is learned)
        while learner.decisions < decisions:
            learner.learn(min(learner.decisions + every, decisions), after)
            state = {**learner.state_dict(), "steering": steering}
            if apart:  # written only where it is true: older checkpoints load as they were
                state["apart"] = True
            path = save_checkpoint(out, state)
            if hooks.checkpointed is not None and learner.decisions < decisions:
                hooks.checkpointed(path, learner.decisions)
        seconds = time.perf_counter() - started
        if progress.last is not None:
            progress(progress.last, last=True)
    torch.save({"config": config.to_json(), "net": learner.net.state_dict()}, out / WEIGHTS)
    export_network(learner.net, out / POLICY, observation=env.observation_labels,
                   actions=env.action_labels)  # fmt: skip
    done = learner.decisions - first
    last = progress.last
    report = {
        "algo": "recurrent-ppo" if config.memory_units else "ppo",
        **(labels or {}),
        "library": "nanonav",
        "decisions": learner.decisions,
        "decisions_this_run": done,
        "resumed_from": first if resume else None,
        "envs": config.envs,
        "seed": scenario.seed,
        "seconds": round(seconds, 3),
        "decisions_per_s": round(done / max(seconds, 1e-9), 1),
        "startup_s": round(started - began, 3),
        "rollout_s": None if last is None else round(last.rollout_s, 3),
        "update_s": None if last is None else round(last.update_s, 3),
        "decision_interval_steps": scenario.decision_steps,
        "steering": steering,
        "memory_units": config.memory_units,
        "threads": settings.threads,
        "device": str(device),
        # the learner's process and the collector's (with overlap), each at its peak
        "peak_memory_mb": round(peak_memory_mb() + learner.collector_peak_memory_mb, 1),
        "collector_peak_memory_mb": round(learner.collector_peak_memory_mb, 1),
        "config": config.to_json(),
        "onnx": POLICY,
    }
    (out / REPORT).write_text(json.dumps(report, indent=1) + "\n")
    return report
