"""The transition band asked with the anchor's budgets: in 'alonso-kirkegaard', does a learner
trained for 10^8 to 10^9 decisions beat the strongest rule, for robots of what size?

    python benchmarks/transition_band.py train --radius 1 --learner gru --decisions 100000000
    python benchmarks/transition_band.py report [--seeds 20] [--worlds 20]
    python benchmarks/transition_band.py --quick          # a smoke run of both

``train`` trains one learner at one radius with NanoNav's trainer (``nanonav.rl.training``)
into ``runs/transition-band/R-um-LEARNER`` (``--out``), in stages of 10^6, 3 x 10^6, 10^7, ...
decisions up to ``--decisions``; after each stage it evaluates the policy on the curve seeds
and adds a point to the run's ``curve.json``. Each stage resumes from the last checkpoint, so
a run that was stopped (a session's end, a kill) goes on from its last checkpoint (one every
10^7 decisions) when ``train`` is given again, and a longer ``--decisions`` extends a finished one.

- ``gru``: a GRU of 25 units then a 64x64 torso the actor and the critic share (the trainer's
  fast recurrent setting; Alonso & Kirkegaard's memory size); ``mlp``: no memory, the same
  torso. Both observe what the rule reads: the count, its change, and the gradient of the
  counts averaged over the rule's own gradient memory at that radius. ``gru-counts``: the GRU
  given the last count's gradient alone (no gradient memory), as Alonso & Kirkegaard's
  recurrent policy read its counts: its memory must do the averaging. ``gru-anchor``: Alonso &
  Kirkegaard's recurrent network (a GRU of 25, then an actor of 2x64 and a critic of 2x128 of
  their own, tanh), observing what ``gru`` does.
- Training worlds are drawn from seed 100,000 on (world k of ``--envs`` from 100,000 + k), far
  from every seed evaluated here.
- The rule: ``gradient`` with the gradient memory the design seeds chose at each radius
  (``python benchmarks/strongest_rule.py --preset alonso-kirkegaard`` on seeds 5000-5009,
  among 29 rules that include temporal comparison, run and tumble on the change of the counts,
  and the remembered spatial gradient: 2 s at 0.5 and 1 um, 0.5 s at 2 um).

``report`` evaluates every finished run in ``--out`` on two sets of fresh seeds (7100.. and
7200.., ``--seeds`` x ``--worlds`` worlds each), beside the rule in the same worlds: the share
of episodes that reach the source, each learner minus the rule paired by seed with its 95 %
interval and Wilcoxon's p, Holm over every comparison of the set; what each learner's
decisions were and what it steers by (each observation shuffled across its decisions in turn,
the share of them the network then makes otherwise: ``reads``); as a second look outside the
Holm family, the same network sampling its actions as in training (``Sampled``: the greedy
export can do otherwise, as the 1 um GRU did at 3 x 10^8); and draws ``curves.png``:
each run's success on the curve seeds against the decisions it was trained for, with the
rule's level on the same seeds.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from science import mean_ci

from nanonav import stats
from nanonav.engine import simulate
from nanonav.engine.observations import action_labels, observation_of
from nanonav.scenario import Scenario, preset_scenario

PRESET = "alonso-kirkegaard"
TIME_LIMIT_S = 25.6
RADII = (0.5, 1.0, 2.0)
# the strongest rule's gradient memory, s, at each radius (design seeds; see the docstring)
RULE_MEMORY_S = {0.5: 2.0, 1.0: 2.0, 2.0: 0.5}
LEARNERS = ("gru", "mlp", "gru-counts", "gru-anchor")
# Alonso & Kirkegaard's recurrent network: a GRU of 25, then an actor of 2x64 and a critic of
# 2x128 of their own, tanh
ANCHOR_NETWORK = {"layers": (), "actor": (64, 64), "critic": (128, 128), "activation": "tanh"}
TRAINING_SEED = 100_000
CURVE_SEEDS = 8000
REPORT_FROM = (7100, 7200)
STAGES = (10**6, 3 * 10**6, 10**7, 3 * 10**7, 10**8, 3 * 10**8, 10**9, 3 * 10**9)
# decisions between two checkpoints: a minute and a half at 100,000 decisions a second, so
# that a stopped run (a session's end, a kill) loses little of a long stage
CHECKPOINT_EVERY = 10**7
OUT = Path("runs/transition-band")


def memory_s(radius: float) -> float:
    """The rule's gradient memory at ``radius`` (the nearest radius the design seeds chose for)."""
    nearest = min(RULE_MEMORY_S, key=lambda r: abs(r - radius))
    return RULE_MEMORY_S[nearest]


