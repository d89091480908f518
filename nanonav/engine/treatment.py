"""Cells that can be treated: a robot that reaches an untreated cell delivers its payload and
stays bound to it; the ``capacity``-th payload treats the cell, whose sources then shed only
``treated_secretion`` of their biomarker, and which is no longer a target (not sensed, not
reached: later robots are turned away and keep searching).

A room of its own because what a delivery does to the world is apart from how robots move,
sense or choose. Everything here runs under numba.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from nanonav.engine.compiled import inlined
from nanonav.engine.state import KernelParams, Social, Treatment


@inlined
def nearest_target(
    cells: NDArray[np.float64], treated_at: NDArray[np.int64], x: float, y: float, z: float
) -> tuple[int, float]:
    """The untreated cell nearest to (x, y, z) and its distance (-1 and inf if none is left)."""
    best = -1
    best_d2 = np.inf
    for j in range(cells.shape[0]):
        if treated_at[j] >= 0:
            continue
        dx = cells[j, 0] - x
        dy = cells[j, 1] - y
        dz = cells[j, 2] - z
        d2 = dx * dx + dy * dy + dz * dz
        if d2 < best_d2:
            best_d2 = d2
            best = j
    return best, math.sqrt(best_d2)


@inlined
def untreated(treated_at: NDArray[np.int64]) -> int:
    """How many cells still need drug."""
    left = 0
    for j in range(treated_at.shape[0]):
        if treated_at[j] < 0:
            left += 1
    return left


@njit(cache=True, error_model="numpy")
def deliver(p: KernelParams, tr: Treatment, so: Social, i: int, cell: int, t: int) -> bool:
    """Robot ``i`` delivers its payload to ``cell`` at step ``t`` and is bound there; returns
    whether this treated the cell (from the next step its sources keep ``treated_secretion`` of
    their strength: ``fields.place_treated``)."""
    so.bound_to[i] = cell
    tr.load[cell] += 1
    if p.capacity <= 0 or tr.load[cell] < p.capacity:
        return False
    tr.treated_at[cell] = t
    return True
