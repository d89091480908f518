"""Networks sent as ONNX models: checked before they are kept, and run to decide for robots.

ONNX is data (a protobuf graph of standard operators and its weights): nothing here loads a
pickle or TorchScript. A model is accepted when it is small enough, keeps its weights inside
itself (external data could name any file of the machine that runs it), uses only the standard
operator sets at a version ONNX Runtime runs, takes one float32 input of a batch of
observations, ``(batch, width)``, and gives either the action logits, ``(batch, actions)``
floats (the action is their argmax), or the actions themselves, ``(batch,)`` or
``(batch, 1)`` integers; and when it answers a trial batch of zero observations so. A network
that steers continuously (its actions ``turn_side``, ``turn_up``) gives the turn itself,
``(batch, 2)`` floats.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import onnx
import onnxruntime
from numpy.typing import NDArray
from onnx import AttributeProto, GraphProto, TensorProto

from nanonav.scenario import Steering

# The operator sets of ONNX itself (the default domain is spelled both ways) and of ONNX-ML
STANDARD_DOMAINS = frozenset({"", "ai.onnx", "ai.onnx.ml"})
# The default domain's versions accepted: from the first with today's operator semantics that
# exporters still write, to the newest this ONNX knows (ONNX Runtime refuses one it cannot run)
MIN_OPSET = 9
MAX_OPSET = int(onnx.defs.onnx_opset_version())
# Rows of the trial batch: more than one, so that a fixed batch of one is found out
TRIAL_ROWS = 2
RULE = "policy_model"
# The model's metadata keys under which a model names what it reads and chooses (JSON lists of
# an environment's observation_labels and action_labels): nanonav train writes them
METADATA_OBSERVATION = "nanonav.observation"
METADATA_ACTIONS = "nanonav.actions"
# What a value the graph computes may hold: per observation when it has the batch axis, else in
# all. A network of two hidden layers of 256 computes under 1,000 numbers an observation; the
# caps keep a model from asking for memory that no policy needs (a broadcast outer product).
MAX_ROW_ELEMENTS = 10_000
MAX_ELEMENTS = 1_000_000
# Operators whose outputs' sizes or running time the graph alone does not bound
UNBOUNDED_OPERATORS = frozenset({"Loop", "Scan", "If", "SequenceMap"})

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
class ModelInfo:
    """What a checked model is: its operator set version, whether it gives logits, actions or a
    turn,
    the input and output it is run by, and a recurrent model's memory."""

    opset: int
    output: Output
    input_name: str
    output_name: str
    memory: tuple[Memory, ...] = ()


def model_labels(data: bytes, *, max_bytes: int) -> tuple[list[str] | None, list[str] | None]:
    """The observation and action labels a model's metadata names (``METADATA_*``), each
    None where it names none; ``InvalidModel`` for a model that is not one, or labels that are
    not a JSON list of strings."""
    model = _parsed(data, max_bytes)
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


def _tensors(graph: GraphProto) -> Iterator[TensorProto]:
    """Every tensor the graph holds, in its subgraphs too: initializers (dense and sparse) and
    the tensors of node attributes."""
    yield from graph.initializer
    for sparse in graph.sparse_initializer:
        yield sparse.values
        yield sparse.indices
    for node in graph.node:
        for attribute in node.attribute:
            if attribute.type == AttributeProto.TENSOR:
                yield attribute.t
            yield from attribute.tensors
            if attribute.type == AttributeProto.GRAPH:
                yield from _tensors(attribute.g)
            for sub in attribute.graphs:
                yield from _tensors(sub)


def _domains(graph: GraphProto) -> Iterator[str]:
    """The operator domain of every node, in subgraphs too."""
    for node in graph.node:
        yield node.domain
        for attribute in node.attribute:
            if attribute.type == AttributeProto.GRAPH:
                yield from _domains(attribute.g)
            for sub in attribute.graphs:
                yield from _domains(sub)


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


def _parsed(data: bytes, max_bytes: int) -> onnx.ModelProto:
    if len(data) > max_bytes:
        raise InvalidModel(f"the model takes {len(data)} bytes, over the limit of {max_bytes}")
    try:
        model = onnx.load_model_from_string(data)
    except Exception as error:  # protobuf's DecodeError, or worse
        raise InvalidModel(f"this is not an ONNX model: {error}") from None
    if model.ir_version <= 0 or not model.graph.node:
        raise InvalidModel("this is not an ONNX model: it has no IR version or no graph")
    return model


