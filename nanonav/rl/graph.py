"""What a network sent as a policy is, read from its graph alone, without running it: whether it
may run at all, what it reads and gives, and what one observation costs.

ONNX is data (a protobuf graph of standard operators and its weights): nothing here loads a
pickle or TorchScript. A model is read when it is small enough, keeps its weights inside itself
(external data could name any file of the machine that runs it), uses only operators of the
allow-list (``nanonav.rl.operators``) at an opset ONNX Runtime runs, takes one float32 input of
a batch of observations, ``(batch, width)``, and gives either the action logits, ``(batch,
actions)`` floats (the action is their argmax), or the actions themselves, ``(batch,)`` or
``(batch, 1)`` integers; a network that steers continuously gives the turn itself, ``(batch,
2)`` floats. A recurrent one also reads its memory and gives it back.

Every value the graph computes must have a size the graph fixes, but for the batch axis, so
that its cost is counted before it runs (``Cost``): the multiply-adds and the largest memory
live at once, per observation and per call. A model over the caps is refused, with the count
and the cap.

This module runs where the model is checked, in the sandbox's process
(``nanonav.rl.sandbox``): it imports nothing of NanoNav's but the allow-list.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from functools import cache
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import NDArray

from nanonav.rl import operators

if TYPE_CHECKING:
    import onnx

# The default domain's versions accepted: from the first with today's operator semantics that
# exporters still write, to the newest this ONNX knows (ONNX Runtime refuses one it cannot run)
MIN_OPSET = 9
RULE = "policy_model"
# The model's metadata keys under which a model names what it reads and chooses (JSON lists of
# an environment's observation_labels and action_labels): nanonav train writes them
METADATA_OBSERVATION = "nanonav.observation"
METADATA_ACTIONS = "nanonav.actions"
# The caps on what one observation may cost. The largest policy our exporters write, sb3-
# contrib's RecurrentPPO (an LSTM of 256 and two layers of 64), takes about 290,000 multiply-
# adds and 7 kB live an observation; an MLP of two layers of 1,000 about 1,000,000 and 8 kB.
# The caps leave a policy room to grow: four million multiply-adds, a quarter of a megabyte.
MAX_MULTIPLY_ADDS = 4_000_000
MAX_LIVE_BYTES = 262_144
# What the values without a batch axis (computed once a call, whatever its rows) may cost
MAX_FIXED_MULTIPLY_ADDS = 10_000_000
MAX_FIXED_BYTES = 64 * 1024 * 1024
# Nodes a model may have, its subgraphs' counted too: shape inference and counting take time
# in proportion; they are counted from the model's bytes before it is parsed
MAX_NODES = 5_000
# Outputs one node may give (an LSTM gives 3, a Split a few), and values a graph may name in
# all (the inputs, weights and outputs of its nodes): what its check's time grows with
MAX_NODE_OUTPUTS = 64
MAX_VALUES = 20_000
# The axes a value may have (a policy's have two or three: batch, features, a sequence)
MAX_RANK = 8
# Field numbers of ONNX's protobuf (onnx.proto: ModelProto.graph, GraphProto.node,
# NodeProto.attribute, AttributeProto.g and .graphs), by which nodes are counted unparsed
MODEL_GRAPH, GRAPH_NODE, NODE_ATTRIBUTE, ATTRIBUTE_GRAPH, ATTRIBUTE_GRAPHS = 7, 1, 5, 6, 11
# What one inference call may cost: its rows are as many as fit both (and ``CALL_ROWS``), so
# that a call takes well under a second and a quarter of a gigabyte whatever the model
CALL_MULTIPLY_ADDS = 2**30
CALL_BYTES = 256 * 1024 * 1024
CALL_ROWS = 8192

Output = Literal["logits", "actions", "turn"]


class InvalidModel(ValueError):
    """A model that cannot decide for the scenario's robots; the message says why."""


@dataclass(frozen=True)
class Memory:
    """A recurrent model's memory: an input it reads, the output that gives it back for the
    next decision, their shape (a number per fixed axis, the batch axis's name) and which axis
    is the batch's."""

    input_name: str
    output_name: str
    dims: tuple[int | str, ...]
    batch_axis: int

    def zeros(self, rows: int) -> NDArray[np.float32]:
        """The memory of ``rows`` robots at an episode's start."""
        shape = [rows if axis == self.batch_axis else int(d) for axis, d in enumerate(self.dims)]
        return np.zeros(shape, dtype=np.float32)


