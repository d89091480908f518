"""A network's graph read before it runs: only allowed operators, arithmetic on float32 only,
and a cost counted from its shapes (multiply-adds and the memory live at once, per
observation), refused past the caps with the count and the cap, naming the node."""

from __future__ import annotations

import numpy as np
import onnx
import pytest
from onnx import TensorProto, helper, numpy_helper

from nanonav.rl import graph, operators
from nanonav.rl.graph import MAX_LIVE_BYTES, MAX_MULTIPLY_ADDS, InvalidModel, inspect_model
from tests.rl import models

NODE = r"node '[^']+' \((\w+)\): "


def inspected(data: bytes, width: int = 7, actions: int = 4) -> graph.ModelInfo:
    return inspect_model(onnx.load_model_from_string(data), width, actions)


@pytest.mark.parametrize(
    ("data", "operator", "reason"),
    [
        (models.integer_division(7), "Mod", "Mod is not an operator a policy needs"),
        (models.integer_division(7, only_when_positive=True), "Mod", "Mod is not an operator"),
        (models.convolutions(7, 4), "Expand", "Expand is not an operator a policy needs"),
        (models.kept_alive(7, 4), "Sum", "Sum is not an operator a policy needs"),
        (models.looping(7, 4), "Loop", "Loop is not an operator a policy needs"),
        (models.beyond_once_sensing(7, 4), "Greater", "Greater is not an operator"),
    ],
)  # fmt: skip
def test_an_operator_off_the_list_is_refused_naming_its_node(
    data: bytes, operator: str, reason: str
) -> None:
    with pytest.raises(InvalidModel, match=NODE + reason) as refused:
        inspected(data)
    assert f"({operator})" in str(refused.value)


def test_arithmetic_on_integers_is_refused_though_its_operators_are_allowed() -> None:
    """Add, Sub, Mul and Div compute on float32 only: a Div of int64 is what raised SIGFPE."""
    weights = [numpy_helper.from_array(np.array([3], np.int64), "three"),
               numpy_helper.from_array(np.zeros((7, 4), np.float32), "w")]  # fmt: skip
    nodes = [
        helper.make_node("Cast", ["observation"], ["whole"], to=TensorProto.INT64),
        helper.make_node("Div", ["whole", "three"], ["third"], name="divide"),
        helper.make_node("MatMul", ["observation", "w"], ["logits"]),
    ]
    g = helper.make_graph(nodes, "p", [models.observation(7)], [models.logits(4)], weights)
    model = helper.make_model(g, opset_imports=[helper.make_opsetid("", models.OPSET)])
    with pytest.raises(InvalidModel) as refused:
        inspect_model(model, 7, 4)
    assert str(refused.value) == (
        "node 'divide' (Div): its input 0 is INT64: Div computes on float32 only (arithmetic "
        "on integers is not run)"
    )


def test_every_allowed_operator_exists_in_onnx_and_says_why_it_is_allowed() -> None:
    for name, operator in operators.ALLOWED.items():
        assert onnx.defs.has(name), name
        assert len(operator.why) > 10, name
    assert operators.refusal("Conv", "", []) is not None
    assert operators.refusal("Gemm", "com.microsoft", []) is not None


def test_an_mlp_costs_its_layers_products_and_biases() -> None:
    """observation (7) -> Gemm 16 -> Relu -> Gemm 4: 16 x (7 + 1) + 16 + 4 x (16 + 1)
    multiply-adds; at most the hidden layer and its activation live at once (2 x 16 floats)."""
    cost = inspected(models.mlp(7, 4, hidden=16)).cost
    assert cost.multiply_adds == 16 * (7 + 1) + 16 + 4 * (16 + 1)
    assert cost.live_bytes == 2 * 16 * 4
    assert cost.weight_bytes == 4 * (7 * 16 + 16 + 16 * 4 + 4)
    assert cost.rows_per_call == graph.CALL_ROWS


def test_a_recurrent_cell_costs_its_gates_at_every_step() -> None:
    """An LSTM of H = 32 over one step of 7 inputs: 4H x (7 + H) products, 4H gate
    activations (tanh and sigmoids, at TRANSCENDENTAL each) and 4H of the cell's update."""
    hidden, width = 32, 7
    rng = np.random.default_rng(0)
    weights = [
        numpy_helper.from_array(rng.normal(size=(1, 4 * hidden, width)).astype(np.float32), "W"),
        numpy_helper.from_array(rng.normal(size=(1, 4 * hidden, hidden)).astype(np.float32), "R"),
        numpy_helper.from_array(np.array([0], np.int64), "axis"),
        numpy_helper.from_array(np.ones((hidden, 4), np.float32), "out"),
    ]  # fmt: skip
    nodes = [
        helper.make_node("Unsqueeze", ["observation", "axis"], ["sequence"]),
        helper.make_node("LSTM", ["sequence", "W", "R"], ["", "last"], hidden_size=hidden),
        helper.make_node("Squeeze", ["last", "axis"], ["state"]),
        helper.make_node("MatMul", ["state", "out"], ["logits"]),
    ]
    g = helper.make_graph(nodes, "p", [models.observation(width)], [models.logits(4)], weights)
    model = helper.make_model(g, opset_imports=[helper.make_opsetid("", models.OPSET)])
    cost = inspect_model(model, width, 4).cost
    cell = 4 * hidden * (width + hidden) + operators.TRANSCENDENTAL * 4 * hidden + 4 * hidden
    assert cost.multiply_adds == cell + 4 * hidden


