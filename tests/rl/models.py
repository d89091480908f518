"""ONNX models built node by node (``onnx.helper``), as a network exported elsewhere would be:
a small multilayer perceptron, one that always prefers one action, broken ones, and the hostile
ones an attacker with a key sent: integer division that raises SIGFPE in ONNX Runtime, a chain
of large convolutions, values kept alive by the megabyte, actions far outside the action set."""

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
    """Action 0 for a zero observation, but action ``actions``, one past the last, as soon as
    the reading (column 0) is positive; it compares and multiplies integers, which a policy
    may not."""
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


def _int64(name: str, *values: int) -> onnx.TensorProto:
    return numpy_helper.from_array(np.array(values, dtype=np.int64), name)


def integer_division(width: int, *, only_when_positive: bool = False) -> bytes:
    """The audit's 300-byte model: the observation cast to int64, INT64_MIN divided by -1 (the
    one quotient that does not fit: the processor's integer division raises SIGFPE), and the
    result's largest, absolute value, modulo 4, as the action. ``only_when_positive``: the
    divisor is -1 only where an observation is 1 or more, else 1, so that zero observations
    answer."""
    weights = [_int64("one", 1), _int64("two", 2), _int64("zero", 0), _int64("four", 4),
               _int64("smallest", np.iinfo(np.int64).min)]  # fmt: skip
    nodes = [helper.make_node("Cast", ["observation"], ["whole"], to=TensorProto.INT64)]
    if only_when_positive:
        nodes += [
            helper.make_node("Min", ["whole", "one"], ["capped"]),
            helper.make_node("Max", ["capped", "zero"], ["sensed"]),
            helper.make_node("Mul", ["sensed", "two"], ["twice"]),
            helper.make_node("Sub", ["one", "twice"], ["divisor"]),
            helper.make_node("Div", ["smallest", "divisor"], ["quotient"]),
        ]
    else:
        nodes += [
            helper.make_node("Sub", ["whole", "one"], ["minus_one"]),
            helper.make_node("Mul", ["minus_one", "smallest"], ["product"]),
            helper.make_node("Div", ["product", "minus_one"], ["quotient"]),
        ]
    nodes += [
        helper.make_node("ReduceMax", ["quotient"], ["largest"], axes=[1], keepdims=0),
        helper.make_node("Abs", ["largest"], ["size"]),
        helper.make_node("Mod", ["size", "four"], ["action"]),
    ]
    out = helper.make_tensor_value_info("action", TensorProto.INT64, ["batch"])
    return _model(nodes, weights, [observation(width)], out)


def convolutions(width: int, actions: int, *, layers: int = 20) -> bytes:
    """A chain of convolutions with a 99 x 99 kernel over a 1 x 100 x 100 image of each row,
    both made with Expand: a few hundred bytes, 98 million multiply-adds an observation a
    layer."""
    weights = [
        _int64("first", 0), _int64("second", 1), _int64("image", 1, 1, 100, 100),
        _int64("column", -1, 1, 1, 1), _int64("kernel_shape", 1, 1, 99, 99),
        numpy_helper.from_array(np.full((1, 1, 1, 1), 1e-3, np.float32), "seed"),
        numpy_helper.from_array(np.ones((1, actions), np.float32), "out"),
    ]  # fmt: skip
    nodes = [
        helper.make_node("Slice", ["observation", "first", "second", "second"], ["reading"]),
        helper.make_node("Reshape", ["reading", "column"], ["pixel"]),
        helper.make_node("Expand", ["pixel", "image"], ["layer0"]),
        helper.make_node("Expand", ["seed", "kernel_shape"], ["kernel"]),
    ]
    for k in range(layers):
        nodes.append(helper.make_node("Conv", [f"layer{k}", "kernel"], [f"layer{k + 1}"],
                                      pads=[49, 49, 49, 49]))  # fmt: skip
    nodes += [
        helper.make_node("ReduceMean", [f"layer{layers}"], ["mean"], axes=[2, 3], keepdims=0),
        helper.make_node("MatMul", ["mean", "out"], ["logits"]),
    ]
    return _model(nodes, weights, [observation(width)], logits(actions))