@dataclass(frozen=True)
class Cost:
    """What running a model costs, counted from its graph: ``multiply_adds`` and
    ``live_bytes`` (the most memory its values hold at once) for each observation, and the
    same for the values computed once a call whatever its rows (``fixed_*``), and its
    weights' bytes."""

    multiply_adds: int
    live_bytes: int
    fixed_multiply_adds: int = 0
    fixed_bytes: int = 0
    weight_bytes: int = 0

    @property
    def rows_per_call(self) -> int:
        """The most observations one inference call takes: as many as keep the call within
        ``CALL_MULTIPLY_ADDS`` and ``CALL_BYTES``, at most ``CALL_ROWS``."""
        by_work = CALL_MULTIPLY_ADDS // max(self.multiply_adds, 1)
        by_memory = CALL_BYTES // max(self.live_bytes, 1)
        return max(1, min(CALL_ROWS, by_work, by_memory))

    def to_dict(self) -> dict[str, int]:
        return asdict(self)


@dataclass(frozen=True)
class ModelInfo:
    """What a checked model is: its operator set version, whether it gives logits, actions or a
    turn, the input and output it is run by, a recurrent model's memory, and its cost."""

    opset: int
    output: Output
    input_name: str
    output_name: str
    memory: tuple[Memory, ...] = ()
    cost: Cost = Cost(0, 0)

    def to_json(self) -> dict[str, Any]:
        """As JSON: what the sandbox's process answers (``of_json`` reads it back)."""
        return asdict(self)

    @classmethod
    def of_json(cls, data: dict[str, Any]) -> ModelInfo:
        memory = tuple(
            Memory(m["input_name"], m["output_name"], tuple(m["dims"]), int(m["batch_axis"]))
            for m in data["memory"]
        )
        cost = Cost(**{k: int(v) for k, v in data["cost"].items()})
        return cls(int(data["opset"]), data["output"], data["input_name"], data["output_name"],
                   memory, cost)  # fmt: skip


@cache
def max_opset() -> int:
    """The newest version of the default domain this ONNX knows (the last accepted)."""
    import onnx

    return int(onnx.defs.onnx_opset_version())


def parsed(data: bytes, max_bytes: int) -> onnx.ModelProto:
    """The model ``data`` holds; ``InvalidModel`` if it is larger than ``max_bytes`` or is no
    ONNX model."""
    if len(data) > max_bytes:
        raise InvalidModel(f"the model takes {len(data)} bytes, over the limit of {max_bytes}")
    for count in _node_counts(memoryview(data)):
        if count > MAX_NODES:
            raise InvalidModel(
                f"the model has over {MAX_NODES:,} nodes (its subgraphs' counted), the most a "
                "policy may have"
            )
    import onnx  # here, not above: what imports this module's names need not load ONNX

    try:
        model = onnx.load_model_from_string(bytes(data))
    except Exception as error:  # protobuf's DecodeError, or worse
        raise InvalidModel(f"this is not an ONNX model: {error}") from None
    if model.ir_version <= 0 or not model.graph.node:
        raise InvalidModel("this is not an ONNX model: it has no IR version or no graph")
    return model


def model_labels(data: bytes, *, max_bytes: int) -> tuple[list[str] | None, list[str] | None]:
    """The observation and action labels a model's metadata names (``METADATA_*``), each
    None where it names none; ``InvalidModel`` for a model that is not one, or labels that are
    not a JSON list of strings."""
    model = parsed(data, max_bytes)
    found: dict[str, list[str] | None] = {METADATA_OBSERVATION: None, METADATA_ACTIONS: None}
    for entry in model.metadata_props:
        if entry.key in found:
            try:
                labels = json.loads(entry.value)
            except ValueError:
                labels = None
            if not (isinstance(labels, list) and all(isinstance(x, str) for x in labels)):
                raise InvalidModel(f"the model's metadata {entry.key!r} is not a list of labels")
            found[entry.key] = labels
    return found[METADATA_OBSERVATION], found[METADATA_ACTIONS]