def test_a_model_past_a_cap_is_refused_with_the_count_and_the_cap() -> None:
    with pytest.raises(InvalidModel) as heavy:
        inspected(models.dense_stack(7, 4, units=1100, layers=4))
    assert str(heavy.value) == (
        f"node 'layer3' (MatMul): the model takes 4,874,100, over the cap of "
        f"{MAX_MULTIPLY_ADDS:,}, multiply-adds an observation by here (the cap on a policy's "
        "cost)"
    )
    with pytest.raises(InvalidModel, match=NODE + r"the model holds 280,000, over the cap of "
                       f"{MAX_LIVE_BYTES:,}, bytes an observation at once here"):  # fmt: skip
        inspected(models.kept_alive(7, 4, summed_by="Add"))
    with pytest.raises(InvalidModel, match=r"^node 'join' \(Concat\): the model holds 280,400, "
                       "over the cap"):  # fmt: skip
        inspected(models.concatenated(7, 4))
    within = inspected(models.dense_stack(7, 4, units=1000, layers=3)).cost
    assert within.multiply_adds < MAX_MULTIPLY_ADDS
    # the weights, made once a call: the square, and the layers into and out of it
    assert within.fixed_multiply_adds == 1000 * 1000 + 7 * 1000 + 1000 * 4
    assert within.fixed_bytes == 4 * (1000 * 1000 + 7 * 1000 + 1000 * 4)
    # a call takes as many rows as keep it within a gigabyte of multiply-adds
    assert within.rows_per_call == graph.CALL_MULTIPLY_ADDS // within.multiply_adds


def test_a_value_whose_size_the_graph_does_not_fix_is_refused_naming_its_node() -> None:
    """A shape read from the observation's own numbers: no size before it runs."""
    weights = [numpy_helper.from_array(np.array(0, np.int64), "first")]
    nodes = [
        helper.make_node("Cast", ["observation"], ["whole"], to=TensorProto.INT64),
        helper.make_node("Gather", ["whole", "first"], ["shape"]),
        helper.make_node("Reshape", ["observation", "shape"], ["reshaped"], name="reshape"),
        helper.make_node("Identity", ["observation"], ["logits"]),
    ]
    g = helper.make_graph(nodes, "p", [models.observation(4)], [models.logits(4)], weights)
    model = helper.make_model(g, opset_imports=[helper.make_opsetid("", models.OPSET)])
    with pytest.raises(InvalidModel, match=r"^node 'reshape' \(Reshape\): it gives 'reshaped', "
                       "whose size the graph does not fix"):  # fmt: skip
        inspect_model(model, 4, 4)


def test_a_value_that_grows_with_the_batch_squared_is_refused() -> None:
    """Every observation against every other: (batch, batch) numbers."""
    nodes = [
        helper.make_node("Transpose", ["observation"], ["columns"]),
        helper.make_node("MatMul", ["observation", "columns"], ["pairs"], name="pairs"),
        helper.make_node("Identity", ["observation"], ["logits"]),
    ]
    g = helper.make_graph(nodes, "p", [models.observation(4)], [models.logits(4)])
    model = helper.make_model(g, opset_imports=[helper.make_opsetid("", models.OPSET)])
    grows = r"^node 'pairs' \(MatMul\): its output 'pairs' grows with the batch otherwise than"
    with pytest.raises(InvalidModel, match=grows + r" in proportion to it \(1, 4, 9 "):
        inspect_model(model, 4, 4)


@pytest.mark.parametrize(
    ("form", "where"),
    [
        ("sparse", r"^node 'reader' \(Constant\): its tensor 'secret_values'"),
        ("dense", r"^node 'reader' \(Constant\): its tensor 'secret_dense'"),
        ("sparse_list", r"^node 'reader' \(Constant\): its tensor 'secret_values'"),
        ("nested", r"^node 'reader' \(Constant\) in node 'choose' \(If\): its tensor"),
        ("initializer", r"^the model's sparse_initializer: its tensor 'secret_values'"),
    ],
)
def test_data_kept_outside_the_model_is_refused_wherever_it_hides(form: str, where: str) -> None:
    """The audit read a file beside the API through a Constant's sparse value; any tensor
    anywhere in the proto that names data outside the model is refused, naming its node."""
    data = models.file_reader(7, 4, "var/nanonav.db", form=form)
    with pytest.raises(InvalidModel, match=where + ".* keeps its data outside the model"):
        inspected(data)