def kept_alive(width: int, actions: int, *, values: int = 40, summed_by: str = "Sum") -> bytes:
    """``values`` values of (batch, 10,000) computed from the observation and all kept alive
    until they are summed, by one ``Sum`` or by a chain of ``Add``: 1.6 MB an observation."""
    rng = np.random.default_rng(0)
    weights = [
        numpy_helper.from_array(rng.normal(size=(width, 10_000)).astype(np.float32), "wide"),
        numpy_helper.from_array(rng.normal(size=(10_000, actions)).astype(np.float32), "narrow"),
    ]
    nodes = [helper.make_node("MatMul", ["observation", "wide"], ["spread"])]
    for k in range(values):
        weights.append(numpy_helper.from_array(np.array([k], np.float32), f"shift{k}"))
        nodes.append(helper.make_node("Add", ["spread", f"shift{k}"], [f"value{k}"]))
    if summed_by == "Sum":
        nodes.append(helper.make_node("Sum", [f"value{k}" for k in range(values)], ["total"]))
    else:
        last = "value0"
        for k in range(1, values):
            name = "total" if k == values - 1 else f"partial{k}"
            nodes.append(helper.make_node("Add", [last, f"value{k}"], [name]))
            last = name
    nodes.append(helper.make_node("MatMul", ["total", "narrow"], ["logits"]))
    return _model(nodes, weights, [observation(width)], logits(actions))


def dense_stack(width: int, actions: int, *, units: int, layers: int) -> bytes:
    """``layers`` dense layers of ``units`` x ``units`` (tanh), their weights made in the graph
    as outer products (a few kilobytes sent, ``units`` squared multiply-adds an observation a
    layer): heavy within the allowed operators."""
    weights = [
        numpy_helper.from_array(np.full((units, 1), 1.0 / units, np.float32), "left"),
        numpy_helper.from_array(np.ones((1, units), np.float32), "right"),
        numpy_helper.from_array(np.ones((width, 1), np.float32), "inputs"),
        numpy_helper.from_array(np.ones((1, actions), np.float32), "outputs"),
    ]
    nodes = [
        helper.make_node("MatMul", ["left", "right"], ["square"]),
        helper.make_node("MatMul", ["inputs", "right"], ["into"]),
        helper.make_node("MatMul", ["left", "outputs"], ["out"]),
        helper.make_node("MatMul", ["observation", "into"], ["h0"]),
    ]
    for k in range(layers):
        nodes += [
            helper.make_node("MatMul", [f"h{k}", "square"], [f"z{k}"], name=f"layer{k}"),
            helper.make_node("Tanh", [f"z{k}"], [f"h{k + 1}"]),
        ]
    nodes.append(helper.make_node("MatMul", [f"h{layers}", "out"], ["logits"]))
    return _model(nodes, weights, [observation(width)], logits(actions))


def concatenated(width: int, actions: int, *, copies: int = 700) -> bytes:
    """A hundred features of each observation joined ``copies`` times over: 280 kB an
    observation in one value from a model of a few kilobytes."""
    weights = [
        numpy_helper.from_array(np.ones((width, 100), np.float32), "spread"),
        numpy_helper.from_array(np.ones((1, actions), np.float32), "out"),
        numpy_helper.from_array(np.array([1], np.int64), "axis"),
    ]
    nodes = [
        helper.make_node("MatMul", ["observation", "spread"], ["features"]),
        helper.make_node("Concat", ["features"] * copies, ["joined"], axis=1, name="join"),
        helper.make_node("ReduceMean", ["joined"], ["mean"], axes=[1], keepdims=1),
        helper.make_node("MatMul", ["mean", "out"], ["logits"]),
    ]
    return _model(nodes, weights, [observation(width)], logits(actions))


def far_actions(width: int, *, action: float = 3297.0) -> bytes:
    """Actions computed as numbers and cast to integers: ``action`` for a zero observation,
    ``-action`` + 1 for one of ones (all the columns' sum times -2 action)."""
    weights = [
        numpy_helper.from_array(np.full((width, 1), (1 - 2 * action) / width, np.float32), "w"),
        numpy_helper.from_array(np.array([action], np.float32), "b"),
    ]
    nodes = [
        helper.make_node("Gemm", ["observation", "w", "b"], ["score"]),
        helper.make_node("Cast", ["score"], ["action"], to=TensorProto.INT64),
    ]
    out = helper.make_tensor_value_info("action", TensorProto.INT64, ["batch", 1])
    return _model(nodes, weights, [observation(width)], out)