def _node_counts(data: memoryview) -> Iterator[int]:
    """The nodes of the model's graph and of every graph in their attributes, counted one by
    one from the protobuf's wire format without parsing it (a count of nodes costs the parse
    of none): yields 1, 2, 3, ... as each node is met, so that a caller stops at its cap."""
    counted = 0
    for graph in _fields(data, MODEL_GRAPH):
        for node_count in _graph_nodes(graph):
            counted += node_count
            yield counted


def _graph_nodes(graph: memoryview) -> Iterator[int]:
    for node in _fields(graph, GRAPH_NODE):
        yield 1
        for attribute in _fields(node, NODE_ATTRIBUTE):
            for number in (ATTRIBUTE_GRAPH, ATTRIBUTE_GRAPHS):
                for sub in _fields(attribute, number):
                    yield from _graph_nodes(sub)


def _fields(data: memoryview, wanted: int) -> Iterator[memoryview]:
    """The length-delimited fields numbered ``wanted`` of one protobuf message's bytes;
    ``InvalidModel`` for bytes that are no message."""
    at, end = 0, len(data)
    while at < end:
        key, at = _varint(data, at)
        number, wire = key >> 3, key & 7
        if wire == 0:
            _, at = _varint(data, at)
        elif wire == 1:
            at += 8
        elif wire == 5:
            at += 4
        elif wire == 2:
            length, at = _varint(data, at)
            if at + length > end:
                raise InvalidModel("this is not an ONNX model: its bytes are no protobuf message")
            if number == wanted:
                yield data[at : at + length]
            at += length
        else:
            raise InvalidModel("this is not an ONNX model: its bytes are no protobuf message")
    if at != end:
        raise InvalidModel("this is not an ONNX model: its bytes are no protobuf message")


def _varint(data: memoryview, at: int) -> tuple[int, int]:
    value = shift = 0
    while True:
        if at >= len(data) or shift > 63:
            raise InvalidModel("this is not an ONNX model: its bytes are no protobuf message")
        byte = data[at]
        at += 1
        value |= (byte & 0x7F) << shift
        shift += 7
        if byte < 0x80:
            return value, at


def _outside(message: Any, where: str) -> str | None:
    """Where in ``message``, at any depth, a tensor keeps its data outside the model (an
    ``external_data`` entry, or a ``data_location`` other than the default), said as a
    message names it; None where none does. Every field of every message is walked, whatever
    its name, so that a place ONNX adds for a tensor later is walked too."""
    for field, value in message.ListFields():
        if field.name == "external_data" or (field.name == "data_location" and value != 0):
            return where
        if field.type != field.TYPE_MESSAGE:
            continue
        if hasattr(value, "ListFields"):
            items = [value]
        elif field.message_type.GetOptions().map_entry:
            items = list(value.values())
        else:
            items = list(value)
        for k, item in enumerate(items):
            inner = _place(item, field.name, k, where)
            found = _outside(item, inner)
            if found is not None:
                return found
    return None


def _place(item: Any, field: str, k: int, where: str) -> str:
    """How a message names ``item``, met in ``field`` (at its ``k``-th place) inside
    ``where``: a node by its name and operator, a tensor by its name."""
    descriptor = item.DESCRIPTOR.name
    if descriptor == "NodeProto":
        return _node_name(item, k) + (f" in {where}" if where else "")
    if descriptor == "TensorProto":
        name = getattr(item, "name", "")
        tensor = f"its tensor {name!r}" if name else f"a tensor of its {field}"
        return f"{where}: {tensor}" if where else f"the model's {field} {name!r}"
    if where or descriptor == "GraphProto":
        return where
    return f"the model's {field}"


def _dims(value: onnx.ValueInfoProto) -> list[int | str | None]:
    """A value's shape: a number per fixed axis, a name per named one, None per unknown one."""
    shape = value.type.tensor_type.shape
    out: list[int | str | None] = []
    for dim in shape.dim:
        if dim.HasField("dim_value"):
            out.append(int(dim.dim_value))
        elif dim.HasField("dim_param"):
            out.append(dim.dim_param)
        else:
            out.append(None)
    return out


def _node_name(node: onnx.NodeProto, index: int) -> str:
    """How a message names a node: its name, else its place, and its operator."""
    name = node.name or f"#{index}"
    return f"node {name!r} ({node.op_type})"


