"""What robots send and receive (``communication.model``).

Chemical signals ('attractant', 'attractant_repellent'): every robot bound to a cell releases,
each solver step, into the grid of ``signals`` (species 0 the attractant; species 1 the
repellent, released instead once its cell is treated), which then diffuses and decays. A robot
reads the net signal, attractant minus repellent, and its gradient where it is, as it reads the
biomarker: in the lattice with its noise rules; in the active Brownian physics with sensor
'counted', by counting each species' molecules that its six receptor patches took in over the
window just past (``sensing.absorb``, ``sensing.count_patches``), a count known at the window's
end and held until the next; with sensor 'each_step', at the Berg-Purcell limit each step.
'broadcast': an engineered radio; a robot that reaches a cell sends its position to every
robot within range (found in a cell list as wide as the range), who keeps the nearest message
it was sent until it gets there.

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
from nanonav.engine.sensing import RECEPTOR_PATCHES, absorb, count_patches
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

# sensor 'counted': ``Social.signal_flux`` holds each species' patches (``RECEPTOR_PATCHES``
# columns a species, at most two species), then the window's steps
SIGNAL_STEPS = 2 * RECEPTOR_PATCHES


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
def take_in_signal(
    p: KernelParams, grid: NDArray[np.float64], pos: NDArray[np.float64], so: Social, i: int,
    steps: float,
) -> None:  # fmt: skip
    """Robot ``i``'s receptor patches take in ``steps`` steps' molecules of each species where
    it is now, on average, added to its window's."""
    for species in range(grid.shape[0]):
        c, dx, dy, dz = signals.sample(
            grid, p.signal_origin, p.signal_spacing, p.signal_dims, species,
            pos[i, 0], pos[i, 1], pos[i, 2],
        )  # fmt: skip
        absorb(
            so.signal_flux[i], species * RECEPTOR_PATCHES, p.signal_patch_rate,
            p.signal_patch_gradient_rate, max(c, 0.0), dx, dy, dz, steps,
        )  # fmt: skip
    so.signal_flux[i, SIGNAL_STEPS] += steps


@inlined
def count_signal(
    p: KernelParams, rng: np.random.Generator, species_count: int, so: Social, i: int
) -> None:
    """Robot ``i`` counts the molecules of each species that its patches took in over the
    window just past: the net signal is the attractant's counts less the repellent's, each over
    what the body takes in a window at 1 nM; its gradient, their patches' differences over
    twice a patch's gradient rate. The last count becomes ``prev_signal``; the window starts
    anew."""
    steps = so.signal_flux[i, SIGNAL_STEPS]
    net = 0.0
    gx = 0.0
    gy = 0.0
    gz = 0.0
    for species in range(species_count):
        sign = 1.0 if species == ATTRACTANT_SPECIES else -1.0
        total, dx, dy, dz = count_patches(rng, so.signal_flux[i], species * RECEPTOR_PATCHES)
        net += sign * total / (RECEPTOR_PATCHES * steps * p.signal_patch_rate)
        across = sign / (2.0 * steps * p.signal_patch_gradient_rate)
        gx += dx * across
        gy += dy * across
        gz += dz * across
    so.prev_signal[i] = so.signal[i]
    so.signal[i] = net
    so.signal_grad[i, 0] = gx
    so.signal_grad[i, 1] = gy
    so.signal_grad[i, 2] = gz
    so.signal_flux[i, :] = 0.0


@inlined
def counted_signal(
    p: KernelParams, rng: np.random.Generator, grid: NDArray[np.float64],
    pos: NDArray[np.float64], so: Social, i: int,
) -> tuple[float, float, float, float]:  # fmt: skip
    """Robot ``i``'s net signal and its gradient with sensor 'counted': a count in the steps
    that end a window, held between (a robot starts having counted a window where it starts),
    then this step's molecules taken in for the next."""
    if so.signal_flux[i, SIGNAL_STEPS] == 0.0:
        take_in_signal(p, grid, pos, so, i, float(p.window))
    if so.signal_flux[i, SIGNAL_STEPS] >= p.window:
        count_signal(p, rng, grid.shape[0], so, i)
    take_in_signal(p, grid, pos, so, i, 1.0)
    net = so.signal[i]
    if abs(net) <= p.signal_threshold:
        return net, 0.0, 0.0, 0.0
    return net, so.signal_grad[i, 0], so.signal_grad[i, 1], so.signal_grad[i, 2]


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
    reading is kept in ``so.signal``, the one before in ``so.prev_signal`` (broadcast: 1 while
    a message waits)."""
    if p.signal == BROADCAST:
        ux, uy, uz = toward_message(p, pos, so, i, arrived)
        heard = MESSAGE if so.has_message[i] else NOTHING
        so.signal[i] = heard
        return heard, ux, uy, uz
    if p.counted:
        net, ux, uy, uz = counted_signal(p, rng, grid, pos, so, i)
    else:
        net, ux, uy, uz = receive(p, rng, grid, pos[i, 0], pos[i, 1], pos[i, 2])
        so.prev_signal[i] = so.signal[i]
        so.signal[i] = net
    return received(p, net, so.prev_signal[i]), ux, uy, uz