def counting_past(width: int) -> bytes:
    """A recurrent model whose action is the count of its decisions (its memory): 1 at the
    first, the trial run's; one past the last action once it has decided as many times as
    there are actions."""
    weights = [
        numpy_helper.from_array(np.array([[1.0]], dtype=np.float32), "one"),
        numpy_helper.from_array(np.zeros((width, 1), dtype=np.float32), "ignore"),
    ]
    nodes = [
        helper.make_node("MatMul", ["observation", "ignore"], ["nothing"]),
        helper.make_node("Add", ["memory_in", "one"], ["counted"]),
        helper.make_node("Add", ["counted", "nothing"], ["memory_out"]),
        helper.make_node("Cast", ["memory_out"], ["action"], to=TensorProto.INT64),
    ]
    memory_in = helper.make_tensor_value_info("memory_in", TensorProto.FLOAT, ["batch", 1])
    memory_out = helper.make_tensor_value_info("memory_out", TensorProto.FLOAT, ["batch", 1])
    out = helper.make_tensor_value_info("action", TensorProto.INT64, ["batch", 1])
    graph = helper.make_graph(
        nodes, "counting", [observation(width), memory_in], [out, memory_out], initializer=weights
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", OPSET)])
    model.ir_version = 8
    return bytes(model.SerializeToString())


def looping(width: int, actions: int) -> bytes:
    """A Loop whose count comes from the observation: a graph whose running time the graph
    does not bound."""
    body = helper.make_graph(
        [helper.make_node("Identity", ["cond_in"], ["cond_out"])], "body",
        [helper.make_tensor_value_info("i", TensorProto.INT64, []),
         helper.make_tensor_value_info("cond_in", TensorProto.BOOL, [])],
        [helper.make_tensor_value_info("cond_out", TensorProto.BOOL, [])],
    )  # fmt: skip
    weights = [_int64("many", 10**12), numpy_helper.from_array(np.array(True), "go"),
               numpy_helper.from_array(np.zeros((width, actions), np.float32), "w")]  # fmt: skip
    nodes = [
        helper.make_node("Loop", ["many", "go"], [], body=body),
        helper.make_node("MatMul", ["observation", "w"], ["logits"]),
    ]
    return _model(nodes, weights, [observation(width)], logits(actions))


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


def _external(tensor: onnx.TensorProto, location: str, length: int = 8) -> None:
    """Make ``tensor`` keep its data at ``location`` (a path relative to where the model is
    run), ``length`` bytes from its start."""
    tensor.ClearField("raw_data")
    tensor.ClearField("int64_data")
    tensor.data_location = TensorProto.EXTERNAL
    for key, value in (("location", location), ("offset", "0"), ("length", str(length))):
        entry = tensor.external_data.add()
        entry.key, entry.value = key, value


def file_reader(width: int, actions: int, location: str, *, form: str = "sparse") -> bytes:
    """The audit's model that read a file beside the API: a Gemm on the observation, ArgMax,
    then a Gather from a constant whose 8 bytes are the file's first (``location``, relative),
    answered as the action, so that a refusal quoting the action would quote the file.
    ``form``: ``sparse`` (a Constant's ``sparse_value``, its values external), ``dense`` (a
    Constant's ``value``), ``sparse_list`` (an attribute's ``sparse_tensors``), ``nested``
    (the sparse Constant inside an If's branch), ``initializer`` (a sparse initializer)."""
    values = numpy_helper.from_array(np.zeros(1, dtype=np.int64), "secret_values")
    _external(values, location)
    indices = numpy_helper.from_array(np.array([1], dtype=np.int64), "secret_indices")
    sparse = helper.make_sparse_tensor(values, indices, [2])
    # the second column wins for any observation with a positive sum (a trial row of ones)
    choose = np.zeros((width, 2), dtype=np.float32)
    choose[:, 1] = 1.0
    weights = [numpy_helper.from_array(choose, "w")]
    scores = helper.make_node("Gemm", ["observation", "w"], ["scores"])
    argmax = helper.make_node("ArgMax", ["scores"], ["which"], axis=1, keepdims=0)
    gather = helper.make_node("Gather", ["secret", "which"], ["action"], axis=0)
    if form == "dense":
        dense = numpy_helper.from_array(np.zeros(2, dtype=np.int64), "secret_dense")
        _external(dense, location, 16)
        made = [helper.make_node("Constant", [], ["secret"], name="reader", value=dense)]
    elif form == "sparse_list":
        attribute = helper.make_attribute("sparse_tensors", [sparse])
        node = helper.make_node("Constant", [], ["secret"], name="reader", sparse_value=sparse)
        node.attribute.append(attribute)
        made = [node]
    elif form == "nested":
        inner = helper.make_node("Constant", [], ["inside"], name="reader", sparse_value=sparse)
        branch = helper.make_graph(
            [inner], "branch", [],
            [helper.make_tensor_value_info("inside", TensorProto.INT64, [2])],
        )  # fmt: skip
        condition = numpy_helper.from_array(np.array(True), "condition")
        weights.append(condition)
        made = [helper.make_node("If", ["condition"], ["secret"], name="choose",
                                 then_branch=branch, else_branch=branch)]  # fmt: skip
    elif form == "initializer":
        graph_inputs = [observation(width)]
        out = helper.make_tensor_value_info("action", TensorProto.INT64, ["batch"])
        values.name = "secret"
        graph = helper.make_graph([scores, argmax, gather], "policy", graph_inputs, [out],
                                  initializer=weights, sparse_initializer=[sparse])  # fmt: skip
        sparse.values.name = "secret"
        model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", OPSET)])
        model.ir_version = 8
        return bytes(model.SerializeToString())
    else:
        made = [helper.make_node("Constant", [], ["secret"], name="reader", sparse_value=sparse)]
    out = helper.make_tensor_value_info("action", TensorProto.INT64, ["batch"])
    return _model([*made, scores, argmax, gather], weights, [observation(width)], out)


def shape_liar(width: int, actions: int, *, wide: int = 64, declared: bool = True) -> bytes:
    """The audit's model that lied about its cost: the features' largest values over the batch,
    (``wide``,), reshaped to a shape taken from the observation (``[1, -1]`` when no
    observation is positive, as the trial's zero rows; ``[-1, 1]`` else) and declared ``(1,
    wide)`` in ``value_info``; added to their ``(1, wide)`` self they make ``wide`` squared
    numbers at run time where the declared shapes count ``wide``."""
    pick = np.zeros((width, 2), dtype=np.float32)
    pick[:, 1] = 1.0
    weights = [
        numpy_helper.from_array(np.ones((width, wide), dtype=np.float32), "wide"),
        numpy_helper.from_array(pick, "pick"),
        numpy_helper.from_array(np.zeros((width, actions), dtype=np.float32), "w"),
        numpy_helper.from_array(np.array([[1, -1], [-1, 1]], dtype=np.int64), "table"),
        numpy_helper.from_array(np.array([1, -1], dtype=np.int64), "as_row"),
    ]
    nodes = [
        helper.make_node("MatMul", ["observation", "wide"], ["features"]),
        helper.make_node("ReduceMax", ["features"], ["largest"], keepdims=0, axes=[0]),
        helper.make_node("MatMul", ["observation", "pick"], ["votes"]),
        helper.make_node("ReduceMax", ["votes"], ["total"], keepdims=0, axes=[0]),
        helper.make_node("ArgMax", ["total"], ["which"], axis=0, keepdims=0),
        helper.make_node("Gather", ["table", "which"], ["shape"], axis=0),
        helper.make_node("Reshape", ["largest", "as_row"], ["row"]),
        helper.make_node("Reshape", ["largest", "shape"], ["column"], name="lying"),
        helper.make_node("Add", ["row", "column"], ["square"]),
        helper.make_node("ReduceMax", ["square"], ["top"], keepdims=0, axes=[0, 1]),
        helper.make_node("Gemm", ["observation", "w"], ["plain"]),
        helper.make_node("Add", ["plain", "top"], ["logits"]),
    ]
    graph = helper.make_graph(nodes, "policy", [observation(width)], [logits(actions)],
                              initializer=weights)  # fmt: skip
    if declared:
        graph.value_info.extend(
            helper.make_tensor_value_info(name, TensorProto.FLOAT, [1, wide])
            for name in ("column", "square")
        )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    return bytes(model.SerializeToString())


def empty_nodes(width: int, actions: int, count: int) -> bytes:
    """An MLP followed by ``count`` empty nodes, written straight into its bytes (two bytes
    a node: 690,000 of them take 1.38 MB and cost ONNX 100 MB to parse)."""
    model = onnx.load_model_from_string(always(width, actions, 0))
    graph = bytearray(model.graph.SerializeToString())
    graph += b"\x0a\x00" * count  # GraphProto.node (field 1, length-delimited), empty
    model.ClearField("graph")
    return bytes(model.SerializeToString()) + b"\x3a" + _varint(len(graph)) + bytes(graph)


def _varint(value: int) -> bytes:
    out = bytearray()
    while True:
        low, value = value & 0x7F, value >> 7
        out.append(low | (0x80 if value else 0))
        if not value:
            return bytes(out)


def split_into(width: int, actions: int, outputs: int) -> bytes:
    """An MLP whose logits are also split into ``outputs`` pieces no one reads: the audit's
    15 s check was a Split into 50,000."""
    weights = [
        numpy_helper.from_array(np.zeros((width, actions), dtype=np.float32), "w"),
        numpy_helper.from_array(np.zeros(outputs, dtype=np.float32), "long"),
        numpy_helper.from_array(np.ones(outputs, dtype=np.int64), "sizes"),
    ]
    pieces = [f"piece{k}" for k in range(outputs)]
    nodes = [
        helper.make_node("Gemm", ["observation", "w"], ["logits"]),
        helper.make_node("Split", ["long", "sizes"], pieces, name="splitter", axis=0),
    ]
    return _model(nodes, weights, [observation(width)], logits(actions))