def _check_contents(model: onnx.ModelProto) -> int:
    """Refuse external data, other operator sets, model-local functions and sparse weights;
    returns the default domain's opset."""
    import onnx

    outside = _outside(model, "")
    if outside is not None:
        raise InvalidModel(
            f"{outside} keeps its data outside the model (external data could name any file "
            "of the machine that runs it): save the model with its weights inside it "
            "(onnx.save(model, path), without save_as_external_data)"
        )
    if model.functions:
        raise InvalidModel("the model defines functions of its own: only standard operators")
    if model.graph.sparse_initializer:
        raise InvalidModel("the model keeps sparse weights: save them dense")
    opset = None
    for entry in model.opset_import:
        if entry.domain not in ("", "ai.onnx"):
            raise InvalidModel(
                f"the model imports the operator set {entry.domain!r}: only ONNX's own is run"
            )
        opset = int(entry.version)
    if opset is None:
        raise InvalidModel("the model imports no version of ONNX's operator set")
    if not MIN_OPSET <= opset <= max_opset():
        raise InvalidModel(
            f"the model's opset is {opset}: it must lie between {MIN_OPSET} and {max_opset()}"
        )
    named = len(model.graph.input) + len(model.graph.initializer)
    for index, node in enumerate(model.graph.node):
        problem = operators.refusal(node.op_type, node.domain, [])
        if problem is None and len(node.output) > MAX_NODE_OUTPUTS:
            outputs = len(node.output)
            problem = f"it gives {outputs:,} outputs, over the {MAX_NODE_OUTPUTS} a node may"
        if problem is not None:
            raise InvalidModel(f"{_node_name(node, index)}: {problem}")
        named += len(node.input) + len(node.output)
        if named > MAX_VALUES:
            raise InvalidModel(
                f"{_node_name(node, index)}: the graph names over {MAX_VALUES:,} values (its "
                "nodes' inputs and outputs) by here, the most a policy's may"
            )
    try:
        onnx.checker.check_model(model)
    except onnx.checker.ValidationError as error:
        raise InvalidModel(f"the model is not valid ONNX: {_first_line(error)}") from None
    return opset


def _first_line(error: BaseException) -> str:
    text = str(error).strip()
    return text.splitlines()[0] if text else type(error).__name__


# The batch sizes the graph's shapes are inferred at: what a value holds must grow in
# proportion to the batch (its numbers per observation, and those it holds besides)
BATCHES = (1, 2, 3)


@dataclass(frozen=True)
class _Value:
    """A value of the graph: its element type and its shape at each of ``BATCHES``."""

    elem_type: int
    shapes: tuple[tuple[int, ...], ...]

    @property
    def row_elements(self) -> int:
        """Its numbers for each observation."""
        return math.prod(self.shapes[1]) - math.prod(self.shapes[0])

    @property
    def per_row(self) -> bool:
        return self.row_elements > 0

    @property
    def itemsize(self) -> int:
        return 8 if self.elem_type == operators.INT64 else 4

    @property
    def row_bytes(self) -> int:
        return self.row_elements * self.itemsize

    @property
    def fixed_bytes(self) -> int:
        """Its bytes whatever the batch."""
        return (math.prod(self.shapes[0]) - self.row_elements) * self.itemsize


def _at_batch(model: onnx.ModelProto, batch: str, size: int) -> onnx.ModelProto:
    """``model`` with its inputs' batch axis ``size`` long, and without the shapes it declares
    of anything else (its ``value_info``, its outputs'): shape inference keeps a declared shape
    where it cannot infer one, and a model may declare what it does not compute (a Reshape to
    a shape computed from the observation, declared small, is large at run time). So every
    shape counted is inferred from the inputs and weights alone, and a value whose shape they
    do not fix is refused."""
    fixed = type(model)()
    fixed.CopyFrom(model)
    fixed.graph.ClearField("value_info")
    for output in fixed.graph.output:
        output.type.tensor_type.ClearField("shape")
    for value in fixed.graph.input:
        for dim in value.type.tensor_type.shape.dim:
            if dim.HasField("dim_param") and dim.dim_param == batch:
                dim.dim_value = size
    return fixed


