"""What robots send and receive (``communication.model``).

Chemical signals ('attractant', 'attractant_repellent'): every robot bound to a cell releases,
each solver step, into the grid of ``signals`` (species 0 the attractant; species 1 the
repellent, released instead once its cell is treated), which then diffuses and decays. A robot
reads the net signal, attractant minus repellent, and its gradient where it is, with the noise
rules it reads the biomarker with. 'broadcast': an engineered radio; a robot that reaches a cell
sends its position to every robot within range (found in a cell list as wide as the range), who
keeps the nearest message it was sent until it gets there.

A room of its own because signalling is apart from how robots move and from what they decide to
do with what they receive. Everything here runs under numba.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from nanonav.engine import signals
from nanonav.engine.compiled import inlined
from nanonav.engine.contacts import CellList, each_within
from nanonav.engine.dynamics.brownian import read_counted
from nanonav.engine.state import (
    ACTIVE_BROWNIAN,
    ATTRACTANT_REPELLENT,
    BROADCAST,
    KernelParams,
    Social,
)

ATTRACTANT_SPECIES = 0
REPELLENT_SPECIES = 1

# What a robot receives, the Q-learning state's 'signal' (qlearning.SIGNAL_STATES).
NOTHING = 0
ATTRACTANT_RISING = 1
ATTRACTANT_FALLING = 2
REPELLENT = 3
MESSAGE = 1  # broadcast: a message is waiting


@njit(cache=True, error_model="numpy")
def update_field(
    p: KernelParams, pos: NDArray[np.float64], bound_to: NDArray[np.int64],
    treated_at: NDArray[np.int64], grid: NDArray[np.float64], scratch: NDArray[np.float64],
) -> None:  # fmt: skip
    """One update of the grid (``signal_every`` engine steps, in ``signal_substeps`` solver
    steps): every bound robot releases what it releases in that time, then each species
    diffuses and decays."""
    amount = p.signal_release * p.signal_every
    released = False
    for i in range(pos.shape[0]):
        cell = bound_to[i]
        if cell < 0:
            continue
        species = ATTRACTANT_SPECIES
        if p.signal == ATTRACTANT_REPELLENT and treated_at[cell] >= 0:
            species = REPELLENT_SPECIES
        signals.release(
            grid, p.signal_origin, p.signal_spacing, p.signal_dims, species,
            pos[i, 0], pos[i, 1], pos[i, 2], amount,
        )  # fmt: skip
        released = True
    dt = p.signal_every / p.signal_substeps
    for species in range(grid.shape[0]):
        if released or not signals.is_zero(grid, species):
            for _ in range(p.signal_substeps):
                signals.diffuse(
                    grid, scratch, p.signal_spacing, p.signal_dims, species,
                    p.signal_diffusion, p.signal_decay, dt, p.walls,
                )  # fmt: skip


@inlined
def _read_lattice(p: KernelParams, rng: np.random.Generator, c: float) -> float:
    """A reading of the signal with the biomarker's noise rules (relative noise, then the
    floor); the detection threshold is applied to the net signal."""
    if p.noise > 0.0:
        c *= 1.0 + p.noise * rng.standard_normal()
    if p.noise_floor > 0.0:
        c += p.noise_floor * rng.standard_normal()
    return c


@njit(cache=True, error_model="numpy")
def receive(
    p: KernelParams, rng: np.random.Generator, grid: NDArray[np.float64],
    x: float, y: float, z: float,
) -> tuple[float, float, float, float]:  # fmt: skip
    """The net signal (attractant minus repellent) a robot at (x, y, z) reads, and its sensed
    gradient. Lattice: each species read as the biomarker is (noise, floor), the gradient with
    the gradient's noise; active Brownian: each at the Berg-Purcell limit, the gradient across
    the body."""
    net = 0.0
    gx = 0.0
    gy = 0.0
    gz = 0.0
    for species in range(grid.shape[0]):
        sign = 1.0 if species == ATTRACTANT_SPECIES else -1.0
        c, dx, dy, dz = signals.sample(
            grid, p.signal_origin, p.signal_spacing, p.signal_dims, species, x, y, z
        )
        c = max(c, 0.0)
        if p.physics == ACTIVE_BROWNIAN:
            molecules = p.signal_counting
            a = p.robot_radius
            net += sign * read_counted(rng, c, molecules * c)
            for axis in range(3):
                g = dx if axis == 0 else (dy if axis == 1 else dz)
                hi = c + a * g
                lo = max(c - a * g, 0.0)
                v = (read_counted(rng, hi, molecules * hi)
                     - read_counted(rng, lo, molecules * lo)) / (2.0 * a)  # fmt: skip
                if axis == 0:
                    gx += sign * v
                elif axis == 1:
                    gy += sign * v
                else:
                    gz += sign * v
        else:
            net += sign * _read_lattice(p, rng, c)
            gx += sign * (dx * (1.0 + p.noise * rng.standard_normal()) if p.noise > 0.0 else dx)
            gy += sign * (dy * (1.0 + p.noise * rng.standard_normal()) if p.noise > 0.0 else dy)
            gz += sign * (dz * (1.0 + p.noise * rng.standard_normal()) if p.noise > 0.0 else dz)
            if p.noise_floor > 0.0:
                gx += sign * p.gradient_noise * rng.standard_normal()
                gy += sign * p.gradient_noise * rng.standard_normal()
                gz += sign * p.gradient_noise * rng.standard_normal()
    if abs(net) <= p.signal_threshold:
        return net, 0.0, 0.0, 0.0
    return net, gx, gy, gz


@inlined
def received(p: KernelParams, net: float, prev: float) -> int:
    """The state's 'signal' of a chemical reading: nothing, an attractant rising or not, or a
    repellent."""
    if net > p.signal_threshold:
        return ATTRACTANT_RISING if net > prev else ATTRACTANT_FALLING
    if net < -p.signal_threshold:
        return REPELLENT
    return NOTHING


@njit(cache=True, error_model="numpy")
def broadcast(
    p: KernelParams, pos: NDArray[np.float64], active: NDArray[np.bool_], so: Social,
    radio: CellList, found: NDArray[np.int64], sender: int,
) -> None:  # fmt: skip
    """``sender`` reached a cell: every active robot within ``broadcast_range`` of it keeps its
    position unless it holds a nearer message."""
    x = pos[sender, 0]
    y = pos[sender, 1]
    z = pos[sender, 2]
    k = each_within(radio, pos, x, y, z, p.broadcast_range, found)
    for n in range(k):
        j = found[n]
        if j == sender or not active[j]:
            continue
        dx = x - pos[j, 0]
        dy = y - pos[j, 1]
        dz = z - pos[j, 2]
        d2 = dx * dx + dy * dy + dz * dz
        if so.has_message[j]:
            ox = so.message[j, 0] - pos[j, 0]
            oy = so.message[j, 1] - pos[j, 1]
            oz = so.message[j, 2] - pos[j, 2]
            if ox * ox + oy * oy + oz * oz <= d2:
                continue
        so.has_message[j] = True
        so.message[j, 0] = x
        so.message[j, 1] = y
        so.message[j, 2] = z


@inlined
def toward_message(
    p: KernelParams, pos: NDArray[np.float64], so: Social, i: int, arrived: float
) -> tuple[float, float, float]:
    """Robot ``i``'s way to the message it holds (zero if none), which it drops once within
    ``arrived`` of the position it was sent."""
    if not so.has_message[i]:
        return 0.0, 0.0, 0.0
    dx = so.message[i, 0] - pos[i, 0]
    dy = so.message[i, 1] - pos[i, 1]
    dz = so.message[i, 2] - pos[i, 2]
    if math.sqrt(dx * dx + dy * dy + dz * dz) <= arrived:
        so.has_message[i] = False
        return 0.0, 0.0, 0.0
    return dx, dy, dz


@njit(cache=True, error_model="numpy")
def listen(
    p: KernelParams, rng: np.random.Generator, grid: NDArray[np.float64],
    pos: NDArray[np.float64], so: Social, i: int, arrived: float,
) -> tuple[int, float, float, float]:  # fmt: skip
    """What robot ``i`` receives this step: the state's 'signal', and the way it points (up
    the net signal, or toward the message it holds, dropped within ``arrived`` of it); the
    reading is kept in ``so.signal`` (broadcast: 1 while a message waits)."""
    if p.signal == BROADCAST:
        ux, uy, uz = toward_message(p, pos, so, i, arrived)
        heard = MESSAGE if so.has_message[i] else NOTHING
        so.signal[i] = heard
        return heard, ux, uy, uz
    net, ux, uy, uz = receive(p, rng, grid, pos[i, 0], pos[i, 1], pos[i, 2])
    heard = received(p, net, so.prev_signal[i])
    so.prev_signal[i] = net
    so.signal[i] = net
    return heard, ux, uy, uz