def test_the_walk_finds_external_data_in_a_field_it_was_not_told_of() -> None:
    """The walk reads every field of every message, so a tensor in a place named by no rule
    (here the model's training_info, which ONNX Runtime ignores) is found all the same."""
    model = onnx.load_model_from_string(models.mlp(7, 4))
    hidden = onnx.TensorProto(name="elsewhere", data_type=TensorProto.INT64, dims=[1])
    hidden.data_location = TensorProto.EXTERNAL
    info = model.training_info.add()
    info.initialization.initializer.append(hidden)
    with pytest.raises(InvalidModel, match="the model's training_info: its tensor 'elsewhere'"):
        inspect_model(model, 7, 4)


def test_nodes_are_counted_from_the_bytes_before_the_model_is_parsed() -> None:
    """690,000 empty nodes (1.38 MB) cost ONNX 100 MB to parse: they are counted unparsed, and
    refused at the cap's first node past it, in a small part of a parse's time."""
    data = models.empty_nodes(7, 4, 690_000)
    assert len(data) > 1_380_000
    with pytest.raises(InvalidModel, match=r"has over 5,000 nodes \(its subgraphs' counted\)"):
        graph.parsed(data, 2_000_000)
    at_the_cap = models.empty_nodes(7, 4, graph.MAX_NODES - 1)  # and the MLP's one
    assert len(graph.parsed(at_the_cap, 2_000_000).graph.node) == graph.MAX_NODES


def test_the_wire_format_field_numbers_are_onnxs() -> None:
    """The unparsed count reads fields by number: they are those of ONNX's own proto."""
    numbers = [
        onnx.ModelProto.DESCRIPTOR.fields_by_name["graph"].number,
        onnx.GraphProto.DESCRIPTOR.fields_by_name["node"].number,
        onnx.NodeProto.DESCRIPTOR.fields_by_name["attribute"].number,
        onnx.AttributeProto.DESCRIPTOR.fields_by_name["g"].number,
        onnx.AttributeProto.DESCRIPTOR.fields_by_name["graphs"].number,
    ]
    assert numbers == [graph.MODEL_GRAPH, graph.GRAPH_NODE, graph.NODE_ATTRIBUTE,
                       graph.ATTRIBUTE_GRAPH, graph.ATTRIBUTE_GRAPHS]  # fmt: skip


@pytest.mark.parametrize("data", [b"\xff" * 40, b"\x3a\xff\xff\xff\xff\x0f", b"\x3a\x05ab"])
def test_bytes_that_are_no_protobuf_are_refused_by_the_count(data: bytes) -> None:
    with pytest.raises(InvalidModel, match="this is not an ONNX model"):
        graph.parsed(data, 2_000_000)


def test_a_node_with_thousands_of_outputs_is_refused_before_its_shapes_are_inferred() -> None:
    """The audit's Split into 50,000 outputs took 15 s to check and was accepted."""
    with pytest.raises(InvalidModel, match=r"^node 'splitter' \(Split\): it gives 50,000 "
                       r"outputs, over the 64 a node may"):  # fmt: skip
        inspected(models.split_into(7, 4, 50_000))
    inspected(models.split_into(7, 4, 64))


def test_a_graph_naming_too_many_values_is_refused_at_the_node_past_the_cap() -> None:
    nodes = [helper.make_node("Gemm", ["observation", "w"], ["logits"])]
    nodes += [helper.make_node("Split", ["long", "sizes"], [f"p{j}_{i}" for i in range(64)],
                               axis=0) for j in range(320)]  # fmt: skip
    weights = [
        numpy_helper.from_array(np.zeros((7, 4), dtype=np.float32), "w"),
        numpy_helper.from_array(np.zeros(64, dtype=np.float32), "long"),
        numpy_helper.from_array(np.ones(64, dtype=np.int64), "sizes"),
    ]
    g = helper.make_graph(nodes, "p", [models.observation(7)], [models.logits(4)], weights)
    model = helper.make_model(g, opset_imports=[helper.make_opsetid("", models.OPSET)])
    with pytest.raises(InvalidModel, match=r"^node '#\d+' \(Split\): the graph names over "
                       "20,000 values"):  # fmt: skip
        inspect_model(model, 7, 4)


def test_a_shape_the_model_declares_but_does_not_compute_is_not_counted() -> None:
    """The audit's lie: a Reshape to a shape read from the observation, declared (1, K) in
    value_info; shape inference kept the declaration, and the count was K where a call made
    K^2. Declared shapes are dropped before inference, so the Reshape has no size."""
    lying = r"^node 'lying' \(Reshape\): it gives 'column', whose size the graph does not fix"
    for declared in (True, False):
        with pytest.raises(InvalidModel, match=lying):
            inspected(models.shape_liar(7, 4, declared=declared))


def test_a_wrong_declared_output_shape_does_not_change_what_is_inferred() -> None:
    """An output declared (batch, 9) where the graph computes (batch, 4) is what it computes."""
    model = onnx.load_model_from_string(models.mlp(7, 4))
    model.graph.output[0].type.tensor_type.shape.dim[1].dim_value = 9
    assert inspect_model(model, 7, 4).output == "logits"
