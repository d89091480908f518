"""Neighbours in O(n): a cell list, a uniform grid over the space whose cells each hold a linked
list of the robots inside, so that finding every robot within ``cutoff`` of a point looks at the
cells around it (at most 8: they are two cutoffs wide), never at the whole swarm.

The cells are narrow, so a dense cluster (robots packed round a cell
they deliver to) costs a search a few robots, not hundreds. So many cells would not fit in memory
at 100,000 robots, so they are hashed into about two buckets per robot (spatial hashing):
robots of two far cells may share a bucket, which costs a distance test and never changes an
answer, and a search looks at each bucket once.

Two ways to keep it exact while robots move one by one within a step. ``rebuild`` lists every
robot once a step (O(robots)); the grid then still lists a robot where it was, which stays exact
as long as searches reach the longest move of a step further (``grid_for``'s ``step``). Or
``relist`` moves a robot to its new cell as it moves (O(robots in a bucket)), which stays exact
however far a step goes (a Brownian jiggle has no bound): the engine's step does this. Points
outside the grid (a space without walls) are kept in its border cells, which stays exact and
only costs speed.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit
from numpy.typing import NDArray

from nanonav.engine.compiled import inlined

BUCKETS_PER_ROBOT = 2  # at least: rounded up to a power of two
# A cell is this many cutoffs wide: a search then spans at most 2 cells an axis (8 buckets), and
# a cell of a dense cluster holds a few robots (narrower cells cost more buckets a search).
CUTOFFS_PER_CELL = 2.0
FEWEST_BUCKETS = 64
# Cells per axis at most: the cell's coordinates stay far from overflowing the hash.
MAX_CELLS_PER_AXIS = 1 << 20
# The primes of the classic spatial hash (Teschner et al., VMV 2003).
_PX = 73_856_093
_PY = 19_349_663
_PZ = 83_492_791


class CellList(NamedTuple):
    """The grid's arrays: ``heads[b]`` the first robot in bucket b (-1 if none), ``next[i]`` the
    robot after i in its bucket's list, ``cell[i]`` the bucket robot i is listed in (-1 if not)."""

    heads: NDArray[np.int64]  # (buckets,)
    next: NDArray[np.int64]  # (robots,)
    cell: NDArray[np.int64]  # (robots,)
    origin: float  # the grid spans [origin, origin + dims * width) on every axis
    width: float
    dims: int
    slack: float  # how far a robot may be from where it is listed (the ``step`` of grid_for)


def grid_for(half: float, cutoff: float, step: float, robots: int) -> CellList:
    """An empty cell list over the cube [-half, half]^3 whose cells are at least two
    ``cutoff`` wide, for ``robots`` robots that may be up to ``step`` from where they are
    listed (see the module docstring)."""
    if half <= 0 or cutoff < 0 or step < 0:
        raise ValueError("half must be positive, cutoff and step not negative")
    least = max(CUTOFFS_PER_CELL * cutoff, 1e-9)
    dims = max(1, min(MAX_CELLS_PER_AXIS, math.floor(2 * half / least)))
    # a power of two, so that a bucket is the hash's low bits (a mask, not a division)
    wanted = max(FEWEST_BUCKETS, BUCKETS_PER_ROBOT * robots)
    buckets = min(dims**3, 1 << (wanted - 1).bit_length())
    return CellList(
        heads=np.full(buckets, -1, dtype=np.int64),
        next=np.full(robots, -1, dtype=np.int64),
        cell=np.full(robots, -1, dtype=np.int64),
        origin=-half,
        width=2 * half / dims,
        dims=dims,
        slack=step,
    )


@inlined
def _axis_index(v: float, origin: float, width: float, dims: int) -> int:
    k = math.floor((v - origin) / width)
    return min(max(k, 0), dims - 1)


@inlined
def _bucket(grid: CellList, cx: int, cy: int, cz: int) -> int:
    buckets: int = grid.heads.shape[0]
    if buckets == grid.dims * grid.dims * grid.dims:
        return (cx * grid.dims + cy) * grid.dims + cz  # every cell its own bucket
    return ((cx * _PX) ^ (cy * _PY) ^ (cz * _PZ)) & (buckets - 1)