def _check_contents(model: onnx.ModelProto) -> int:
    """Refuse external data, other operator sets and model-local functions; returns the
    default domain's opset."""
    for tensor in _tensors(model.graph):
        if tensor.data_location == TensorProto.EXTERNAL or len(tensor.external_data):
            raise InvalidModel(
                f"tensor {tensor.name!r} keeps its data outside the model: save the model "
                "with its weights inside it (onnx.save(model, path), without "
                "save_as_external_data)"
            )
    if model.functions:
        raise InvalidModel("the model defines functions of its own: only standard operators")
    opset = None
    for entry in model.opset_import:
        if entry.domain not in STANDARD_DOMAINS:
            raise InvalidModel(
                f"the model imports the operator set {entry.domain!r}: only ONNX's own "
                "(and ONNX-ML's) are run"
            )
        if entry.domain in ("", "ai.onnx"):
            opset = int(entry.version)
    if opset is None:
        raise InvalidModel("the model imports no version of ONNX's operator set")
    if not MIN_OPSET <= opset <= MAX_OPSET:
        raise InvalidModel(
            f"the model's opset is {opset}: it must lie between {MIN_OPSET} and {MAX_OPSET}"
        )
    for domain in _domains(model.graph):
        if domain not in STANDARD_DOMAINS:
            raise InvalidModel(f"the model uses an operator of the custom domain {domain!r}")
    try:
        onnx.checker.check_model(model)
    except onnx.checker.ValidationError as error:
        raise InvalidModel(f"the model is not valid ONNX: {_first_line(error)}") from None
    return opset


def _check_sizes(model: onnx.ModelProto, batch: str | None) -> None:
    """Refuse a graph whose computed values have sizes it does not fix (but for the batch
    axis), or that are larger than ``MAX_ROW_ELEMENTS`` an observation (``MAX_ELEMENTS`` for a
    value without the batch axis), and control flow, whose cost the graph does not bound."""
    for node in model.graph.node:
        if node.op_type in UNBOUNDED_OPERATORS:
            raise InvalidModel(
                f"the model uses {node.op_type}: a policy's graph runs straight through, "
                "without loops or branches"
            )
    try:
        inferred = onnx.shape_inference.infer_shapes(model, strict_mode=True, data_prop=True)
    except Exception as error:
        raise InvalidModel(f"the model's shapes do not check: {_first_line(error)}") from None
    graph = inferred.graph
    for value in [*graph.value_info, *graph.output]:
        if not value.type.HasField("tensor_type"):
            raise InvalidModel(f"the model computes {value.name!r}, which is not a tensor")
        dims = _dims(value)
        if not value.type.tensor_type.HasField("shape"):
            dims = [None]
        rows = dims.count(batch) if batch is not None else 0
        fixed = [d for d in dims if d != batch]
        if any(not isinstance(d, int) for d in fixed):
            raise InvalidModel(
                f"the model computes {value.name!r} of shape {dims}, whose size the graph does "
                "not fix: only the batch axis may vary"
            )
        elements = math.prod(d for d in fixed if isinstance(d, int))
        limit = MAX_ROW_ELEMENTS if rows else MAX_ELEMENTS
        if rows > 1 or elements > limit:
            per = " an observation" if rows else ""
            raise InvalidModel(
                f"the model computes {value.name!r} of shape {dims}: {elements} numbers{per}, "
                f"over the {limit} a policy may compute"
            )


def _first_line(error: BaseException) -> str:
    text = str(error).strip()
    return text.splitlines()[0] if text else type(error).__name__


def _session(data: bytes) -> onnxruntime.InferenceSession:
    """An ONNX Runtime session on one thread (a worker runs one job a core)."""
    options = onnxruntime.SessionOptions()
    options.intra_op_num_threads = 1
    options.inter_op_num_threads = 1
    options.log_severity_level = 3
    return onnxruntime.InferenceSession(data, options, providers=["CPUExecutionProvider"])


