"""Chemical signals robots release, on a grid: each species diffuses with its own coefficient D and
decays at rate k, dc/dt = D lap c - k c, solved by explicit finite differences on a uniform grid.

Why a grid: the field of many releasing robots, read by many robots, then costs O(nodes) per update
and O(1) per release and per reading, never sources x readers as a sum of Green's functions would.

The scheme:

- time and space: forward Euler in time, the 7-point Laplacian in space (FTCS), with first-order
  decay, so one step is c' = a c + r (sum of the 6 neighbours), r = D dt / h^2 and
  a = 1 - 6 r - k dt. Every weight is non-negative, and the step is a positive map that never
  raises the maximum, while dt (6 D / h^2 + k) <= 1 (``stable_step``). Past
  dt (12 D / h^2 + k) = 2, at most twice that bound, the checkerboard mode grows without bound.
  The scheme is first order in time and second in space; with reflecting faces a step conserves
  sum c h^3 but for the factor (1 - k dt) of decay. At the bound itself, and k dt small, the
  node's own weight a is about 0: a point release then hops between the two halves of the
  lattice (i + j + m even, odd) on alternate steps and the field is a checkerboard whose odd-even
  part decays only as (1 - k dt)^n. Half the bound makes a = 1/2 and damps that mode at once (its
  factor a step is then k dt); a steady state, as of a constant source, does not depend on dt.
- faces: reflecting (zero flux) or absorbing (zero beyond), both by ghost nodes one spacing
  outside the outer nodes. Reflecting mirrors the outer node into its ghost, so nothing crosses
  the face between them: each node is the centre of a cube of side h, the walls lie h / 2
  outside the outer nodes, and the amount on the grid is exactly sum c h^3.
- releasing: cloud-in-cell, the amount shared over the 8 nodes around the point with trilinear
  weights, so the deposit's mass and centre of mass are exactly the amount and the point.
- reading: trilinear interpolation and its exact derivative, which reproduce a linear field.

Points outside the grid are clamped onto its boundary, for releases and readings alike.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit
from numpy.typing import NDArray

from nanonav.engine.compiled import inlined, inlined_callable


class SignalGrid(NamedTuple):
    """The arrays of the grid: ``conc[s]`` the concentration of species s at the nodes, ``scratch``
    the work array ``diffuse`` writes one step into, shared by all species."""

    conc: NDArray[np.float64]  # (species, dims, dims, dims)
    scratch: NDArray[np.float64]  # (dims, dims, dims)
    origin: float  # node (i, j, m) sits at origin + spacing * (i, j, m)
    spacing: float
    dims: int


def grid_for(half: float, nodes_per_axis: int, species: int) -> SignalGrid:
    """A zero grid of nodes_per_axis^3 nodes spanning the cube [-half, half]^3 (nodes on both
    faces, so spacing = 2 half / (nodes_per_axis - 1)), for ``species`` signals."""
    if half <= 0 or nodes_per_axis < 2 or species < 1:
        raise ValueError("half must be positive, nodes_per_axis at least 2, species at least 1")
    n = int(nodes_per_axis)
    return SignalGrid(
        conc=np.zeros((species, n, n, n), dtype=np.float64),
        scratch=np.zeros((n, n, n), dtype=np.float64),
        origin=-half,
        spacing=2 * half / (n - 1),
        dims=n,
    )


@inlined_callable
def _weights(diffusion: float, decay: float, dt: float, spacing: float) -> tuple[float, float]:
    """The weights of one step, (a, r): the node's own and each neighbour's. ``stable_step``
    calls it too, so that the bound holds for the very numbers ``diffuse`` uses."""
    r = diffusion * dt / (spacing * spacing)
    return 1.0 - 6.0 * r - decay * dt, r


def stable_step(diffusion: float, decay: float, spacing: float) -> float:
    """The largest time step for which the explicit update keeps every node non-negative and is
    stable: dt (6 D / h^2 + k) <= 1. It is nudged down to the float below when rounding would make
    the node's own weight negative, so non-negativity holds exactly, not only to round-off.
    Infinite when nothing diffuses or decays. A field smooth from node to node after point
    releases wants half of it (see the module docstring)."""
    if diffusion < 0 or decay < 0 or spacing <= 0:
        raise ValueError("diffusion and decay must not be negative, spacing must be positive")
    rate = 6.0 * diffusion / (spacing * spacing) + decay
    if rate == 0:
        return math.inf
    dt = 1.0 / rate
    while _weights(diffusion, decay, dt, spacing)[0] < 0:
        dt = math.nextafter(dt, 0.0)
    return dt


@inlined
def _locate(v: float, origin: float, spacing: float, dims: int) -> tuple[int, float]:
    """The cell along one axis that holds v, clamped onto the grid, and where in it v is (0..1)."""
    u = (v - origin) / spacing
    top = dims - 1
    if not u > 0.0:  # also NaN: the first cell rather than a wild index
        return 0, 0.0
    if u >= top:
        return top - 1, 1.0
    k = min(math.floor(u), top - 1)
    return k, u - k


@njit(cache=True, error_model="numpy")
def release(
    grid_conc: NDArray[np.float64], origin: float, spacing: float, dims: int, species: int,
    x: float, y: float, z: float, amount: float,
) -> None:  # fmt: skip
    """Add ``amount`` (molecules, or the lattice's concentration-volume units) at (x, y, z) by
    cloud-in-cell: trilinear weights over the 8 surrounding nodes, as concentration
    amount * weight / h^3. The weights sum to 1 and their mean position is the point, so the grid
    gains exactly ``amount`` centred where it was released. A point outside the grid is clamped
    onto the boundary cell."""
    c = grid_conc[species]
    i, fx = _locate(x, origin, spacing, dims)
    j, fy = _locate(y, origin, spacing, dims)
    m, fz = _locate(z, origin, spacing, dims)
    scale = amount / (spacing * spacing * spacing)
    for di in range(2):
        wx = fx if di else 1.0 - fx
        for dj in range(2):
            wxy = wx * (fy if dj else 1.0 - fy)
            c[i + di, j + dj, m] += scale * wxy * (1.0 - fz)
            c[i + di, j + dj, m + 1] += scale * wxy * fz


@njit(cache=True, error_model="numpy")
def diffuse(
    grid_conc: NDArray[np.float64], scratch: NDArray[np.float64], spacing: float, dims: int,
    species: int, diffusion: float, decay: float, dt: float, no_flux: bool,
) -> None:  # fmt: skip
    """One explicit step of dc/dt = D lap c - k c for one species, written into ``scratch`` and
    copied back (no allocation). no_flux=True: reflecting faces, the ghost node beyond a face
    mirrors the node inside it, so the mass is conserved but for decay; False: the ghosts are 0,
    the field absorbed beyond the faces. Non-negative as long as dt <= ``stable_step``."""
    a, r = _weights(diffusion, decay, dt, spacing)
    c = grid_conc[species]
    last = dims - 1
    ghost = 1.0 if no_flux else 0.0  # a ghost's weight: mirrors the outer node, or 0
    for i in range(dims):
        im = max(i - 1, 0)
        ip = min(i + 1, last)
        wim = 1.0 if i > 0 else ghost
        wip = 1.0 if i < last else ghost
        for j in range(dims):
            jm = max(j - 1, 0)
            jp = min(j + 1, last)
            wjm = 1.0 if j > 0 else ghost
            wjp = 1.0 if j < last else ghost
            # the inner axis: its two ends apart, so the loop between them has no branch
            side = wim * c[im, j, 0] + wip * c[ip, j, 0] + wjm * c[i, jm, 0] + wjp * c[i, jp, 0]
            scratch[i, j, 0] = a * c[i, j, 0] + r * (side + ghost * c[i, j, 0] + c[i, j, 1])
            for m in range(1, last):
                scratch[i, j, m] = a * c[i, j, m] + r * (
                    wim * c[im, j, m] + wip * c[ip, j, m] + wjm * c[i, jm, m]
                    + wjp * c[i, jp, m] + c[i, j, m - 1] + c[i, j, m + 1]
                )  # fmt: skip
            side = (wim * c[im, j, last] + wip * c[ip, j, last] + wjm * c[i, jm, last]
                    + wjp * c[i, jp, last])  # fmt: skip
            scratch[i, j, last] = a * c[i, j, last] + r * (
                side + c[i, j, last - 1] + ghost * c[i, j, last]
            )
    # back node by node: no view is made, so the uncounted step may call this
    for i in range(dims):
        for j in range(dims):
            for m in range(dims):
                c[i, j, m] = scratch[i, j, m]


@njit(cache=True, error_model="numpy")
def sample(
    grid_conc: NDArray[np.float64], origin: float, spacing: float, dims: int, species: int,
    x: float, y: float, z: float,
) -> tuple[float, float, float, float]:  # fmt: skip
    """Concentration and its gradient (c, dc/dx, dc/dy, dc/dz) at (x, y, z): trilinear
    interpolation over the 8 nodes around the point, and the derivative of that interpolant,
    exact for a linear field and continuous in value across cells. Outside the grid the point is
    clamped onto the boundary, where the boundary cell's value and gradient are read."""
    c = grid_conc[species]
    i, fx = _locate(x, origin, spacing, dims)
    j, fy = _locate(y, origin, spacing, dims)
    m, fz = _locate(z, origin, spacing, dims)
    ox = 1.0 - fx
    oy = 1.0 - fy
    oz = 1.0 - fz
    # along z first: the value at (node x, node y) and the slope along z there
    v00 = c[i, j, m] * oz + c[i, j, m + 1] * fz
    v01 = c[i, j + 1, m] * oz + c[i, j + 1, m + 1] * fz
    v10 = c[i + 1, j, m] * oz + c[i + 1, j, m + 1] * fz
    v11 = c[i + 1, j + 1, m] * oz + c[i + 1, j + 1, m + 1] * fz
    s00 = c[i, j, m + 1] - c[i, j, m]
    s01 = c[i, j + 1, m + 1] - c[i, j + 1, m]
    s10 = c[i + 1, j, m + 1] - c[i + 1, j, m]
    s11 = c[i + 1, j + 1, m + 1] - c[i + 1, j + 1, m]
    v0 = v00 * oy + v01 * fy
    v1 = v10 * oy + v11 * fy
    value = v0 * ox + v1 * fx
    dx = (v1 - v0) / spacing
    dy = ((v01 - v00) * ox + (v11 - v10) * fx) / spacing
    dz = ((s00 * oy + s01 * fy) * ox + (s10 * oy + s11 * fy) * fx) / spacing
    return value, dx, dy, dz


@njit(cache=True, error_model="numpy")
def total(grid_conc: NDArray[np.float64], spacing: float, species: int) -> float:
    """The amount of one species on the grid, sum c h^3: what ``release`` adds and a reflecting
    ``diffuse`` conserves but for decay."""
    c = grid_conc[species]
    s = 0.0
    for i in range(c.shape[0]):
        for j in range(c.shape[1]):
            for m in range(c.shape[2]):
                s += c[i, j, m]
    return s * spacing * spacing * spacing


@njit(cache=True, error_model="numpy")
def is_zero(grid_conc: NDArray[np.float64], species: int) -> bool:
    """Whether a species has nothing on the grid yet, so a caller can skip its updates (a step
    from zero stays exactly zero): a read-only scan that stops at the first non-zero node, about
    a third of a ``diffuse`` on an empty grid, nothing once a node near the start holds mass."""
    c = grid_conc[species]
    for i in range(c.shape[0]):
        for j in range(c.shape[1]):
            for m in range(c.shape[2]):
                if c[i, j, m] != 0.0:
                    return False
    return True
