"""A training run's checkpoint: one file, ``checkpoint.pt``, written whole or not at all (a
temporary file beside it, then ``os.replace``), so that a run stopped at any moment resumes
from the last one written (``nanonav train --resume DIR``)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import torch

CHECKPOINT = "checkpoint.pt"


def save_checkpoint(folder: Path, state: dict[str, Any]) -> Path:
    """Write ``state`` as ``folder``'s checkpoint, replacing the last one atomically."""
    path = folder / CHECKPOINT
    written = folder / f".{CHECKPOINT}.tmp"
    with written.open("wb") as out:
        torch.save(state, out)
        out.flush()
        os.fsync(out.fileno())
    os.replace(written, path)
    return path


def load_checkpoint(folder: Path) -> dict[str, Any]:
    """``folder``'s checkpoint (``FileNotFoundError`` where it has none). Only tensors and
    plain values are read back: a checkpoint holds no code."""
    with (folder / CHECKPOINT).open("rb") as given:
        state: dict[str, Any] = torch.load(given, map_location="cpu", weights_only=True)
    return state