def check_model(
    data: bytes, width: int, actions: int, *, max_bytes: int, continuous: bool = False
) -> ModelInfo:
    """Check that ``data`` is an ONNX model that decides from ``width`` observation columns
    among ``actions`` actions, or ``continuous``ly a turn of ``actions`` parts
    (``InvalidModel`` saying what is wrong if not), by reading the graph and running it once
    on a batch of zero observations."""
    model = _parsed(data, max_bytes)
    opset = _check_contents(model)
    weights = {tensor.name for tensor in model.graph.initializer}
    inputs = [value for value in model.graph.input if value.name not in weights]
    if not inputs:
        raise InvalidModel("the model takes no input: it must take the observation")
    given = inputs[0]
    if given.type.tensor_type.elem_type != TensorProto.FLOAT:
        kind = TensorProto.DataType.Name(given.type.tensor_type.elem_type)
        raise InvalidModel(f"the model's input {given.name!r} is {kind}, not FLOAT (float32)")
    dims = _dims(given)
    if len(dims) != 2 or dims[1] != width:
        raise InvalidModel(
            f"the model's input {given.name!r} has the shape {dims}: it must be (batch, {width}),"
            f" one row of the {width} observation columns for each robot"
        )
    if not isinstance(dims[0], str):
        fixed = f"a batch of exactly {dims[0]}" if dims[0] is not None else "an unnamed batch axis"
        raise InvalidModel(
            f"the model's input {given.name!r} has {fixed}: its first axis must be a named "
            "dynamic axis (torch.onnx.export(..., dynamic_axes={name: {0: 'batch'}}))"
        )
    memory = _memory(model, inputs[1:], dims[0])
    _check_sizes(model, dims[0])
    try:
        session = _session(data)
    except Exception as error:
        raise InvalidModel(f"ONNX Runtime cannot run the model: {_first_line(error)}") from None
    output = session.get_outputs()[0]
    feeds = {given.name: np.zeros((TRIAL_ROWS, width), np.float32)}
    feeds.update({m.input_name: m.zeros(TRIAL_ROWS) for m in memory})
    names = [output.name, *(m.output_name for m in memory)]
    try:
        answer = session.run(names, feeds)
    except Exception as error:
        raise InvalidModel(
            f"the model failed on a batch of {TRIAL_ROWS} zero observations: {_first_line(error)}"
        ) from None
    kind = _kind(np.asarray(answer[0]), actions, continuous)
    for m, kept in zip(memory, answer[1:], strict=True):
        if np.asarray(kept).shape != m.zeros(TRIAL_ROWS).shape:
            raise InvalidModel(
                f"the model's output {m.output_name!r} is not shaped as its memory "
                f"{m.input_name!r}, {list(m.dims)}"
            )
    return ModelInfo(opset, kind, given.name, output.name, memory)


def _memory(
    model: onnx.ModelProto, inputs: list[onnx.ValueInfoProto], batch: str
) -> tuple[Memory, ...]:
    """The memory of a recurrent model: each input after the observation, float32, with the
    batch axis once and every other axis fixed, at most ``MAX_ROW_ELEMENTS`` numbers a robot,
    given back by the output at its place after the decision (input k+1, output k+1)."""
    outputs = list(model.graph.output)
    found = []
    for k, value in enumerate(inputs, start=1):
        dims = _dims(value)
        fixed = [d for d in dims if d != batch]
        if (
            value.type.tensor_type.elem_type != TensorProto.FLOAT
            or dims.count(batch) != 1
            or not all(isinstance(d, int) for d in fixed)
        ):
            raise InvalidModel(
                f"the model's input {value.name!r}, shape {dims}, is neither the observation "
                f"nor a memory: the first input is the observation; any other is a float32 "
                f"memory with the batch axis {batch!r} once and every other axis fixed"
            )
        if math.prod(d for d in fixed if isinstance(d, int)) > MAX_ROW_ELEMENTS:
            raise InvalidModel(
                f"the model's memory {value.name!r} holds over {MAX_ROW_ELEMENTS} numbers a robot"
            )
        if len(outputs) <= k or _dims(outputs[k]) != dims:
            raise InvalidModel(
                f"the model reads the memory {value.name!r} but gives no output {k} of its "
                f"shape {dims} back: output k after the decision carries input k's memory"
            )
        found.append(Memory(value.name, outputs[k].name, tuple(dims), dims.index(batch)))  # type: ignore[arg-type]
    return tuple(found)


