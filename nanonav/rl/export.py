"""A trained network's greedy decision written as ONNX, the file the service checks and runs
(``nanonav.rl.graph`` says what such a model may be): one float32 ``observation`` input
``(batch, width)``, the action ``logits`` (or steering continuously the ``turn``) out; a
recurrent one also takes ``memory_in`` ``(batch, units)`` and gives ``memory_out`` back."""

from __future__ import annotations

import json
import warnings
from collections.abc import Sequence
from pathlib import Path

import torch

from nanonav.rl.graph import METADATA_ACTIONS, METADATA_OBSERVATION
from nanonav.rl.networks import ActorCritic, Greedy

ONNX_OPSET = 17
"""The ONNX opset written: one that every onnxruntime since 2022 runs."""


def export_network(
    net: ActorCritic,
    path: Path,
    *,
    observation: Sequence[str] | None = None,
    actions: Sequence[str] | None = None,
) -> None:
    """Write ``net``'s greedy decision to ``path`` (through a temporary file, so that a reader
    never meets half a model), with the env's ``observation`` and ``actions`` labels in its
    metadata, where ``POST /policies`` reads them."""
    greedy = Greedy(net).to("cpu").eval()
    given: tuple[torch.Tensor, ...] = (torch.zeros(1, net.width),)
    first = "turn" if net.continuous else "logits"
    inputs, outputs = ["observation"], [first]
    if net.memory_units:
        given = (*given, torch.zeros(1, net.memory_units))
        inputs.append("memory_in")
        outputs.append("memory_out")
    axes = {name: {0: "batch"} for name in (*inputs, *outputs)}
    write_onnx(greedy, given, path, inputs=inputs, outputs=outputs, axes=axes,
               observation=observation, actions=actions)  # fmt: skip


def write_onnx(
    module: torch.nn.Module,
    given: tuple[torch.Tensor, ...],
    path: Path,
    *,
    inputs: list[str],
    outputs: list[str],
    axes: dict[str, dict[int, str]],
    observation: Sequence[str] | None = None,
    actions: Sequence[str] | None = None,
) -> None:
    """Trace ``module`` on ``given`` into an ONNX model at ``path``, its inputs and outputs
    named and their ``axes`` dynamic, with the labels in its metadata (``label``), through a
    temporary file, so that a reader never meets half a model."""
    written = path.with_name(path.name + ".tmp")
    with warnings.catch_warnings():
        # the TorchScript exporter (the newer one needs onnxscript, which nothing else does)
        # warns that it is deprecated, and its tracer that a recurrent cell's shape checks are
        # traced as constants: the ONNX cell it writes takes any batch (tests run it at another)
        warnings.simplefilter("ignore")
        torch.onnx.export(
            module, given, str(written), input_names=inputs, output_names=outputs,
            opset_version=ONNX_OPSET, dynamo=False, dynamic_axes=axes,
        )  # fmt: skip
    label(written, observation=observation, actions=actions)
    written.replace(path)


def label(
    path: Path, *, observation: Sequence[str] | None = None, actions: Sequence[str] | None = None
) -> None:
    """Write the observation and action labels into the ONNX model at ``path``'s metadata
    (``METADATA_OBSERVATION``, ``METADATA_ACTIONS``: JSON lists)."""
    if observation is None and actions is None:
        return
    import onnx

    model = onnx.load(str(path))
    for key, labels in ((METADATA_OBSERVATION, observation), (METADATA_ACTIONS, actions)):
        if labels is not None:
            entry = model.metadata_props.add()
            entry.key, entry.value = key, json.dumps(list(labels))
    onnx.save(model, str(path))
