"""Biomarker concentration fields and their analytic gradients (paper 2.1, 2.2, 2.6).

A field is a sum over point sources: the cells themselves for the Gaussian and diffusion models,
the emitters scattered around each cell for the inverse-square model. ``sample`` is the one
implementation of the physics; the simulation kernel calls it per robot and ``field_and_gradient``
calls it over arrays of points (heatmaps, tests).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from nanonav.engine.compiled import inlined, inlined_callable
from nanonav.scenario import MOLECULES_PER_UM3_PER_NM, Biomarker, Scenario

GAUSSIAN = 0
INVERSE_SQUARE = 1
DIFFUSION = 2
SAMPLED_GAUSSIAN = 3
MODEL_CODES = {"gaussian": GAUSSIAN, "inverse_square": INVERSE_SQUARE, "diffusion": DIFFUSION,
               "sampled_gaussian": SAMPLED_GAUSSIAN}  # fmt: skip
# Models whose sources are emitters around each cell, not the cells themselves.
EMITTER_MODELS = ("inverse_square", "sampled_gaussian")

# No "reassoc": the sum over sources keeps the order ``sample`` writes (four lanes), so that a
# field is the same bits on every processor. Reassociated, the compiler took the sum's order
# from the processor's vector width, and a machine with AVX-512 computed other fields, and so
# other runs, than one with AVX2.
FASTMATH = {"contract", "nsz", "arcp"}
# The lanes ``sample`` sums sources in: partial sums a vector unit adds side by side.
LANES = 4


@njit(cache=True, error_model="numpy", inline="always")
def _term(
    model: int, dx: float, dy: float, dz: float, weight: float, scale: float, eps2: float
) -> tuple[float, float, float, float]:
    """One source's concentration and gradient at offset (dx, dy, dz) from it; ``scale`` is
    1 / sigma^2 (Gaussian) or 1 / lambda (diffusion)."""
    if model in (GAUSSIAN, SAMPLED_GAUSSIAN):
        # eq. 2.1: rho = rho0 exp(-r^2 / 2 sigma^2); eq. 2.2: d rho/dx = -(x - x0)/sigma^2 rho
        e = weight * math.exp(-0.5 * (dx * dx + dy * dy + dz * dz) * scale)
        return e, -(dx * scale * e), -(dy * scale * e), -(dz * scale * e)
    if model == INVERSE_SQUARE:
        # eq. 2.6: C = sum B / d^2, softened to B / (d^2 + eps^2); dC/dx = -2 B (x - xi) / s^2
        inv = 1.0 / (dx * dx + dy * dy + dz * dz + eps2)
        e = weight * inv
        f = -2.0 * e * inv
    else:
        # steady diffusion with first-order decay: C = Q exp(-r/lambda) / (4 pi D r),
        # r softened to rs = sqrt(r^2 + eps^2); dC/drs = -C (1/lambda + 1/rs); drs/dx = dx/rs
        rs = math.sqrt(dx * dx + dy * dy + dz * dz + eps2)
        inv_r = 1.0 / rs
        e = weight * math.exp(-rs * scale) * inv_r
        f = -e * (scale + inv_r) * inv_r
    return e, f * dx, f * dy, f * dz


@njit(cache=True, error_model="numpy", inline="always")
def _plus(
    lane: tuple[float, float, float, float],
    field: tuple[int, float, float, float],
    sx: NDArray[np.float64],
    sy: NDArray[np.float64],
    sz: NDArray[np.float64],
    k: int,
    x: float,
    y: float,
    z: float,
) -> tuple[float, float, float, float]:
    """A lane's sums (concentration, gradient) with source k's term at (x, y, z) added;
    ``field`` is (model, weight, scale, eps2) as ``_term`` takes them."""
    model, weight, scale, eps2 = field
    e, fx, fy, fz = _term(model, x - sx[k], y - sy[k], z - sz[k], weight, scale, eps2)
    return lane[0] + e, lane[1] + fx, lane[2] + fy, lane[3] + fz


@njit(cache=True, error_model="numpy", inline="always")
def sample(
    model: int,
    sx: NDArray[np.float64],
    sy: NDArray[np.float64],
    sz: NDArray[np.float64],
    weight: float,
    length: float,
    softening: float,
    x: float,
    y: float,
    z: float,
) -> tuple[float, float, float, float]:
    """Concentration and gradient at (x, y, z) of sources at (sx, sy, sz), each of strength
    ``weight``; ``length`` is sigma (Gaussian) or lambda (diffusion). Source k is summed into
    lane k % LANES while whole rounds of lanes last, the rest into the first, and the lanes
    are added at the end: one order on every processor, whose vector unit adds the lanes side
    by side (with fewer sources than lanes, the order of the sources)."""
    eps2 = softening * softening
    scale = 1.0 / (length * length) if model in (GAUSSIAN, SAMPLED_GAUSSIAN) else 1.0 / length
    field = (model, weight, scale, eps2)
    lane0 = lane1 = lane2 = lane3 = (0.0, 0.0, 0.0, 0.0)
    n = sx.shape[0]
    rounds = n // LANES * LANES
    for k in range(0, rounds, LANES):
        lane0 = _plus(lane0, field, sx, sy, sz, k, x, y, z)
        lane1 = _plus(lane1, field, sx, sy, sz, k + 1, x, y, z)
        lane2 = _plus(lane2, field, sx, sy, sz, k + 2, x, y, z)
        lane3 = _plus(lane3, field, sx, sy, sz, k + 3, x, y, z)
    for k in range(rounds, n):
        lane0 = _plus(lane0, field, sx, sy, sz, k, x, y, z)
    return (
        lane0[0] + lane1[0] + lane2[0] + lane3[0],
        lane0[1] + lane1[1] + lane2[1] + lane3[1],
        lane0[2] + lane1[2] + lane2[2] + lane3[2],
        lane0[3] + lane1[3] + lane2[3] + lane3[3],
    )


@inlined_callable
def place_sources(
    model: int,
    cells: NDArray[np.float64],
    offsets: NDArray[np.float64],
    sx: NDArray[np.float64],
    sy: NDArray[np.float64],
    sz: NDArray[np.float64],
) -> None:
    """Write the source positions for the cells' current positions: the cells themselves, or
    the emitters around them, which move with them."""
    if model in (INVERSE_SQUARE, SAMPLED_GAUSSIAN):
        per_cell = offsets.shape[0] // cells.shape[0]
        for k in range(offsets.shape[0]):
            j = k // per_cell
            sx[k] = cells[j, 0] + offsets[k, 0]
            sy[k] = cells[j, 1] + offsets[k, 1]
            sz[k] = cells[j, 2] + offsets[k, 2]
    else:
        for j in range(cells.shape[0]):
            sx[j] = cells[j, 0]
            sy[j] = cells[j, 1]
            sz[j] = cells[j, 2]


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def sample_many(
    model: int,
    sx: NDArray[np.float64],
    sy: NDArray[np.float64],
    sz: NDArray[np.float64],
    weight: float,
    length: float,
    softening: float,
    points: NDArray[np.float64],
    wanted: NDArray[np.bool_],
    conc: NDArray[np.float64],
    grad: NDArray[np.float64],
    tx: NDArray[np.float64],
    ty: NDArray[np.float64],
    tz: NDArray[np.float64],
    treated_weight: float,
) -> None:
    """``sample`` at every point whose ``wanted`` flag is set, into ``conc`` and ``grad``. The
    sources of treated cells, at (tx, ty, tz), shed less: ``treated_weight`` (their lost share
    of ``weight``) of their field is taken off again. Taken off rather than weighted in the
    sum, so the sum over all sources stays the one loop it was (and its vectorised order)."""
    for p in range(points.shape[0]):
        if not wanted[p]:
            continue
        x = points[p, 0]
        y = points[p, 1]
        z = points[p, 2]
        c, gx, gy, gz = sample(model, sx, sy, sz, weight, length, softening, x, y, z)
        if tx.shape[0]:
            oc, ox, oy, oz = sample(model, tx, ty, tz, treated_weight, length, softening, x, y, z)
            c = max(c - oc, 0.0)
            gx -= ox
            gy -= oy
            gz -= oz
        conc[p] = c
        grad[p, 0] = gx
        grad[p, 1] = gy
        grad[p, 2] = gz


# No treated cell's sources (for ``sample_many``'s callers outside the kernel).
_NONE_TREATED = (np.zeros(0), np.zeros(0), np.zeros(0))

# In the active Brownian physics the field is read outside the cells only (a robot stops at a
# cell's surface), so the diffusion model's softening, um, only keeps r = 0 finite.
PHYSICAL_SOFTENING_UM = 1e-3


def biomarker_of(scenario: Scenario) -> Biomarker:
    """The field the engine computes. In the lattice physics, the scenario's ``biomarker``; in
    the active Brownian physics, the steady state of what each cell secretes at rate Q
    (molecules/s), diffusing with D_m (um^2/s) and decaying at k (1/s): c = Q exp(-r/lambda) /
    (4 pi D_m r), lambda = sqrt(D_m / k), in nM: the diffusion model with peak = Q / (4 pi D_m)
    (nM um)."""
    if scenario.physics.model != "active_brownian":
        return scenario.biomarker
    ph = scenario.physics
    peak = ph.secretion_molecules_s / (4 * math.pi * ph.molecule_diffusion_um2_s)
    return Biomarker.model_construct(
        **{
            **scenario.biomarker.model_dump(),
            "model": "diffusion",
            "peak": peak / MOLECULES_PER_UM3_PER_NM,
            "decay_length": math.sqrt(ph.molecule_diffusion_um2_s / ph.decay_rate_s),
            "softening": PHYSICAL_SOFTENING_UM,
        }
    )


def source_weight(biomarker: Biomarker) -> float:
    """Strength of one source: the whole peak per cell, or an equal share per emitter."""
    if biomarker.model in EMITTER_MODELS:
        return biomarker.peak / biomarker.emitters_per_cell
    return biomarker.peak


def length_scale(biomarker: Biomarker) -> float:
    """sigma for the Gaussian models, lambda for diffusion (unused by inverse-square)."""
    if biomarker.model in ("gaussian", "sampled_gaussian"):
        return biomarker.spread
    return biomarker.decay_length


def source_count(biomarker: Biomarker, cells: int) -> int:
    """How many point sources ``cells`` cells give."""
    return cells * biomarker.emitters_per_cell if biomarker.model in EMITTER_MODELS else cells


@inlined
def place_treated(
    model: int, cells: NDArray[np.float64], offsets: NDArray[np.float64],
    treated_at: NDArray[np.int64], tx: NDArray[np.float64], ty: NDArray[np.float64],
    tz: NDArray[np.float64],
) -> int:  # fmt: skip
    """Write the sources of the treated cells into (tx, ty, tz) as ``place_sources`` places
    every cell's; returns how many there are."""
    emitters = model in (INVERSE_SQUARE, SAMPLED_GAUSSIAN)
    per_cell = offsets.shape[0] // cells.shape[0] if emitters else 1
    k = 0
    for j in range(cells.shape[0]):
        if treated_at[j] < 0:
            continue
        for e in range(per_cell):
            ox = offsets[j * per_cell + e, 0] if emitters else 0.0
            oy = offsets[j * per_cell + e, 1] if emitters else 0.0
            oz = offsets[j * per_cell + e, 2] if emitters else 0.0
            tx[k] = cells[j, 0] + ox
            ty[k] = cells[j, 1] + oy
            tz[k] = cells[j, 2] + oz
            k += 1
    return k