def _kind(answer: NDArray[Any], actions: int, continuous: bool) -> Output:
    """Whether a trial answer is logits or actions, or for a ``continuous`` network a turn of
    ``actions`` parts; InvalidModel if it is not."""
    rows = TRIAL_ROWS
    floats = "a turn must be floats" if continuous else "logits must be"
    if answer.dtype.kind == "f":
        if answer.shape != (rows, actions):
            raise InvalidModel(
                f"the model's first output is floats of shape {list(answer.shape)} for "
                f"{rows} observations: {floats} (batch, {actions}), one per "
                f"{'part' if continuous else 'action'}"
            )
        if not np.isfinite(answer).all():
            raise InvalidModel("the model's answer for zero observations is not finite")
        return "turn" if continuous else "logits"
    if continuous:
        detail = f"{floats} (batch, {actions})"
        raise InvalidModel(f"the model's first output is {answer.dtype}: {detail}")
    if answer.dtype.kind in "iu":
        if answer.shape not in ((rows,), (rows, 1)):
            raise InvalidModel(
                f"the model's first output is integers of shape {list(answer.shape)} for "
                f"{rows} observations: actions must be (batch,) or (batch, 1)"
            )
        if answer.min() < 0 or answer.max() >= actions:
            raise InvalidModel(
                f"the model answers action {int(answer.ravel()[0])} for a zero observation: "
                f"actions are 0..{actions - 1}"
            )
        return "actions"
    raise InvalidModel(f"the model's first output is {answer.dtype}: logits or actions, please")


def _along(memory: Memory, part: slice) -> tuple[slice, ...]:
    """The index of rows ``part`` of a memory, along its batch axis."""
    return tuple(
        part if axis == memory.batch_axis else slice(None) for axis in range(len(memory.dims))
    )


# Observations a single inference call takes: a larger batch is run in parts of this many, so
# that what the graph computes stays within MAX_ROW_ELEMENTS x this many numbers a value
INFERENCE_ROWS = 8192


class NetworkPolicy:
    """A checked model, deciding for many robots in one inference call (in parts of
    ``INFERENCE_ROWS`` for more)."""

    def __init__(
        self, data: bytes, width: int, actions: int, *, max_bytes: int, continuous: bool = False
    ) -> None:
        self.info = check_model(data, width, actions, max_bytes=max_bytes, continuous=continuous)
        self._session = _session(data)
        self.width = width
        self._kept: list[NDArray[np.float32]] | None = None

    @property
    def remembers(self) -> bool:
        """Whether the network carries a memory from decision to decision (recurrent)."""
        return bool(self.info.memory)

    @property
    def steering(self) -> Steering:
        """``continuous`` where the network answers a turn (rows x parts of floats), else
        ``discrete`` (an action number a row)."""
        return "continuous" if self.info.output == "turn" else "discrete"

    def forget(self) -> None:
        """Start every robot's memory afresh at the next call (a new set of episodes)."""
        self._kept = None

    def __call__(self, observations: NDArray[np.float64]) -> NDArray[Any]:
        """The action of each row of ``observations`` (a continuous network's turn, a row of
        floats); a recurrent network's row k carries the memory row k had at the last call (the
        same robot, call after call, until ``forget``)."""
        rows = np.ascontiguousarray(observations, dtype=np.float32)
        memory = self.info.memory
        count = rows.shape[0]
        if memory and (self._kept is None or self._kept[0].shape[memory[0].batch_axis] != count):
            self._kept = [m.zeros(count) for m in memory]
        names = [self.info.output_name, *(m.output_name for m in memory)]
        parts = []
        for at in range(0, max(count, 1), INFERENCE_ROWS):
            part = slice(at, at + INFERENCE_ROWS)
            feeds = {self.info.input_name: rows[part]}
            for m, kept in zip(memory, self._kept or [], strict=True):
                feeds[m.input_name] = kept[_along(m, part)]
            answer = self._session.run(names, feeds)
            for m, kept, new in zip(memory, self._kept or [], answer[1:], strict=True):
                kept[_along(m, part)] = new
            parts.append(np.asarray(answer[0]))
        answer = parts[0] if len(parts) == 1 else np.concatenate(parts)
        if self.info.output == "turn":
            if answer.shape != (rows.shape[0], answer.shape[-1]) or not np.isfinite(answer).all():
                raise ValueError("the model's turns are not finite, one row an observation")
            turns: NDArray[np.float64] = answer.astype(np.float64)
            return turns
        if self.info.output == "logits":
            if answer.shape != (rows.shape[0], answer.shape[-1]) or not np.isfinite(answer).all():
                raise ValueError("the model's logits are not finite, one row an observation")
            chosen: NDArray[np.int64] = np.argmax(answer, axis=1).astype(np.int64)
            return chosen
        actions: NDArray[np.int64] = answer.reshape(-1).astype(np.int64)
        return actions
