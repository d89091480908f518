"""Neighbours in O(n): a cell list, a uniform grid over the space whose cells each hold a linked
list of the robots inside, so that finding every robot within ``cutoff`` of a point looks at the
27 cells around it, never at the whole swarm.

Two ways to keep it exact while robots move one by one within a step. ``rebuild`` lists every
robot once a step (O(robots)); the grid then still lists a robot where it was, which stays exact
as long as a cell is at least the cutoff plus the longest move of a step wide (``grid_for``'s
``step``). Or ``relist`` moves a robot to its new cell as it moves (O(robots in a cell)), which
stays exact however far a step goes (a Brownian jiggle has no bound): the engine's step does
this, with cells as wide as the cutoff. Points outside the grid (a space without walls) are kept
in its border cells, which stays exact and only costs speed.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit
from numpy.typing import NDArray

# At most this many cells per axis: beyond, cells are made wider (the search stays exact).
MAX_CELLS_PER_AXIS = 256
CELLS_PER_ROBOT = 8


class CellList(NamedTuple):
    """The grid's arrays: ``heads[c]`` the first robot in cell c (-1 if none), ``next[i]`` the
    robot after i in its cell's list, ``cell[i]`` the cell robot i is listed in (-1 if not)."""

    heads: NDArray[np.int64]  # (cells,)
    next: NDArray[np.int64]  # (robots,)
    cell: NDArray[np.int64]  # (robots,)
    origin: float  # the grid spans [origin, origin + dims * width) on every axis
    width: float
    dims: int


def grid_for(half: float, cutoff: float, step: float, robots: int) -> CellList:
    """An empty cell list over the cube [-half, half]^3 whose cells are at least
    ``cutoff + step`` wide (see the module docstring), for ``robots`` robots."""
    if half <= 0 or cutoff < 0 or step < 0:
        raise ValueError("half must be positive, cutoff and step not negative")
    least = max(cutoff + step, 1e-9)
    # no more than about CELLS_PER_ROBOT cells a robot: more would only cost memory
    roomy = math.ceil((CELLS_PER_ROBOT * max(robots, 1)) ** (1 / 3))
    dims = max(1, min(MAX_CELLS_PER_AXIS, roomy, math.floor(2 * half / least)))
    width = 2 * half / dims
    return CellList(
        heads=np.full(dims**3, -1, dtype=np.int64),
        next=np.full(robots, -1, dtype=np.int64),
        cell=np.full(robots, -1, dtype=np.int64),
        origin=-half,
        width=width,
        dims=dims,
    )


@njit(cache=True, error_model="numpy", inline="always")
def _axis_index(v: float, origin: float, width: float, dims: int) -> int:
    k = math.floor((v - origin) / width)
    return min(max(k, 0), dims - 1)


@njit(cache=True, error_model="numpy")
def rebuild(grid: CellList, pos: NDArray[np.float64], active: NDArray[np.bool_]) -> None:
    """List every active robot in the cell it is in now (inactive ones in none)."""
    grid.heads[:] = -1
    d = grid.dims
    for i in range(pos.shape[0]):
        grid.next[i] = -1
        grid.cell[i] = -1
        if not active[i]:
            continue
        cx = _axis_index(pos[i, 0], grid.origin, grid.width, d)
        cy = _axis_index(pos[i, 1], grid.origin, grid.width, d)
        cz = _axis_index(pos[i, 2], grid.origin, grid.width, d)
        c = (cx * d + cy) * d + cz
        grid.cell[i] = c
        grid.next[i] = grid.heads[c]
        grid.heads[c] = i


@njit(cache=True, error_model="numpy")
def first_within(
    grid: CellList, pos: NDArray[np.float64], active: NDArray[np.bool_],
    x: float, y: float, z: float, distance: float, skip: int,
) -> int:  # fmt: skip
    """The lowest-indexed active robot other than ``skip`` closer than ``distance`` to
    (x, y, z), or -1: what a robot moving there would run into. The lowest index, not the
    first found, so the answer does not depend on the lists' order."""
    d = grid.dims
    cx = _axis_index(x, grid.origin, grid.width, d)
    cy = _axis_index(y, grid.origin, grid.width, d)
    cz = _axis_index(z, grid.origin, grid.width, d)
    d2 = distance * distance
    best = -1
    for ax in range(max(cx - 1, 0), min(cx + 2, d)):
        for ay in range(max(cy - 1, 0), min(cy + 2, d)):
            for az in range(max(cz - 1, 0), min(cz + 2, d)):
                j = grid.heads[(ax * d + ay) * d + az]
                while j >= 0:
                    if j != skip and active[j] and (best < 0 or j < best):
                        dx = pos[j, 0] - x
                        dy = pos[j, 1] - y
                        dz = pos[j, 2] - z
                        if dx * dx + dy * dy + dz * dz < d2:
                            best = j
                    j = grid.next[j]
    return best