def field_and_gradient(
    biomarker: Biomarker,
    cells: NDArray[np.float64],
    emitter_offsets: NDArray[np.float64],
    points: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The exact (noise-free) concentration ``(P,)`` and gradient ``(P, 3)`` at ``points``.

    ``cells`` is ``(C, 3)``; ``emitter_offsets`` is ``(C, E, 3)`` and used by the inverse-square
    model only.
    """
    cells = np.ascontiguousarray(cells, dtype=np.float64).reshape(-1, 3)
    points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    offsets = np.ascontiguousarray(emitter_offsets, dtype=np.float64).reshape(-1, 3)
    model = MODEL_CODES[biomarker.model]
    n = source_count(biomarker, cells.shape[0])
    if model in (INVERSE_SQUARE, SAMPLED_GAUSSIAN) and offsets.shape[0] != n:
        raise ValueError(f"expected {n} emitter offsets, got {offsets.shape[0]}")
    sx, sy, sz = np.empty(n), np.empty(n), np.empty(n)
    place_sources(model, cells, offsets, sx, sy, sz)
    conc = np.empty(points.shape[0])
    grad = np.empty((points.shape[0], 3))
    sample_many(
        model,
        sx,
        sy,
        sz,
        source_weight(biomarker),
        length_scale(biomarker),
        biomarker.softening,
        points,
        np.ones(points.shape[0], dtype=np.bool_),
        conc,
        grad,
        *_NONE_TREATED,
        0.0,
    )
    return conc, grad


def radial_profile(biomarker: Biomarker, distances: NDArray[np.float64]) -> NDArray[np.float64]:
    """Concentration at ``distances`` from one lone cell whose emitters sit at its centre: the
    reference the robots' concentration levels are cut from."""
    points = np.zeros((len(distances), 3))
    points[:, 0] = distances
    model = MODEL_CODES[biomarker.model]
    one = np.zeros(1)
    conc = np.empty(len(distances))
    grad = np.empty((len(distances), 3))
    sample_many(
        model,
        one,
        one,
        one,
        biomarker.peak,
        length_scale(biomarker),
        biomarker.softening,
        points,
        np.ones(len(distances), dtype=np.bool_),
        conc,
        grad,
        *_NONE_TREATED,
        0.0,
    )
    return conc