def _values(model: onnx.ModelProto, batch: str) -> dict[str, _Value]:
    """Every value of the graph, by name, its shapes inferred at each of ``BATCHES``;
    ``InvalidModel`` naming the node that makes a value whose type or size the graph does not
    fix, or whose size does not grow in proportion to the batch."""
    import onnx

    makers = {name: _node_name(node, k) for k, node in enumerate(model.graph.node)
              for name in node.output}  # fmt: skip
    seen: dict[str, tuple[int, list[tuple[int, ...]]]] = {}
    for size in BATCHES:
        try:
            inferred = onnx.shape_inference.infer_shapes(
                _at_batch(model, batch, size), strict_mode=True, data_prop=True
            )
        except Exception as error:
            raise InvalidModel(f"the model's shapes do not check: {_first_line(error)}") from None
        graph = inferred.graph
        found: dict[str, tuple[int, tuple[int, ...] | None]] = {
            t.name: (t.data_type, tuple(int(d) for d in t.dims)) for t in graph.initializer
        }
        for value in [*graph.input, *graph.value_info, *graph.output]:
            if value.name in found:
                continue
            where = makers.get(value.name, "the graph")
            if not value.type.HasField("tensor_type"):
                raise InvalidModel(f"{where}: it gives {value.name!r}, which is not a tensor")
            dims = _dims(value) if value.type.tensor_type.HasField("shape") else [None]
            if len(dims) > MAX_RANK:
                raise InvalidModel(
                    f"{where}: it gives {value.name!r} of {len(dims)} axes, over the "
                    f"{MAX_RANK} a policy's values may have"
                )
            known = all(isinstance(d, int) for d in dims)
            found[value.name] = (
                value.type.tensor_type.elem_type,
                tuple(int(d) for d in dims) if known else None,  # type: ignore[arg-type]
            )
        for name, (kind, shape) in found.items():
            if shape is None:
                where = makers.get(name, "the graph")
                raise InvalidModel(
                    f"{where}: it gives {name!r}, whose size the graph does not fix: only the "
                    "batch axis may vary"
                )
            seen.setdefault(name, (kind, []))[1].append(shape)
    values = {}
    for name, (kind, shapes) in seen.items():
        if len(shapes) != len(BATCHES):
            raise InvalidModel(f"{makers.get(name, 'the graph')}: its output {name!r} is not "
                               "inferred at every batch size")  # fmt: skip
        value = _Value(kind, tuple(shapes))
        sizes = [math.prod(shape) for shape in shapes]
        if sizes[2] - sizes[1] != value.row_elements or value.fixed_bytes < 0:
            raise InvalidModel(
                f"{makers.get(name, 'the graph')}: its output {name!r} grows with the batch "
                f"otherwise than in proportion to it ({sizes[0]}, {sizes[1]}, {sizes[2]} "
                "numbers for 1, 2, 3 observations): a robot's decision may not depend on "
                "the others'"
            )
        values[name] = value
    return values