def observed_memory_s(radius: float, learner: str) -> float:
    """The gradient memory a learner observes through: the rule's, or none for ``gru-counts``."""
    return 0.0 if learner == "gru-counts" else memory_s(radius)


def scenario(
    radius: float, seed: int, worlds: int, policy: str = "q_learning",
    gradient_memory_s: float | None = None,
) -> Scenario:  # fmt: skip
    """The preset with one robot of ``radius`` um that remembers its counts' gradient as the
    rule does (or for ``gradient_memory_s``), over 25.6 s, evaluated in ``worlds`` worlds."""
    memory = memory_s(radius) if gradient_memory_s is None else gradient_memory_s
    physics = {"model": "active_brownian", "time_limit_s": TIME_LIMIT_S,
               "robot_radius_um": radius, "gradient_memory_s": memory}  # fmt: skip
    return preset_scenario(
        PRESET, seed=seed, physics=physics, robots={"policy": policy},
        learning={"episodes": 0}, evaluation={"worlds": worlds},
    )  # fmt: skip


def folder(out: Path, radius: float, learner: str) -> Path:
    return out / f"{radius:g}-um-{learner}"


def config(learner: str, quick: bool, overlap: bool = False) -> Any:
    from nanonav.rl.ppo import PPOConfig

    units = 0 if learner == "mlp" else 25
    network: dict[str, Any] = ANCHOR_NETWORK if learner == "gru-anchor" else {}
    if quick:
        return PPOConfig(envs=32, rollout=16, minibatch=256, bptt=8, memory_units=units,
                         seed=TRAINING_SEED, **network)  # fmt: skip
    # in turn unless asked, as the tables in docs/explanation/learning.md were trained
    return PPOConfig(memory_units=units, seed=TRAINING_SEED, overlap=overlap, **network)


class Counted:
    """A network's decisions, counted by action as they are made (what the policy learned,
    read from what it does); its memory is the network's."""

    def __init__(self, decide: Any, actions: int) -> None:
        self.decide = decide
        self.counts = np.zeros(actions, dtype=np.int64)
        self.remembers = decide.remembers

    def forget(self) -> None:
        self.decide.forget()

    def __call__(self, observations: Any) -> Any:
        chosen = self.decide(observations)
        self.counts += np.bincount(chosen, minlength=self.counts.size)
        return chosen


class Recorded:
    """A network's decisions with what it was given: every call's observations and answers, in
    order, and where its memory was started afresh (``forget``), so that they can be replayed."""

    def __init__(self, decide: Any) -> None:
        self.decide = decide
        self.remembers = decide.remembers
        self.calls: list[tuple[Any, Any]] = []
        self.fresh: set[int] = {0}

    def forget(self) -> None:
        self.fresh.add(len(self.calls))
        self.decide.forget()

    def __call__(self, observations: Any) -> Any:
        chosen = self.decide(observations)
        self.calls.append((np.array(observations, dtype=np.float32), np.array(chosen)))
        return chosen