@njit(cache=True, error_model="numpy")
def pairs_within(
    grid: CellList, pos: NDArray[np.float64], active: NDArray[np.bool_], distance: float
) -> int:
    """How many pairs of active robots are closer than ``distance`` (each pair once), from a
    freshly rebuilt grid whose cells are at least ``distance`` wide."""
    d = grid.dims
    d2 = distance * distance
    found = 0
    for i in range(pos.shape[0]):
        if not active[i]:
            continue
        c = grid.cell[i]
        cx = c // (d * d)
        cy = (c // d) % d
        cz = c % d
        for ax in range(max(cx - 1, 0), min(cx + 2, d)):
            for ay in range(max(cy - 1, 0), min(cy + 2, d)):
                for az in range(max(cz - 1, 0), min(cz + 2, d)):
                    j = grid.heads[(ax * d + ay) * d + az]
                    while j >= 0:
                        if j > i:
                            dx = pos[j, 0] - pos[i, 0]
                            dy = pos[j, 1] - pos[i, 1]
                            dz = pos[j, 2] - pos[i, 2]
                            if dx * dx + dy * dy + dz * dz < d2:
                                found += 1
                        j = grid.next[j]
    return found


@njit(cache=True, error_model="numpy", inline="always")
def cell_of(grid: CellList, x: float, y: float, z: float) -> int:
    """The index of the grid cell that holds (x, y, z) (border cells hold what lies beyond)."""
    d = grid.dims
    cx = _axis_index(x, grid.origin, grid.width, d)
    cy = _axis_index(y, grid.origin, grid.width, d)
    cz = _axis_index(z, grid.origin, grid.width, d)
    return (cx * d + cy) * d + cz


@njit(cache=True, error_model="numpy")
def relist(grid: CellList, i: int, x: float, y: float, z: float) -> None:
    """Robot ``i`` moved to (x, y, z): list it in the cell it is in now, so that the grid stays
    exact however far a step goes (a Brownian jiggle has no bound). O(robots in its old cell)."""
    old = grid.cell[i]
    new = cell_of(grid, x, y, z)
    if new == old:
        return
    if old >= 0:
        j = grid.heads[old]
        if j == i:
            grid.heads[old] = grid.next[i]
        else:
            while j >= 0:
                if grid.next[j] == i:
                    grid.next[j] = grid.next[i]
                    break
                j = grid.next[j]
    grid.cell[i] = new
    grid.next[i] = grid.heads[new]
    grid.heads[new] = i


@njit(cache=True, error_model="numpy")
def each_within(
    grid: CellList, pos: NDArray[np.float64], x: float, y: float, z: float, distance: float,
    out: NDArray[np.int64],
) -> int:  # fmt: skip
    """Every listed robot closer than ``distance`` to (x, y, z), written to ``out[:k]`` in
    increasing index order; returns k. The grid's cells must be at least ``distance`` wide."""
    d = grid.dims
    cx = _axis_index(x, grid.origin, grid.width, d)
    cy = _axis_index(y, grid.origin, grid.width, d)
    cz = _axis_index(z, grid.origin, grid.width, d)
    d2 = distance * distance
    k = 0
    for ax in range(max(cx - 1, 0), min(cx + 2, d)):
        for ay in range(max(cy - 1, 0), min(cy + 2, d)):
            for az in range(max(cz - 1, 0), min(cz + 2, d)):
                j = grid.heads[(ax * d + ay) * d + az]
                while j >= 0:
                    dx = pos[j, 0] - x
                    dy = pos[j, 1] - y
                    dz = pos[j, 2] - z
                    if dx * dx + dy * dy + dz * dz < d2:
                        out[k] = j
                        k += 1
                    j = grid.next[j]
    out[:k].sort()
    return k
