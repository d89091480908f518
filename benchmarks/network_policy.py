"""A network evaluated by the service's own path (``nanonav.rl.evaluate`` with an ONNX model
run by onnxruntime, as a worker runs a ``policy_from`` network), beside a Q-table evaluated by
``simulate`` in the same worlds, in the same run: robot-steps per second of the evaluation.

    python benchmarks/network_policy.py            # about a minute
    python benchmarks/network_policy.py --quick    # a smoke run
    python benchmarks/network_policy.py --against REV   # the network, REV's and this tree's

The network is a multilayer perceptron of two hidden layers of 64 (tanh, as Stable-Baselines3's
MlpPolicy), random weights, observation -> action logits, opset 17. Cases, 1,000 robots in one
world, every robot decided in one inference call a decision (the simultaneous schedule):

- ``lattice``: 'paper-swarm' with 1,000 robots (the paper's behaviours), a decision every step;
- ``active_brownian``: 'tumour-microswimmers' (R = 2 um) with 1,000 robots, a decision every
  step (dt_s 10 ms), then every 0.1 s (10 steps) and every 1 s (100 steps), each action held.

The table is an all-ones table of the scenario's layout (its greedy choice is the first action,
whatever the state): what matters is the cost of deciding, not what is decided. A robot-step is
one robot moved one step; a robot that reaches a cell stops. Figures are medians of 3 repeats,
timing the evaluation alone (onnxruntime's session and numba are warmed up first). Target: at
least 1,000,000 robot-steps/s with a decision every step.

Each case also prints what the work budget predicts the evaluation costs (``Scenario.work``
and ``scenario.work.decision_work`` for the network, in seconds at a nanosecond a unit) beside
what it took. ``--against REV`` measures the network, case by case, at a git revision and in
this tree alternately (``against.py``): before and after a change to how a network is run.
"""

from __future__ import annotations

import argparse
import itertools
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

sys.path.insert(0, str(Path(__file__).resolve().parent))

from against import side_by_side
from env import REPEATS, median_rate

from nanonav.engine import qlearning, simulate

try:
    from nanonav.engine.observations import action_labels, observation_of
except ImportError:  # a tree of --against from before engine/observations.py
    from nanonav.engine.worlds import action_labels, observation_of  # type: ignore[attr-defined,no-redef]
from nanonav.rl.evaluate import evaluate
from nanonav.rl.onnx_policy import NetworkPolicy
from nanonav.scenario import Scenario

ROBOTS = 1000
HIDDEN = 64
TARGET_RATE = 1_000_000
LATTICE: dict[str, Any] = {"preset": "paper-swarm"}
BROWNIAN: dict[str, Any] = {"preset": "tumour-microswimmers", "physics": {"robot_radius_um": 2.0}}


def mlp(width: int, actions: int, seed: int = 0) -> bytes:
    """observation -> Gemm 64 -> Tanh -> Gemm 64 -> Tanh -> Gemm -> logits."""
    rng = np.random.default_rng(seed)
    sizes = [width, HIDDEN, HIDDEN, actions]
    weights, nodes, last = [], [], "observation"
    for layer, (fan_in, fan_out) in enumerate(itertools.pairwise(sizes)):
        w = (rng.normal(size=(fan_in, fan_out)) / np.sqrt(fan_in)).astype(np.float32)
        b = np.zeros(fan_out, np.float32)
        weights += [
            numpy_helper.from_array(w, f"w{layer}"),
            numpy_helper.from_array(b, f"b{layer}"),
        ]
        out = "logits" if layer == len(sizes) - 2 else f"h{layer}"
        nodes.append(helper.make_node("Gemm", [last, f"w{layer}", f"b{layer}"], [out]))
        if out != "logits":
            nodes.append(helper.make_node("Tanh", [out], [f"a{layer}"]))
            out = f"a{layer}"
        last = out
    graph = helper.make_graph(
        nodes, "mlp",
        [helper.make_tensor_value_info("observation", TensorProto.FLOAT, ["batch", width])],
        [helper.make_tensor_value_info("logits", TensorProto.FLOAT, ["batch", actions])],
        initializer=weights,
    )  # fmt: skip
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    return bytes(model.SerializeToString())


def scenario(base: dict[str, Any], steps: int, interval_s: float | None = None) -> Scenario:
    data = {**base, "robots": {"count": ROBOTS, "schedule": "simultaneous", "policy": "q_learning"},
            "seed": 7,
            "evaluation": {"worlds": 1}}  # fmt: skip
    learning: dict[str, Any] = {"episodes": 0}
    if "physics" in base:
        data["physics"] = {**base["physics"], "time_limit_s": steps * 0.01}
        if interval_s is not None:
            learning["decision_interval_s"] = interval_s
    else:
        learning["max_steps"] = steps
    data["learning"] = learning
    return Scenario.model_validate(data)