def trained_network(run: Path, width: int, actions: int) -> tuple[Any, int]:
    """The run's network as trained (``model.pt``), in eval mode, and its memory's units."""
    import torch

    from nanonav.rl.networks import ActorCritic
    from nanonav.rl.ppo import PPOConfig

    kept = torch.load(run / "model.pt", map_location="cpu", weights_only=True)
    config = PPOConfig.of_json(kept["config"])
    net = ActorCritic(width, actions, memory_units=config.memory_units, layers=config.layers,
                      actor=config.actor, critic=config.critic,
                      activation=config.activation)  # fmt: skip
    net.load_state_dict(kept["net"])
    return net.eval(), config.memory_units


def replayed(run: Path, recorded: Recorded, calls: list[Any], actions: int) -> Any:
    """The greedy actions of the run's network (``model.pt``, as exported) for the calls'
    observations in order, its memory carried row by row as the service carries it (afresh
    where the recording forgot, or where the number of rows changed)."""
    import torch

    from nanonav.rl.networks import Greedy

    net, units = trained_network(run, calls[0].shape[1], actions)
    greedy = Greedy(net).eval()
    answers = []
    memory = None
    with torch.no_grad():
        for k, rows in enumerate(calls):
            x = torch.from_numpy(rows)
            if k in recorded.fresh or memory is None or memory.shape[0] != len(rows):
                memory = torch.zeros(len(rows), units)
            if units:
                head, memory = greedy(x, memory)
            else:
                head = greedy(x)
            answers.append(head.argmax(dim=1).numpy())
    return answers


def reads(run: Path, radius: float, learner: str, seeds: range, worlds: int) -> str:
    """What the policy steers by, read from its decisions: each observation shuffled across all
    its decisions in turn (its values kept, their link to the moment broken), the share of
    decisions the replayed network then makes otherwise. A large share: the choice rests on
    it."""
    from nanonav.rl.evaluate import evaluate
    from nanonav.rl.onnx_policy import NetworkPolicy

    memory = observed_memory_s(radius, learner)
    shown = scenario(radius, seeds.start, worlds, gradient_memory_s=memory)
    model = (run / "policy.onnx").read_bytes()
    width, labels = observation_of(shown).columns.size, action_labels(shown)
    with NetworkPolicy(model, width, len(labels), max_bytes=len(model)) as network:
        recorded = Recorded(network)
        for seed in seeds:
            evaluate(scenario(radius, seed, worlds, gradient_memory_s=memory), recorded)
    given = [rows for rows, _ in recorded.calls]
    made = np.concatenate([chosen for _, chosen in recorded.calls])
    same = np.concatenate(replayed(run, recorded, given, len(labels)))
    names = observation_of(shown).labels
    rng = np.random.default_rng(0)
    said = [f"replay agrees with the sandbox in {np.mean(same == made):.3f} of {made.size:,}"]
    for column, name in enumerate(names):
        pooled = np.concatenate([rows[:, column] for rows in given])
        shuffled = rng.permutation(pooled)
        changed, at = [], 0
        for rows in given:
            copy = rows.copy()
            copy[:, column] = shuffled[at : at + len(rows)]
            at += len(rows)
            changed.append(copy)
        other = np.concatenate(replayed(run, recorded, changed, len(labels)))
        said.append(f"{name} shuffled: {np.mean(other != same):.2f} of its decisions change")
    return "; ".join(said)


def success(
    policy: Path, radius: float, learner: str, seeds: range, worlds: int,
    counts: list[int] | None = None,
) -> list[float]:  # fmt: skip
    """The share of episodes that reach the source, a seed each, for the exported network
    ``policy`` run by the service's own path (its memory carried from decision to decision);
    ``counts``, if given, gets how often it chose each action."""
    from nanonav.rl.evaluate import evaluate
    from nanonav.rl.onnx_policy import NetworkPolicy

    memory = observed_memory_s(radius, learner)
    shown = scenario(radius, seeds.start, worlds, gradient_memory_s=memory)
    model = policy.read_bytes()
    width, actions = observation_of(shown).columns.size, len(action_labels(shown))
    found = []
    with NetworkPolicy(model, width, actions, max_bytes=len(model)) as network:
        decide = Counted(network, actions)
        for seed in seeds:
            result = evaluate(scenario(radius, seed, worlds, gradient_memory_s=memory), decide)
            found.append(float(result.summary["success_rate"]))
    if counts is not None:
        counts[:] = decide.counts.tolist()
    return found


