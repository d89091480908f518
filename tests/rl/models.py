"""ONNX models built node by node (``onnx.helper``), as a network exported elsewhere would be:
a small multilayer perceptron, one that always prefers one action, and broken ones."""

from __future__ import annotations

from typing import Any

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

OPSET = 17


def _model(
    nodes: list[onnx.NodeProto],
    weights: list[onnx.TensorProto],
    inputs: list[onnx.ValueInfoProto],
    output: onnx.ValueInfoProto,
    *,
    opset: int = OPSET,
    domains: tuple[tuple[str, int], ...] = (),
    metadata: dict[str, str] | None = None,
) -> bytes:
    graph = helper.make_graph(nodes, "policy", inputs, [output], initializer=weights)
    imports = [helper.make_opsetid("", opset)] + [helper.make_opsetid(d, v) for d, v in domains]
    model = helper.make_model(graph, opset_imports=imports, producer_name="tests")
    model.ir_version = 8
    for key, value in (metadata or {}).items():
        entry = model.metadata_props.add()
        entry.key, entry.value = key, value
    return bytes(model.SerializeToString())


def observation(width: int, batch: Any = "batch") -> onnx.ValueInfoProto:
    return helper.make_tensor_value_info("observation", TensorProto.FLOAT, [batch, width])


def logits(actions: int) -> onnx.ValueInfoProto:
    return helper.make_tensor_value_info("logits", TensorProto.FLOAT, ["batch", actions])


