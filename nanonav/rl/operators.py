"""The operators a network sent as a policy may use: an allow-list, each with why a policy needs
it and what it costs.

A policy maps an observation of a few numbers to action logits, a turn or an action. What the
exporters our users run write for one (PyTorch's ``torch.onnx.export`` of a Stable-Baselines3
or sb3-contrib policy, ``nanonav train``'s ``export_onnx``) is dense layers, activations,
normalisation, a recurrent cell, some reshaping and at most an ``ArgMax`` at the end. Anything
else is refused, naming the node: convolutions, control flow, random numbers, string and
sequence operators, and arithmetic on integers (integer division is how a 300-byte model
raised SIGFPE in ONNX Runtime). Integers only index and shape: an operator that computes takes
float32 alone; one that moves numbers (``Operator.moves``) may carry int64 and int32 too.

The cost of a node (``Operator.cost``) is counted in multiply-adds from the shapes shape
inference gives, per observation when its values have the batch axis: a dense layer's
products, a recurrent cell's products at every step of the sequence, and for everything else
its output's numbers once (its input's for a reduction), weighted by ``TRANSCENDENTAL`` for a
function such as tanh that costs several multiply-adds an element.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

Cost = Literal["gemm", "matmul", "lstm", "gru", "rnn", "elements", "transcendental", "reduce",
               "none"]  # fmt: skip
# An element of exp, tanh, a sigmoid or an error function, in multiply-adds: ONNX Runtime's
# vectorised tanh takes about as long as 8 multiply-adds of a dense layer on one core
TRANSCENDENTAL = 8
# The types a value may have: float32 for what is computed, int64 and int32 for shapes, axes,
# indices, sequence lengths and the actions an ArgMax gives
# (ONNX's TensorProto.DataType numbers, fixed by its specification: named here so that what
# imports the allow-list does not import ONNX, half a second of every API process's start)
FLOAT = 1
INT32 = 6
INT64 = 7
INTEGERS = frozenset({INT64, INT32})
TYPES = frozenset({FLOAT, *INTEGERS})


@dataclass(frozen=True)
class Operator:
    """An operator a policy may use: why it is on the list, how its cost is counted, whether it
    only moves numbers (then any of ``TYPES`` may pass through it), and which of its inputs are
    parameters that may be integers (a shape, axes, indices, sequence lengths)."""

    why: str
    cost: Cost = "elements"
    moves: bool = False
    parameters: frozenset[int] = frozenset()


def _op(why: str, cost: Cost = "elements", *, moves: bool = False,
        parameters: Sequence[int] = ()) -> Operator:  # fmt: skip
    return Operator(why, cost, moves, frozenset(parameters))


DENSE = "a dense layer (PyTorch's nn.Linear)"
WRITTEN_OUT = "{} written out, as PyTorch exports it at the older opsets"
ALLOWED: dict[str, Operator] = {
    # dense layers
    "Gemm": _op(DENSE + ": x W^T + b in one operator", "gemm"),
    "MatMul": _op(DENSE + " without its bias, or an LSTM's input projection", "matmul"),
    "Add": _op("a bias, a residual connection, normalisation's shift"),
    "Sub": _op("normalisation's centring, a difference of features"),
    "Mul": _op("a scale, a gate, normalisation's gain"),
    "Div": _op("normalisation's division, a temperature (floats only: no integer division)"),
    # activations
    "Relu": _op("an activation (Stable-Baselines3's DQN default)"),
    "LeakyRelu": _op("an activation"),
    "PRelu": _op("an activation with a learned slope"),
    "Elu": _op("an activation", "transcendental"),
    "Selu": _op("an activation", "transcendental"),
    "Celu": _op("an activation", "transcendental"),
    "Tanh": _op("an activation (Stable-Baselines3's PPO default)", "transcendental"),
    "Sigmoid": _op("an activation, a gate", "transcendental"),
    "HardSigmoid": _op("an activation"),
    "HardSwish": _op("an activation"),
    "Softplus": _op("an activation, a positive scale", "transcendental"),
    "Softsign": _op("an activation"),
    "Gelu": _op("an activation (transformers' MLPs)", "transcendental"),
    "Erf": _op(WRITTEN_OUT.format("GELU"), "transcendental"),
    "Mish": _op("an activation", "transcendental"),
    "Clip": _op("a continuous action clipped to its bounds, as Stable-Baselines3 predicts it"),
    "Max": _op("an activation or a bound written out"),
    "Min": _op("an activation or a bound written out"),
    "Abs": _op("a magnitude"),
    "Neg": _op("a sign flipped"),
    "Exp": _op(WRITTEN_OUT.format("softmax") + "; a log-std's scale", "transcendental"),
    "Log": _op(WRITTEN_OUT.format("log-softmax"), "transcendental"),
    "Sqrt": _op(WRITTEN_OUT.format("normalisation"), "transcendental"),
    "Reciprocal": _op(WRITTEN_OUT.format("normalisation")),
    "Pow": _op(
        WRITTEN_OUT.format("normalisation (the square of the centred input)"), "transcendental"
    ),
    "Softmax": _op("a distribution over the actions", "transcendental"),
    "LogSoftmax": _op("a distribution over the actions, as log-probabilities", "transcendental"),
    # normalisation
    "LayerNormalization": _op("normalisation (nn.LayerNorm, opset 17 and later)"),
    "BatchNormalization": _op("normalisation with fixed statistics (nn.BatchNorm1d, in eval)"),
    "ReduceMean": _op(WRITTEN_OUT.format("normalisation's mean"), "reduce", parameters=[1]),
    "ReduceSum": _op(WRITTEN_OUT.format("softmax's sum"), "reduce", parameters=[1]),
    "ReduceMax": _op(WRITTEN_OUT.format("a stable softmax's maximum"), "reduce", parameters=[1]),
    # recurrent cells: a memory carried from decision to decision (sb3-contrib's RecurrentPPO)
    "LSTM": _op(
        "a recurrent policy's memory (RecurrentPPO's MlpLstmPolicy)", "lstm", parameters=[4]
    ),
    "GRU": _op("a recurrent policy's memory", "gru", parameters=[4]),
    "RNN": _op("a recurrent policy's memory", "rnn", parameters=[4]),
    # reshaping: numbers moved, not computed
    "Identity": _op("a name given to a value (PyTorch writes it for outputs)", "none", moves=True),
    "Constant": _op("a weight or a shape written into the graph", "none", moves=True),
    "Cast": _op(
        "the float32 cast PyTorch writes at the input; actions cast to an integer type", moves=True
    ),
    "Flatten": _op(
        "the observation flattened (Stable-Baselines3's FlattenExtractor)", "none", moves=True
    ),
    "Reshape": _op("a layer's output reshaped", "none", moves=True, parameters=[1]),
    "Squeeze": _op(
        "an axis dropped: a recurrent cell's sequence axis", "none", moves=True, parameters=[1]
    ),
    "Unsqueeze": _op(
        "an axis added: a recurrent cell's sequence axis", "none", moves=True, parameters=[1]
    ),
    "Transpose": _op("axes swapped: a recurrent cell's batch and sequence", moves=True),
    "Concat": _op("features joined, a shape built", moves=True),
    "Split": _op("features or gates split", moves=True, parameters=[1]),
    "Slice": _op("some features taken", moves=True, parameters=[1, 2, 3, 4]),
    "Gather": _op("some features or a shape's axis taken", moves=True, parameters=[1]),
    "Shape": _op("a value's shape, to reshape another by it", "none", moves=True),
    # the end: the action itself
    "ArgMax": _op("the action: the index of the largest logit", "reduce"),
}
# Where a model may give integers: ArgMax's output, and what moves them
GIVES_INTEGERS = frozenset({"ArgMax", "Shape"})


def type_name(elem_type: int) -> str:
    """``FLOAT``, ``INT64``, ... as ONNX names an element type."""
    from onnx import TensorProto

    try:
        return str(TensorProto.DataType.Name(elem_type))
    except ValueError:
        return f"type {elem_type}"


def refusal(op_type: str, domain: str, inputs: Sequence[int | None]) -> str | None:
    """Why a node of ``op_type`` in ``domain`` whose inputs have the element types ``inputs``
    (None for an input left out) may not run in a policy, or None if it may."""
    if domain not in ("", "ai.onnx"):
        return f"its operator is of the domain {domain!r}: only ONNX's own operators are run"
    operator = ALLOWED.get(op_type)
    if operator is None:
        return (
            f"{op_type} is not an operator a policy needs: the allowed ones are dense layers, "
            "activations, normalisation, LSTM, GRU and RNN, reshaping and ArgMax "
            "(the full list: docs/reference/networks.md)"
        )
    for position, kind in enumerate(inputs):
        if kind is None:
            continue
        if kind not in TYPES:
            return f"its input {position} is {type_name(kind)}: values are float32, or integers"
        if kind != FLOAT and not operator.moves and position not in operator.parameters:
            return (
                f"its input {position} is {type_name(kind)}: {op_type} computes on float32 "
                "only (arithmetic on integers is not run)"
            )
    return None


def multiply_adds(
    op_type: str, inputs: Sequence[Sequence[int] | None], outputs: Sequence[Sequence[int] | None]
) -> int:
    """What a node costs, in multiply-adds, for the shapes of its inputs and outputs (with the
    batch axis, where a value has it, taken as 1: the cost of one observation)."""
    operator = ALLOWED[op_type]
    out = outputs[0] if outputs and outputs[0] is not None else ()
    given = inputs[0] if inputs and inputs[0] is not None else ()
    if operator.cost == "none":
        return 0
    if operator.cost == "gemm":
        # (M, K) x (K, N) + (M, N): K products for each number of the output, and its bias (K
        # read off A, transposed or not, as its numbers over the output's M rows)
        rows = out[0] if out else 1
        return math.prod(out) * (math.prod(given) // max(rows, 1) + 1)
    if operator.cost == "matmul":
        return math.prod(out) * (given[-1] if given else 1)
    if operator.cost in ("lstm", "gru", "rnn"):
        return _recurrent(operator.cost, inputs)
    if operator.cost == "reduce":
        return math.prod(given)
    elements = sum(math.prod(shape) for shape in outputs if shape is not None)
    if operator.cost == "transcendental":
        return TRANSCENDENTAL * elements
    return elements


def _recurrent(kind: str, inputs: Sequence[Sequence[int] | None]) -> int:
    """A recurrent cell over its sequence: at each step the gates' products with the input and
    the memory (W x and R h, each gate H numbers), and their activations."""
    x, w, r = (inputs[k] if k < len(inputs) else None for k in range(3))
    if x is None or w is None or r is None or len(x) != 3 or len(w) != 3:
        return 0
    # (sequence, batch, input) or, with layout 1, (batch, sequence, input): the batch is 1 here
    steps, width = x[0] * x[1], x[2]
    directions, rows, hidden = r[0], r[1], r[2]
    products = rows * (width + hidden)
    activations = TRANSCENDENTAL * rows + 4 * hidden
    return steps * directions * (products + activations)
