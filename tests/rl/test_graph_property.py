"""Any small graph over the allowed operators either passes its check and then runs within the
cost its check counted (its process's CPU seconds and memory), or is refused naming a node.
The graphs are drawn by Hypothesis: dense layers (some of 2,100 units, their weights made in
the graph, past the caps), activations, normalisation, two heads joined, reshaping, and
logits or an ArgMax at the end."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import onnx
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from onnx import TensorProto, helper, numpy_helper

from nanonav.rl.graph import InvalidModel
from nanonav.rl.onnx_policy import NetworkPolicy
from tests.rl import models

pytestmark = pytest.mark.timeout(600)
ACTIVATIONS = ["Relu", "Tanh", "Sigmoid", "LeakyRelu", "Elu", "HardSigmoid", "Softsign", "Abs",
               "Neg", "Softplus", "Erf", "Identity"]  # fmt: skip
UNITS = [1, 3, 8, 32, 64, 2100]
NAMED_NODE = re.compile(r"^node '[^']+' \(\w+\): ")
# What a call may take beyond its counted cost: the process's own overhead, and generous
# factors for ONNX Runtime's buffers and for a machine slower than this one
CPU_OVERHEAD_S = 0.05
SECONDS_PER_MULTIPLY_ADD = 2e-9
MEMORY_OVERHEAD_BYTES = 96 * 1024 * 1024


@dataclass
class Builder:
    """A graph built node by node from the observation."""

    width: int
    nodes: list[onnx.NodeProto] = field(default_factory=list)
    weights: list[onnx.TensorProto] = field(default_factory=list)
    count: int = 0

    def name(self, stem: str) -> str:
        self.count += 1
        return f"{stem}{self.count}"

    def constant(self, array: np.ndarray) -> str:
        name = self.name("w")
        self.weights.append(numpy_helper.from_array(array, name))
        return name

    def node(self, op: str, inputs: list[str], **attributes: Any) -> str:
        out = self.name(op.lower())
        self.nodes.append(helper.make_node(op, inputs, [out], name=out, **attributes))
        return out

    def dense(self, value: str, fan_in: int, units: int, how: str, rng: np.random.Generator) -> str:
        if units > 1000:  # its weights an outer product made in the graph: a few bytes sent
            left = self.constant(np.full((fan_in, 1), 1.0 / fan_in, np.float32))
            right = self.constant(np.ones((1, units), np.float32))
            return self.node("MatMul", [value, self.node("MatMul", [left, right])])
        w = (rng.normal(size=(fan_in, units)) / np.sqrt(fan_in)).astype(np.float32)
        b = (rng.normal(size=units) * 0.1).astype(np.float32)
        if how == "Gemm":
            return self.node("Gemm", [value, self.constant(w), self.constant(b)])
        return self.node("Add", [self.node("MatMul", [value, self.constant(w)]), self.constant(b)])


@st.composite
def policies(draw: st.DrawFn) -> tuple[bytes, int, int]:
    """A graph over the allowed operators: the model, its observation's width, its actions."""
    width = draw(st.integers(1, 9))
    actions = draw(st.integers(2, 6))
    rng = np.random.default_rng(draw(st.integers(0, 2**16)))
    b = Builder(width)
    value, size = "observation", width
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["dense", "dense", "heads", "norm", "softmax", "reshape"]))
        if kind == "dense":
            units = draw(st.sampled_from(UNITS))
            value = b.dense(value, size, units, draw(st.sampled_from(["Gemm", "MatMul"])), rng)
            value, size = b.node(draw(st.sampled_from(ACTIVATIONS)), [value]), units
        elif kind == "heads":  # two heads, joined along the features or added
            units = draw(st.sampled_from(UNITS[:-1]))
            left = b.dense(value, size, units, "Gemm", rng)
            right = b.node("Tanh", [b.dense(value, size, units, "MatMul", rng)])
            if draw(st.booleans()):
                value, size = b.node("Concat", [left, right], axis=1), 2 * units
            else:
                value = b.node(draw(st.sampled_from(["Add", "Sub", "Mul", "Max", "Min"])),
                               [left, right])  # fmt: skip
                size = units
        elif kind == "norm":
            scale = b.constant(np.ones(size, np.float32))
            shift = b.constant(np.zeros(size, np.float32))
            value = b.node("LayerNormalization", [value, scale, shift], axis=-1)
        elif kind == "softmax":
            value = b.node(draw(st.sampled_from(["Softmax", "LogSoftmax"])), [value], axis=1)
        else:
            shape = b.constant(np.array([-1, 1, size], np.int64))
            flat = b.node("Reshape", [value, shape])
            value = b.node("Flatten", [b.node("Transpose", [flat], perm=[0, 2, 1])], axis=1)
    logits = b.dense(value, size, actions, "Gemm", rng)
    if draw(st.booleans()):
        out = helper.make_tensor_value_info("action", TensorProto.INT64, ["batch"])
        b.nodes.append(helper.make_node("ArgMax", [logits], ["action"], axis=1, keepdims=0))
    else:
        b.nodes.append(helper.make_node("Identity", [logits], ["logits"]))
        out = models.logits(actions)
    g = helper.make_graph(b.nodes, "drawn", [models.observation(width)], [out], b.weights)
    model = helper.make_model(g, opset_imports=[helper.make_opsetid("", models.OPSET)])
    model.ir_version = 8
    return bytes(model.SerializeToString()), width, actions


def status(pid: int) -> dict[str, int]:
    """The process's virtual memory now and at its largest, bytes."""
    found = {}
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        key, _, value = line.partition(":")
        if key in ("VmSize", "VmPeak"):
            found[key] = int(value.split()[0]) * 1024
    return found


@settings(max_examples=20, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])  # fmt: skip
@given(policies())
def test_a_graph_runs_within_its_counted_cost_or_is_refused_naming_a_node(
    drawn: tuple[bytes, int, int],
) -> None:
    model, width, actions = drawn
    try:
        policy = NetworkPolicy(model, width, actions, max_bytes=len(model))
    except InvalidModel as refused:
        assert NAMED_NODE.match(str(refused)), str(refused)
        return
    with policy:
        cost = policy.info.cost
        rows = np.random.default_rng(0).normal(size=(cost.rows_per_call, width)) * 3
        loaded = status(policy._box.pid)["VmSize"]
        before = policy.cpu_s
        chosen = policy(rows)
        assert chosen.shape == (rows.shape[0],) and chosen.min() >= 0 and chosen.max() < actions
        took = policy.cpu_s - before
        counted = rows.shape[0] * cost.multiply_adds + cost.fixed_multiply_adds
        assert took <= CPU_OVERHEAD_S + counted * SECONDS_PER_MULTIPLY_ADD, (took, cost)
        grew = status(policy._box.pid)["VmPeak"] - loaded
        live = rows.shape[0] * cost.live_bytes + cost.fixed_bytes
        assert grew <= 2 * live + MEMORY_OVERHEAD_BYTES, (grew, cost)