def network(s: Scenario) -> NetworkPolicy:
    """The MLP for ``s``'s robots, loaded (close it after)."""
    width = observation_of(s).columns.size
    model = mlp(width, len(action_labels(s)))
    return NetworkPolicy(model, width, len(action_labels(s)), max_bytes=len(model))


def by_network(s: Scenario, policy: NetworkPolicy) -> Callable[[], tuple[int, float]]:
    def run() -> tuple[int, float]:
        result = evaluate(s, policy)
        return int(result.work["robot_steps"]), float(result.work["engine_s"])

    return run


def predicted_s(s: Scenario, policy: NetworkPolicy) -> tuple[float, float]:
    """What the work budget predicts the network's evaluation of ``s`` costs, seconds (a unit
    a nanosecond), and what one evaluation took."""
    try:
        from nanonav.scenario.work import decision_work
    except ImportError:  # a tree of --against from before it moved there
        from nanonav.rl.evaluate import decision_work  # type: ignore[attr-defined,no-redef]

    cost = getattr(getattr(policy, "info", None), "cost", None)
    units = s.work + decision_work(s, cost.multiply_adds if cost is not None else 0)
    started = time.perf_counter()
    evaluate(s, policy)
    return units * 1e-9, time.perf_counter() - started


def by_table(s: Scenario) -> Callable[[], tuple[int, float]]:
    states, actions = qlearning.labels(s.learning.actions, s.communication.model)
    table = np.ones((len(states), len(actions)))

    def run() -> tuple[int, float]:
        result = simulate(s, policy=table)
        return int(result.work["robot_steps"]), float(result.work["engine_s"])

    return run


def cases(steps: int) -> list[tuple[str, Scenario]]:
    return [
        ("lattice, every step", scenario(LATTICE, steps)),
        ("active_brownian, every step", scenario(BROWNIAN, steps, 0.01)),
        ("active_brownian, every 0.1 s", scenario(BROWNIAN, steps, 0.1)),
        ("active_brownian, every 1 s", scenario(BROWNIAN, steps, 1.0)),
    ]


def network_rate(label: str, steps: int = 1000) -> float:
    """The network's robot-steps/s in one case (what ``--against`` compares)."""
    s = dict(cases(steps))[label]
    policy = network(s)
    try:
        by_network(s, policy)()  # warm-up
        return median_rate(by_network(s, policy))
    finally:
        getattr(policy, "close", lambda: None)()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="short episodes: a smoke run")
    parser.add_argument("--against", metavar="REV", help="the network at REV and here, only")
    parser.add_argument("--measure", help=argparse.SUPPRESS)  # one case of --against, as JSON
    args = parser.parse_args(argv)
    steps = 200 if args.quick else 1000
    if args.measure:
        print(network_rate(args.measure, steps))
        return 0
    if args.against:
        labels = [label for label, _ in cases(steps)]
        print(f"The ONNX MLP's evaluation of {ROBOTS:,} robots, robot-steps/s (median of "
              f"{REPEATS}), at {args.against} and in this tree:")  # fmt: skip
        side_by_side(Path(__file__).resolve(), labels, args.against)
        return 0
    for _, s in cases(steps)[:1]:  # warm-up: numba's kernels and onnxruntime's first session
        with network(s) as policy:
            by_network(s, policy)()
        by_table(s)()
    print(f"Evaluation of {ROBOTS:,} robots in one world, robot-steps/s (median of {REPEATS}):")
    print(f"  {'case':32} {'ONNX MLP 64x64':>16} {'Q-table':>12}  network/table")
    verdicts = []
    predictions = []
    for label, s in cases(steps):
        with network(s) as policy:
            rate = median_rate(by_network(s, policy))
            predictions.append((label, *predicted_s(s, policy)))
        table = median_rate(by_table(s))
        print(f"  {label:32} {rate:16,.0f} {table:12,.0f}  {rate / table:.2f}")
        if label.endswith("every step"):
            verdicts.append((label, rate))
    print("What the work budget predicts an evaluation costs, beside what it took (s):")
    for label, predicted, took in predictions:
        print(f"  {label:32} predicted {predicted:8.3f}  took {took:8.3f}  "
              f"predicted/took {predicted / took:.2f}")  # fmt: skip
    for label, rate in verdicts:
        verdict = "meets" if rate >= TARGET_RATE else "BELOW"
        print(f"{verdict} target: ONNX MLP, {label}, {rate:,.0f} vs {TARGET_RATE:,} robot-steps/s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