class Sampled:
    """The run's network (``model.pt``) deciding as it was trained, by sampling its actions
    (the exported network, as the service runs it, takes the likeliest), its memory carried row
    by row as the service carries it; seeded, so that an evaluation is the same each time."""

    def __init__(self, run: Path, width: int, actions: int, seed: int) -> None:
        import torch

        self.net, units = trained_network(run, width, actions)
        self.generator = torch.Generator().manual_seed(seed)
        self.remembers = units > 0
        self.memory: Any = None

    def forget(self) -> None:
        self.memory = None

    def __call__(self, observations: Any) -> Any:
        import torch

        rows = torch.from_numpy(np.ascontiguousarray(observations, dtype=np.float32))
        if self.memory is None or self.memory.shape[0] != rows.shape[0]:
            self.memory = self.net.blank_memory(rows.shape[0])
        decision = self.net.act(rows, self.memory, self.generator)
        self.memory = decision.memory
        return decision.action.numpy().astype(np.int64)


def sampled_success(run: Path, radius: float, learner: str, seeds: range,
                    worlds: int) -> list[float]:  # fmt: skip
    """``success``, the network deciding by sampling its actions as in training (``Sampled``,
    seeded by each seed)."""
    from nanonav.rl.evaluate import evaluate

    memory = observed_memory_s(radius, learner)
    shown = scenario(radius, seeds.start, worlds, gradient_memory_s=memory)
    width, actions = observation_of(shown).columns.size, len(action_labels(shown))
    found = []
    for seed in seeds:
        decide = Sampled(run, width, actions, seed)
        result = evaluate(scenario(radius, seed, worlds, gradient_memory_s=memory), decide)
        found.append(float(result.summary["success_rate"]))
    return found


def rule_success(radius: float, seeds: range, worlds: int) -> list[float]:
    """The rule's share of episodes that reach the source, a seed each, in the same worlds."""
    return [
        float(simulate(scenario(radius, seed, worlds, "gradient")).summary["success_rate"])
        for seed in seeds
    ]


def train(radius: float, learner: str, decisions: int, out: Path, curve: tuple[int, int],
          quick: bool = False, overlap: bool = False) -> list[dict[str, Any]]:  # fmt: skip
    """Train ``learner`` at ``radius`` in stages up to ``decisions``, resuming what ``out``
    holds, and add each stage's point to its ``curve.json``: the points."""
    from nanonav.rl.checkpoint import load_checkpoint
    from nanonav.rl.training import POLICY, RunSettings
    from nanonav.rl.training import train as train_run

    run = folder(out, radius, learner)
    points_file = run / "curve.json"
    points: list[dict[str, Any]] = (
        json.loads(points_file.read_text()) if points_file.exists() else []
    )
    early = (2 * config(learner, quick).batch,) if quick else STAGES
    stages = [s for s in early if s < decisions] + [decisions]
    done = int(load_checkpoint(run)["decisions"]) if (run / "checkpoint.pt").exists() else 0
    settings = RunSettings(
        progress=None if quick else sys.stdout, progress_every_s=60.0,
        checkpoint_every=None if quick else CHECKPOINT_EVERY,
    )  # fmt: skip
    for stage in stages:
        if stage <= done and any(p["decisions"] >= stage for p in points):
            continue
        started = time.perf_counter()
        if done:
            report = train_run(run, stage, resume=True, settings=settings)
        else:
            world = scenario(radius, TRAINING_SEED, 1,
                             gradient_memory_s=observed_memory_s(radius, learner))  # fmt: skip
            report = train_run(run, stage, scenario=world,
                               config=config(learner, quick, overlap),
                               settings=settings)  # fmt: skip
        done = int(report["decisions"])
        seeds = range(CURVE_SEEDS, CURVE_SEEDS + curve[0])
        shares = success(run / POLICY, radius, learner, seeds, curve[1])
        points.append({
            "decisions": done, "success": sum(shares) / len(shares),
            "train_s": round(time.perf_counter() - started, 1),
            "decisions_per_s": report["decisions_per_s"],
            "peak_memory_mb": report["peak_memory_mb"],
        })  # fmt: skip
        points_file.write_text(json.dumps(points, indent=1) + "\n")
        print(f"R = {radius:g} um, {learner}: {done:,} decisions, success "
              f"{points[-1]['success']:.2f} on the curve seeds "
              f"({report['decisions_per_s']:,.0f} decisions/s)", flush=True)  # fmt: skip
    return points