def mlp(width: int, actions: int, *, seed: int = 0, hidden: int = 16, **options: Any) -> bytes:
    """observation -> Gemm -> Relu -> Gemm -> logits, weights drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    weights = [
        numpy_helper.from_array(rng.normal(size=(width, hidden)).astype(np.float32), "w1"),
        numpy_helper.from_array(rng.normal(size=hidden).astype(np.float32), "b1"),
        numpy_helper.from_array(rng.normal(size=(hidden, actions)).astype(np.float32), "w2"),
        numpy_helper.from_array(rng.normal(size=actions).astype(np.float32), "b2"),
    ]
    nodes = [
        helper.make_node("Gemm", ["observation", "w1", "b1"], ["h"]),
        helper.make_node("Relu", ["h"], ["r"]),
        helper.make_node("Gemm", ["r", "w2", "b2"], ["logits"]),
    ]
    return _model(nodes, weights, [observation(width)], logits(actions), **options)


def mlp_weights(width: int, actions: int, *, seed: int = 0, hidden: int = 16) -> list[Any]:
    """The arrays ``mlp`` draws, to compute its logits with numpy."""
    rng = np.random.default_rng(seed)
    return [
        rng.normal(size=(width, hidden)).astype(np.float32),
        rng.normal(size=hidden).astype(np.float32),
        rng.normal(size=(hidden, actions)).astype(np.float32),
        rng.normal(size=actions).astype(np.float32),
    ]


def always(width: int, actions: int, action: int, **options: Any) -> bytes:
    """Logits that prefer ``action`` whatever the observation: observation x 0 + one-hot."""
    bias = np.zeros(actions, dtype=np.float32)
    bias[action] = 1.0
    weights = [
        numpy_helper.from_array(np.zeros((width, actions), dtype=np.float32), "w"),
        numpy_helper.from_array(bias, "b"),
    ]
    nodes = [helper.make_node("Gemm", ["observation", "w", "b"], ["logits"])]
    return _model(nodes, weights, [observation(width)], logits(actions), **options)


def argmax_actions(width: int, actions: int, *, favourite: int = 0) -> bytes:
    """A model that answers action numbers, (batch,) int64, not logits: the column of the
    largest observation among the first ``actions`` (``favourite`` where they tie)."""
    bias = np.zeros(actions, dtype=np.float32)
    bias[favourite] = 1e-3
    weights = [
        numpy_helper.from_array(np.eye(width, actions, dtype=np.float32), "w"),
        numpy_helper.from_array(bias, "b"),
    ]
    nodes = [
        helper.make_node("MatMul", ["observation", "w"], ["product"]),
        helper.make_node("Add", ["product", "b"], ["scores"]),
        helper.make_node("ArgMax", ["scores"], ["action"], axis=1, keepdims=0),
    ]
    out = helper.make_tensor_value_info("action", TensorProto.INT64, ["batch"])
    return _model(nodes, weights, [observation(width)], out)


def custom_operator(width: int, actions: int) -> bytes:
    nodes = [helper.make_node("Secret", ["observation"], ["logits"], domain="com.example")]
    return _model(nodes, [], [observation(width)], logits(actions),
                  domains=(("com.example", 1),))  # fmt: skip


def external_weights(width: int, actions: int) -> bytes:
    """An MLP whose weight names a file outside the model for its data."""
    data = onnx.load_model_from_string(always(width, actions, 0))
    tensor = data.graph.initializer[0]
    tensor.ClearField("raw_data")
    tensor.ClearField("float_data")
    tensor.data_location = TensorProto.EXTERNAL
    for key, value in (("location", "/etc/passwd"), ("offset", "0"), ("length", "64")):
        entry = tensor.external_data.add()
        entry.key, entry.value = key, value
    return bytes(data.SerializeToString())


def outer_product(width: int, actions: int) -> bytes:
    """A model that asks for a (batch, width, 2000) intermediate: more numbers per
    observation than a policy needs."""
    weights = [numpy_helper.from_array(np.ones((1, 1, 2000), dtype=np.float32), "wide")]
    nodes = [
        helper.make_node("Unsqueeze", ["observation", "axis"], ["column"]),
        helper.make_node("Mul", ["column", "wide"], ["big"]),
        helper.make_node("ReduceSum", ["big", "axes"], ["summed"], keepdims=0),
        helper.make_node("Slice", ["summed", "start", "stop", "axis_1"], ["logits"]),
    ]
    weights += [
        numpy_helper.from_array(np.array([2], dtype=np.int64), "axis"),
        numpy_helper.from_array(np.array([2], dtype=np.int64), "axes"),
        numpy_helper.from_array(np.array([0], dtype=np.int64), "start"),
        numpy_helper.from_array(np.array([actions], dtype=np.int64), "stop"),
        numpy_helper.from_array(np.array([1], dtype=np.int64), "axis_1"),
    ]
    return _model(nodes, weights, [observation(width)], logits(actions))


def beyond_once_sensing(width: int, actions: int) -> bytes:
    """Action 0 for a zero observation (it passes the trial run), but action ``actions``, one
    past the last, as soon as the reading (column 0) is positive: a model that fails at run
    time."""
    weights = [
        numpy_helper.from_array(np.array([0], dtype=np.int64), "zero"),
        numpy_helper.from_array(np.array([1], dtype=np.int64), "one"),
        numpy_helper.from_array(np.array([0.0], dtype=np.float32), "nothing"),
        numpy_helper.from_array(np.array([actions], dtype=np.int64), "past"),
    ]
    nodes = [
        helper.make_node("Slice", ["observation", "zero", "one", "one"], ["reading"]),
        helper.make_node("Greater", ["reading", "nothing"], ["sensed"]),
        helper.make_node("Cast", ["sensed"], ["counted"], to=TensorProto.INT64),
        helper.make_node("Mul", ["counted", "past"], ["chosen"]),
        helper.make_node("Squeeze", ["chosen", "one"], ["action"]),
    ]
    out = helper.make_tensor_value_info("action", TensorProto.INT64, ["batch"])
    return _model(nodes, weights, [observation(width)], out)


def counter(width: int, actions: int) -> bytes:
    """A recurrent model: its memory (batch, 1) counts the decisions of each row, and it
    chooses action 0 for the first three, then action 1 (logits [1, count - 2.5, 0, ...])."""
    weights = [
        numpy_helper.from_array(np.array([[1.0]], dtype=np.float32), "one"),
        numpy_helper.from_array(np.eye(1, actions, 1, dtype=np.float32), "to_second"),
        numpy_helper.from_array(
            np.array([1.0, -2.5] + [0.0] * (actions - 2), dtype=np.float32), "bias"
        ),
        numpy_helper.from_array(np.zeros((width, actions), dtype=np.float32), "ignore"),
    ]
    nodes = [
        helper.make_node("Add", ["memory_in", "one"], ["memory_out"]),
        helper.make_node("MatMul", ["memory_out", "to_second"], ["counted"]),
        helper.make_node("MatMul", ["observation", "ignore"], ["nothing"]),
        helper.make_node("Add", ["counted", "nothing"], ["summed"]),
        helper.make_node("Add", ["summed", "bias"], ["logits"]),
    ]
    memory_in = helper.make_tensor_value_info("memory_in", TensorProto.FLOAT, ["batch", 1])
    memory_out = helper.make_tensor_value_info("memory_out", TensorProto.FLOAT, ["batch", 1])
    graph = helper.make_graph(
        nodes, "counter", [observation(width), memory_in], [logits(actions), memory_out],
        initializer=weights,
    )  # fmt: skip
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", OPSET)])
    model.ir_version = 8
    return bytes(model.SerializeToString())