@inlined
def _span(v: float, reach: float, grid: CellList) -> tuple[int, int]:
    """The first and last cell along an axis that a ball of radius ``reach`` around v touches."""
    low = _axis_index(v - reach, grid.origin, grid.width, grid.dims)
    high = _axis_index(v + reach, grid.origin, grid.width, grid.dims)
    return low, high


@inlined
def cell_of(grid: CellList, x: float, y: float, z: float) -> int:
    """The bucket that holds (x, y, z) (border cells hold what lies beyond)."""
    d = grid.dims
    cx = _axis_index(x, grid.origin, grid.width, d)
    cy = _axis_index(y, grid.origin, grid.width, d)
    cz = _axis_index(z, grid.origin, grid.width, d)
    return _bucket(grid, cx, cy, cz)


@njit(cache=True, error_model="numpy")
def rebuild(grid: CellList, pos: NDArray[np.float64], active: NDArray[np.bool_]) -> None:
    """List every active robot in the bucket of the cell it is in now (inactive ones in none)."""
    grid.heads[:] = -1
    for i in range(pos.shape[0]):
        grid.next[i] = -1
        grid.cell[i] = -1
        if not active[i]:
            continue
        c = cell_of(grid, pos[i, 0], pos[i, 1], pos[i, 2])
        grid.cell[i] = c
        grid.next[i] = grid.heads[c]
        grid.heads[c] = i


@njit(cache=True, error_model="numpy")
def relist(grid: CellList, i: int, x: float, y: float, z: float) -> None:
    """Robot ``i`` moved to (x, y, z): list it in the bucket it is in now, so that the grid stays
    exact however far a step goes. O(robots in its old bucket)."""
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
def first_within(
    grid: CellList, pos: NDArray[np.float64], active: NDArray[np.bool_],
    x: float, y: float, z: float, distance: float, skip: int,
) -> int:  # fmt: skip
    """The lowest-indexed active robot other than ``skip`` closer than ``distance`` to
    (x, y, z), or -1: what a robot moving there would run into. The lowest index, not the
    first found, so the answer does not depend on the lists' order."""
    reach = distance + grid.slack
    x0, x1 = _span(x, reach, grid)
    y0, y1 = _span(y, reach, grid)
    z0, z1 = _span(z, reach, grid)
    d2 = distance * distance
    best = -1
    for ax in range(x0, x1 + 1):
        for ay in range(y0, y1 + 1):
            for az in range(z0, z1 + 1):
                # a bucket met twice is searched twice: the lowest index is the same answer
                j = grid.heads[_bucket(grid, ax, ay, az)]
                while j >= 0:
                    if j != skip and active[j] and (best < 0 or j < best):
                        dx = pos[j, 0] - x
                        dy = pos[j, 1] - y
                        dz = pos[j, 2] - z
                        if dx * dx + dy * dy + dz * dz < d2:
                            best = j
                    j = grid.next[j]
    return best


@inlined
def _met_before(
    grid: CellList, b: int, x0: int, y0: int, z0: int, ax: int, ay: int, az: int,
    y1: int, z1: int,
) -> bool:  # fmt: skip
    """Whether a cell before (ax, ay, az) in a search's order over [x0..][y0..y1][z0..z1]
    hashes to bucket ``b`` too: the search then met the bucket already. Recomputed rather than
    remembered, so that a search allocates nothing (a search spans a few cells)."""
    for cx in range(x0, ax + 1):
        for cy in range(y0, y1 + 1):
            for cz in range(z0, z1 + 1):
                if cx == ax and cy == ay and cz == az:
                    return False
                if _bucket(grid, cx, cy, cz) == b:
                    return True
    return False


@inlined
def _sift_down(a: NDArray[np.int64], start: int, end: int) -> None:
    root = start
    while 2 * root + 1 < end:
        child = 2 * root + 1
        if child + 1 < end and a[child] < a[child + 1]:
            child += 1
        if a[root] >= a[child]:
            return
        a[root], a[child] = a[child], a[root]
        root = child