def runs(out: Path) -> list[tuple[float, str, Path]]:
    """Every run in ``out`` that has exported a policy, by radius then learner."""
    found = []
    for radius in RADII:
        for learner in LEARNERS:
            run = folder(out, radius, learner)
            if (run / "policy.onnx").exists() and (run / "curve.json").exists():
                found.append((radius, learner, run))
    return found


def draw(out: Path, every: list[tuple[float, str, Path]], curve: tuple[int, int]) -> Path:
    """curves.png: success on the curve seeds against the decisions trained, a panel a
    radius, with the rule's level on the same seeds."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    radii = sorted({r for r, _, _ in every})
    figure, axes = plt.subplots(1, len(radii), figsize=(4.2 * len(radii), 3.6), squeeze=False)
    seeds = range(CURVE_SEEDS, CURVE_SEEDS + curve[0])
    for ax, radius in zip(axes[0], radii, strict=True):
        level = rule_success(radius, seeds, curve[1])
        ax.axhline(sum(level) / len(level), color="black", linestyle="--",
                   label=f"rule (gradient, memory {memory_s(radius):g} s)")  # fmt: skip
        for r, learner, run in every:
            if r != radius:
                continue
            points = json.loads((run / "curve.json").read_text())
            ax.plot([p["decisions"] for p in points], [p["success"] for p in points],
                    marker="o", label=f"{learner}, greedy (as the service runs it)")  # fmt: skip
        ax.set_xscale("log")
        ax.set_ylim(0, 1.05)  # a share of 1 drawn inside the frame, not on it
        ax.set_xlabel("decisions trained")
        ax.set_ylabel("share of episodes reaching the source")
        ax.set_title(f"robot radius {radius:g} µm")
        ax.legend(fontsize=7, loc="lower right")
    figure.tight_layout()
    where = out / "curves.png"
    figure.savefig(where, dpi=120)
    plt.close(figure)
    return where


def report(out: Path, seeds: int, worlds: int, sets: tuple[int, ...],
           curve: tuple[int, int]) -> int:  # fmt: skip
    every = runs(out)
    if not every:
        print(f"no finished run in {out}: train one first")
        return 1
    started = time.perf_counter()
    for start in sets:
        chosen = range(start, start + seeds)
        rules = {r: rule_success(r, chosen, worlds) for r in sorted({r for r, _, _ in every})}
        chose: dict[tuple[float, str], list[int]] = {(r, n): [] for r, n, _ in every}
        learned = {(r, learner): success(run / "policy.onnx", r, learner, chosen, worlds,
                                         chose[(r, learner)])
                   for r, learner, run in every}  # fmt: skip
        found = {key: stats.paired(shares, rules[key[0]]) for key, shares in learned.items()}
        adjusted = dict(zip(found, stats.holm([d.p_value or 1.0 for d in found.values()]),
                            strict=True))  # fmt: skip
        print(f"\nSeeds {start}-{start + seeds - 1} x {worlds} worlds; learner minus the rule "
              f"paired by seed, Holm over the {len(found)} comparisons of this set:")  # fmt: skip
        for (r, learner), d in found.items():
            trained = json.loads((folder(out, r, learner) / "curve.json").read_text())[-1]
            if d.mean_difference is None or d.ci_low is None or d.ci_high is None:
                continue
            mark = "*" if d.ci_low > 0 or d.ci_high < 0 else " "
            print(f"  R = {r:g} um  rule {mean_ci(rules[r])}  {learner} ({trained['decisions']:,} "
                  f"decisions) {mean_ci(learned[(r, learner)])}  {learner} - rule "
                  f"{d.mean_difference:+.2f} [{d.ci_low:+.2f}, {d.ci_high:+.2f}]{mark} "
                  f"p {d.p_value:.3g}, Holm {adjusted[(r, learner)]:.3g}")  # fmt: skip
            made = chose[(r, learner)]
            labels = action_labels(scenario(r, start, 1))
            total = max(sum(made), 1)
            shares = (f"{label} {n / total:.2f}" for label, n in zip(labels, made, strict=True))
            print("    its decisions: " + ", ".join(shares))
            run = folder(out, r, learner)
            # a second look, outside the set's Holm family: the same network sampling its
            # actions as it did in training, where the greedy export may differ
            drawn = sampled_success(run, r, learner, chosen, worlds)
            other = stats.paired(drawn, rules[r])
            low, high, p = other.ci_low, other.ci_high, other.p_value
            if other.mean_difference is not None and None not in (low, high, p):
                print(f"    sampled as trained: {mean_ci(drawn)}, minus the rule "
                      f"{other.mean_difference:+.2f} [{low:+.2f}, {high:+.2f}] p {p:.3g} "
                      "(not in the Holm family)")  # fmt: skip
            if start == sets[0]:  # what it steers by, on the first five seeds of the first set
                print("    what it reads: " + reads(run, r, learner, chosen[:5], worlds))
    print(f"\ncurves: {draw(out, every, curve)}")
    print(f"({time.perf_counter() - started:.0f} s)")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a smoke run: train, then report")
    parser.add_argument("--out", type=Path, default=OUT, help=f"the runs' folder ({OUT})")
    parser.add_argument("--curve-seeds", type=int, default=10, help="curve seeds (8000 on)")
    parser.add_argument("--curve-worlds", type=int, default=20)
    commands = parser.add_subparsers(dest="command")
    training = commands.add_parser("train", help="train one learner at one radius")
    training.add_argument("--radius", type=float, required=True, choices=RADII)
    training.add_argument("--learner", required=True, choices=LEARNERS)
    training.add_argument("--decisions", type=int, required=True)
    training.add_argument(
        "--overlap", action="store_true",
        help="a new run collects while it learns (nanonav train's default; the tables were "
        "trained in turn)",
    )  # fmt: skip
    reporting = commands.add_parser("report", help="every finished run against the rule")
    reporting.add_argument("--seeds", type=int, default=20)
    reporting.add_argument("--worlds", type=int, default=20)
    args = parser.parse_args(argv)
    curve = (args.curve_seeds, args.curve_worlds)
    if args.quick:
        for learner in LEARNERS:
            train(1.0, learner, 3 * config(learner, True).batch, args.out, (1, 2), quick=True)
        return report(args.out, 2, 2, REPORT_FROM, (1, 2))
    if args.command == "train":
        if args.decisions < 1:
            parser.error("--decisions: at least 1")
        train(args.radius, args.learner, args.decisions, args.out, curve,
              overlap=args.overlap)  # fmt: skip
        return 0
    if args.command == "report":
        return report(args.out, args.seeds, args.worlds, REPORT_FROM, curve)
    parser.print_help()
    return 2


if __name__ == "__main__":
    sys.exit(main())
