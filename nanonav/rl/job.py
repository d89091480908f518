"""A network a job trains (``robots.policy`` ``ppo`` or ``recurrent_ppo``): NanoNav's own
trainer (``nanonav.rl.training``) run in a folder of its own for the job's
``learning.decisions``, on worlds drawn apart from every evaluation's, asked between rollouts
whether to go on, its checkpoints handed to whoever keeps them (a worker keeps them in the
store), and taken up again from one; then exported as ONNX, for the job to evaluate as it
evaluates any network it is given.

A resumed run is not the run an unbroken one would have been: every world is drawn afresh
from its generator where the checkpoint left it (an episode under way is not resumed), and
with the collector one rollout ahead, the rollout collected when it stopped is collected
again with the checkpoint's weights."""

from __future__ import annotations

import math
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from nanonav.engine.observations import action_labels, observation_of
from nanonav.rl.checkpoint import CHECKPOINT
from nanonav.rl.ppo import PPOConfig, Update
from nanonav.rl.training import (
    POLICY,
    SCENARIO,
    Hooks,
    RunSettings,
    TrainingStopped,
    train,
)
from nanonav.scenario import Scenario, Steering

# recurrent_ppo's memory: the GRU of 25 units of Alonso & Kirkegaard's policies
MEMORY_UNITS = 25
# a job's network chooses among the scenario's actions by number
STEERING: Steering = "discrete"
# rows of a training curve over a whole run (more for a run shorter than that many rollouts
# is not possible: a row is at least a rollout)
CURVE_ROWS = 20


@dataclass(frozen=True)
class Checkpoint:
    """A run's state at ``decisions`` (``checkpoint.pt``'s bytes) and its curve so far."""

    decisions: int
    data: bytes
    curve: list[dict[str, Any]]


# what a job's metrics say of its training (``training.json``'s keys)
SUMMARY_KEYS = (
    "algo", "decisions", "decisions_this_run", "decisions_per_s", "seconds", "startup_s",
    "envs", "memory_units", "threads", "device", "peak_memory_mb",
)  # fmt: skip


@dataclass(frozen=True)
class Trained:
    """A trained network (ONNX bytes, what it observes and chooses among, its memory's
    width), the trainer's report (``training.json``), its curve, and the decisions it was
    resumed from (None: trained from the start)."""

    model: bytes
    observation: list[str]
    actions: list[str]
    memory: int
    report: dict[str, Any]
    curve: list[dict[str, Any]]
    resumed_from: int | None

    def summary(self) -> dict[str, Any]:
        """What a job says of its training: what was trained, how long, how fast (this
        worker's part of it, when it was resumed), and from where."""
        said = {key: self.report.get(key) for key in SUMMARY_KEYS}
        return {**said, "resumed_from_decisions": self.resumed_from}


@dataclass
class Curve:
    """A training curve: a row every ``every`` decisions of the training episodes that ended
    since the last row (their actions sampled, as the trainer takes them): ``decisions``
    done, ``episodes`` ended, the share of them that reached a cell (``success_rate``) and
    their mean ``return``."""

    every: int
    rows: list[dict[str, Any]] = field(default_factory=list)
    _episodes: int = 0
    _reached: int = 0
    _returns: float = 0.0

    def add(self, update: Update) -> bool:
        """Count ``update``'s episodes in; True when that closed a row."""
        self._episodes += update.episodes
        self._reached += update.reached
        if update.mean_return is not None:
            self._returns += update.mean_return * update.episodes
        last = self.rows[-1]["decisions"] if self.rows else 0
        if update.decisions - last >= self.every:
            self.close(update.decisions)
            return True
        return False

    def close(self, decisions: int) -> None:
        """End the row at ``decisions`` (none when no rollout was added since the last)."""
        if self.rows and self.rows[-1]["decisions"] >= decisions:
            return
        ended = self._episodes
        self.rows.append(
            {
                "decisions": decisions,
                "episodes": ended,
                "success_rate": self._reached / ended if ended else None,
                "return": self._returns / ended if ended else None,
            }
        )
        self._episodes, self._reached, self._returns = 0, 0, 0.0


def config_of(scenario: Scenario, *, overlap: bool = True) -> PPOConfig:
    """The trainer's settings for a job: its defaults (the fast settings), a GRU of 25 for
    ``recurrent_ppo``, the scenario's seed."""
    units = MEMORY_UNITS if scenario.robots.policy == "recurrent_ppo" else 0
    return PPOConfig(memory_units=units, seed=scenario.seed, overlap=overlap)


def train_network(
    scenario: Scenario,
    *,
    keep_going: Callable[[int], bool],
    keep: Callable[[Checkpoint], None],
    resume: Checkpoint | None = None,
    threads: int = 1,
    device: str = "auto",
    overlap: bool = True,
    grew: Callable[[list[dict[str, Any]]], None] | None = None,
) -> Trained | None:
    """Train the network ``scenario`` asks for (``learning.decisions``), from ``resume``
    where given; ``keep_going(decisions)`` is asked after every rollout (False stops the run
    and None is returned), ``keep`` is given each checkpoint (every
    ``learning.checkpoint_decisions``) before the run's end, and ``grew`` the curve's rows
    each time a row is added (so a job's page draws the curve as it grows)."""
    if not scenario.trains:
        raise ValueError(f"robots.policy '{scenario.robots.policy}' trains no network")
    goal = scenario.training_decisions
    config = config_of(scenario, overlap=overlap)
    every = math.ceil(scenario.checkpoint_every / config.batch) * config.batch
    curve = Curve(every=max(config.batch, math.ceil(goal / CURVE_ROWS)))
    if resume is not None:
        curve.rows = [dict(row) for row in resume.curve]

    def after(update: Update) -> None:
        if curve.add(update) and grew is not None:
            grew([dict(row) for row in curve.rows])
        if not keep_going(update.decisions):
            raise TrainingStopped

    def checkpointed(path: Path, decisions: int) -> None:
        curve.close(decisions)
        keep(Checkpoint(decisions, path.read_bytes(), [dict(row) for row in curve.rows]))

    settings = RunSettings(threads=threads, device=device, checkpoint_every=every, progress=None)
    hooks = Hooks(after=after, checkpointed=checkpointed)
    with tempfile.TemporaryDirectory(prefix="nanonav-training-") as folder:
        out = Path(folder)
        learned = scenario.network_scenario()
        if resume is not None:
            (out / SCENARIO).write_text(learned.model_dump_json(indent=1) + "\n")
            (out / CHECKPOINT).write_bytes(resume.data)
        try:
            report = train(
                out, goal, scenario=learned, config=config, steering=STEERING,
                resume=resume is not None, settings=settings, apart=True, hooks=hooks,
            )  # fmt: skip
        except TrainingStopped:
            return None
        curve.close(int(report["decisions"]))
        model = (out / POLICY).read_bytes()
    return Trained(
        model=model,
        observation=list(observation_of(learned, STEERING).labels),
        actions=list(action_labels(learned, STEERING)),
        memory=config.memory_units,
        report=report,
        curve=curve.rows,
        resumed_from=None if resume is None else resume.decisions,
    )