# long: one pass over the graph's nodes in order, every cap checked at each
def _counted(  # noqa: C901  # one pass over the nodes in order, each checked by every cap
    model: onnx.ModelProto, values: dict[str, _Value]
) -> Cost:
    """The model's cost (``Cost``), node by node in the graph's order (a topological one),
    refused with ``InvalidModel`` naming the node where a cap is passed: a node that does not
    run in a policy, or whose input types it does not take; the node that brings the multiply-
    adds over the cap; the node at which the memory live at once is over it."""
    nodes = list(model.graph.node)
    outputs = {value.name for value in model.graph.output}
    last_use: dict[str, int] = {}
    for index, node in enumerate(nodes):
        for name in node.input:
            if name:
                last_use[name] = index
    for name in outputs:
        last_use[name] = len(nodes)
    weights = {tensor.name for tensor in model.graph.initializer}
    alive: dict[str, _Value] = {
        v.name: values[v.name] for v in model.graph.input if v.name not in weights
    }
    live_rows = sum(v.row_bytes for v in alive.values())
    held_fixed = sum(v.fixed_bytes for v in alive.values())
    total = fixed = 0
    peak = fixed_peak = 0
    for index, node in enumerate(nodes):
        where = _node_name(node, index)
        given: list[_Value | None] = []
        for name in node.input:
            if not name:
                given.append(None)
            elif name in values:
                given.append(values[name])
            else:
                raise InvalidModel(f"{where}: the graph does not say what its input {name!r} is")
        made: list[_Value | None] = []
        for name in node.output:
            if name and name not in values:
                raise InvalidModel(f"{where}: the graph does not say what its output {name!r} is")
            made.append(values[name] if name else None)
        problem = operators.refusal(
            node.op_type, node.domain, [v.elem_type if v else None for v in given]
        )
        if problem is None:
            problem = _output_refusal(node, made)
        if problem is not None:
            raise InvalidModel(f"{where}: {problem}")
        one, two = (
            operators.multiply_adds(
                node.op_type,
                [v.shapes[k] if v else None for v in given],
                [v.shapes[k] if v else None for v in made],
            )
            for k in (0, 1)
        )
        total += two - one
        fixed += max(0, 2 * one - two)
        if total > MAX_MULTIPLY_ADDS:
            raise InvalidModel(
                f"{where}: the model takes {_over(total, MAX_MULTIPLY_ADDS)} multiply-adds an "
                "observation by here (the cap on a policy's cost)"
            )
        if fixed > MAX_FIXED_MULTIPLY_ADDS:
            raise InvalidModel(
                f"{where}: the model takes {_over(fixed, MAX_FIXED_MULTIPLY_ADDS)} multiply-adds "
                "a call whatever its observations by here (the cap on a policy's cost)"
            )
        for name, value in zip(node.output, made, strict=True):
            if value is not None and name not in alive:
                alive[name] = value
                live_rows += value.row_bytes
                held_fixed += value.fixed_bytes
        live = live_rows + _scratch(node, given)
        held = held_fixed
        peak, fixed_peak = max(peak, live), max(fixed_peak, held)
        if live > MAX_LIVE_BYTES:
            raise InvalidModel(
                f"{where}: the model holds {_over(live, MAX_LIVE_BYTES)} bytes an observation at "
                "once here (the cap on a policy's memory)"
            )
        if held > MAX_FIXED_BYTES:
            raise InvalidModel(
                f"{where}: the model holds {_over(held, MAX_FIXED_BYTES)} bytes whatever its "
                "observations at once here (the cap on a policy's memory)"
            )
        for name in [*node.input, *node.output]:
            if name in alive and last_use.get(name, -1) <= index:
                gone = alive.pop(name)
                live_rows -= gone.row_bytes
                held_fixed -= gone.fixed_bytes
    return Cost(total, peak, fixed, fixed_peak, sum(values[w].fixed_bytes for w in weights))


def _over(count: int, cap: int) -> str:
    return f"{count:,}, over the cap of {cap:,},"


def _scratch(node: onnx.NodeProto, given: list[_Value | None]) -> int:
    """What a node holds besides its inputs and outputs, per observation: a recurrent cell's
    gates (4, 3 or 1 of hidden numbers a direction)."""
    cost = operators.ALLOWED[node.op_type].cost
    if cost not in ("lstm", "gru", "rnn") or len(given) < 3 or given[2] is None:
        return 0
    directions, rows = given[2].shapes[0][0], given[2].shapes[0][1]
    return 4 * directions * rows


def _output_refusal(node: onnx.NodeProto, made: list[_Value | None]) -> str | None:
    """Why what a node gives is not what a policy computes: integers from an operator that
    computes (but ArgMax and Shape), a type outside float32 and the integers, a Cast to
    another type, a BatchNormalization that trains."""
    for value in made:
        if value is None:
            continue
        kind = operators.type_name(value.elem_type)
        if value.elem_type not in operators.TYPES:
            return f"it gives {kind}: values are float32, or integers"
        computes = not operators.ALLOWED[node.op_type].moves
        if (
            value.elem_type != operators.FLOAT
            and computes
            and node.op_type not in operators.GIVES_INTEGERS
        ):
            return f"it gives {kind}: it computes on float32 only"
    for attribute in node.attribute:
        training = node.op_type == "BatchNormalization" and attribute.name == "training_mode"
        if training and attribute.i:
            return "it trains (training_mode 1): export the model in eval mode"
    return None