@njit(cache=True, error_model="numpy")
def sort_first(a: NDArray[np.int64], k: int) -> None:
    """Sort ``a[:k]`` in place (a heapsort: numba's own sort allocates its stack)."""
    for start in range(k // 2 - 1, -1, -1):
        _sift_down(a, start, k)
    for end in range(k - 1, 0, -1):
        a[0], a[end] = a[end], a[0]
        _sift_down(a, 0, end)


@njit(cache=True, error_model="numpy")
def each_within(
    grid: CellList, pos: NDArray[np.float64], x: float, y: float, z: float, distance: float,
    out: NDArray[np.int64],
) -> int:  # fmt: skip
    """Every listed robot closer than ``distance`` to (x, y, z), written to ``out[:k]`` in
    increasing index order; returns k. Allocates nothing, so the step can call it."""
    reach = distance + grid.slack
    x0, x1 = _span(x, reach, grid)
    y0, y1 = _span(y, reach, grid)
    z0, z1 = _span(z, reach, grid)
    d2 = distance * distance
    k = 0
    for ax in range(x0, x1 + 1):
        for ay in range(y0, y1 + 1):
            for az in range(z0, z1 + 1):
                b = _bucket(grid, ax, ay, az)
                if _met_before(grid, b, x0, y0, z0, ax, ay, az, y1, z1):
                    continue
                j = grid.heads[b]
                while j >= 0:
                    dx = pos[j, 0] - x
                    dy = pos[j, 1] - y
                    dz = pos[j, 2] - z
                    if dx * dx + dy * dy + dz * dz < d2:
                        out[k] = j
                        k += 1
                    j = grid.next[j]
    sort_first(out, k)
    return k


@njit(cache=True, error_model="numpy")
def pairs_within(
    grid: CellList, pos: NDArray[np.float64], active: NDArray[np.bool_], distance: float
) -> int:
    """How many pairs of active robots are closer than ``distance`` (each pair once), from a
    freshly rebuilt grid."""
    d2 = distance * distance
    reach = distance + grid.slack
    found = 0
    for i in range(pos.shape[0]):
        if not active[i]:
            continue
        x0, x1 = _span(pos[i, 0], reach, grid)
        y0, y1 = _span(pos[i, 1], reach, grid)
        z0, z1 = _span(pos[i, 2], reach, grid)
        for ax in range(x0, x1 + 1):
            for ay in range(y0, y1 + 1):
                for az in range(z0, z1 + 1):
                    b = _bucket(grid, ax, ay, az)
                    if _met_before(grid, b, x0, y0, z0, ax, ay, az, y1, z1):
                        continue
                    j = grid.heads[b]
                    while j >= 0:
                        if j > i:
                            dx = pos[j, 0] - pos[i, 0]
                            dy = pos[j, 1] - pos[i, 1]
                            dz = pos[j, 2] - pos[i, 2]
                            if dx * dx + dy * dy + dz * dz < d2:
                                found += 1
                        j = grid.next[j]
    return found


@inlined
def pushed_out(
    cx: float, cy: float, cz: float, reach: float, x: float, y: float, z: float,
) -> tuple[float, float, float, bool]:  # fmt: skip
    """Where a hard sphere whose centre a move took to (x, y, z), closer than ``reach`` to c,
    comes to rest: moved out along the line of centres to contact (the potential-free
    algorithm of Heyes & Melrose, J. Non-Newtonian Fluid Mech. 46, 1 (1993)). The part of the
    move into the other body is undone and the rest kept, so a body pushed against another
    slides round it by as much whatever the time step. False (and (x, y, z)) where the point
    is not inside that reach (a move that passed through) or is its very centre."""
    dx = x - cx
    dy = y - cy
    dz = z - cz
    d = math.sqrt(dx * dx + dy * dy + dz * dz)
    if d >= reach or d <= 0.0:
        return x, y, z, False
    # a hair beyond contact, so that rounding does not leave it touching
    f = reach * (1.0 + 1e-12) / d
    return cx + f * dx, cy + f * dy, cz + f * dz, True


@njit(cache=True, error_model="numpy")
def bumped_back(
    grid: CellList, pos: NDArray[np.float64], everyone: NDArray[np.bool_], i: int,
    px: float, py: float, pz: float, contact: float,
) -> bool:  # fmt: skip
    """Robot ``i`` moved from p to where ``pos`` has it: if another robot is now closer than
    ``contact``, put it back at p and return True (a bump); else list it where it is."""
    if first_within(grid, pos, everyone, pos[i, 0], pos[i, 1], pos[i, 2], contact, i) >= 0:
        pos[i, 0] = px
        pos[i, 1] = py
        pos[i, 2] = pz
        return True
    relist(grid, i, pos[i, 0], pos[i, 1], pos[i, 2])
    return False