def _memory(
    model: onnx.ModelProto, inputs: list[onnx.ValueInfoProto], batch: str
) -> tuple[Memory, ...]:
    """The memory of a recurrent model: each input after the observation, float32, with the
    batch axis once and every other axis fixed, given back by the output at its place after
    the decision (input k+1, output k+1)."""
    outputs = list(model.graph.output)
    found = []
    for k, value in enumerate(inputs, start=1):
        dims = _dims(value)
        fixed = [d for d in dims if d != batch]
        if (
            value.type.tensor_type.elem_type != operators.FLOAT
            or dims.count(batch) != 1
            or not all(isinstance(d, int) for d in fixed)
        ):
            raise InvalidModel(
                f"the model's input {value.name!r}, shape {dims}, is neither the observation "
                f"nor a memory: the first input is the observation; any other is a float32 "
                f"memory with the batch axis {batch!r} once and every other axis fixed"
            )
        if len(outputs) <= k:
            raise InvalidModel(
                f"the model reads the memory {value.name!r} but gives no output {k} of its "
                f"shape {dims} back: output k after the decision carries input k's memory"
            )
        found.append(Memory(value.name, outputs[k].name, tuple(dims), dims.index(batch)))  # type: ignore[arg-type]
    return tuple(found)


def _check_outputs(
    model: onnx.ModelProto,
    values: dict[str, _Value],
    memory: tuple[Memory, ...],
    actions: int,
    continuous: bool,
) -> Output:
    """Whether the first output is logits, actions or a turn, from its type and its shapes as
    inferred; and that each memory comes back as it went in."""
    for m in memory:
        given, back = values[m.input_name], values[m.output_name]
        if back.shapes != given.shapes or back.elem_type != given.elem_type:
            raise InvalidModel(
                f"the model reads the memory {m.input_name!r} but gives no output of its shape "
                f"{list(m.dims)} back: output k after the decision carries input k's memory "
                f"({m.output_name!r} is {list(back.shapes[1])} for 2 observations)"
            )
    first = model.graph.output[0].name
    value = values[first]
    shape = list(value.shapes[1])
    what = "a turn must be floats" if continuous else "logits must be"
    per = "part" if continuous else "action"
    if value.elem_type == operators.FLOAT:
        if any(list(s) != [b, actions] for s, b in zip(value.shapes, BATCHES, strict=True)):
            raise InvalidModel(
                f"the model's first output {first!r} is floats of shape {shape} for 2 "
                f"observations: {what} (batch, {actions}), one per {per}"
            )
        return "turn" if continuous else "logits"
    kind = operators.type_name(value.elem_type)
    if continuous:
        raise InvalidModel(f"the model's first output is {kind}: {what} (batch, {actions})")
    if any(list(s) not in ([b], [b, 1]) for s, b in zip(value.shapes, BATCHES, strict=True)):
        raise InvalidModel(
            f"the model's first output {first!r} is integers of shape {shape} for 2 "
            "observations: actions must be (batch,) or (batch, 1)"
        )
    return "actions"


def inspect_model(
    model: onnx.ModelProto, width: int, actions: int, *, continuous: bool = False
) -> ModelInfo:
    """Check that ``model`` may run as a policy deciding from ``width`` observation columns
    among ``actions`` actions, or ``continuous``ly a turn of ``actions`` parts, and count what
    it costs; ``InvalidModel`` saying what is wrong if not."""
    opset = _check_contents(model)
    weights = {tensor.name for tensor in model.graph.initializer}
    inputs = [value for value in model.graph.input if value.name not in weights]
    if not inputs:
        raise InvalidModel("the model takes no input: it must take the observation")
    given = inputs[0]
    if given.type.tensor_type.elem_type != operators.FLOAT:
        kind = operators.type_name(given.type.tensor_type.elem_type)
        raise InvalidModel(f"the model's input {given.name!r} is {kind}, not FLOAT (float32)")
    dims = _dims(given)
    if len(dims) != 2 or dims[1] != width:
        raise InvalidModel(
            f"the model's input {given.name!r} has the shape {dims}: it must be (batch, {width}),"
            f" one row of the {width} observation columns for each robot"
        )
    batch = dims[0]
    if not isinstance(batch, str):
        fixed = f"a batch of exactly {batch}" if batch is not None else "an unnamed batch axis"
        raise InvalidModel(
            f"the model's input {given.name!r} has {fixed}: its first axis must be a named "
            "dynamic axis (torch.onnx.export(..., dynamic_axes={name: {0: 'batch'}}))"
        )
    memory = _memory(model, inputs[1:], batch)
    values = _values(model, batch)
    cost = _counted(model, values)
    output = _check_outputs(model, values, memory, actions, continuous)
    return ModelInfo(opset, output, given.name, model.graph.output[0].name, memory, cost)
