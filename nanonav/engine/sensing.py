"""What a robot perceives: the field and its gradient where it is, read with the sensor's noise
and detection threshold (in the active Brownian physics, at the Berg-Purcell limit), and the
discrete Q-learning state those readings and the distances to obstacles and cells map to.

A room of its own because how the robots sense is the same whatever moves them; it holds no
motion and no choice. Everything here runs under numba, inlined into the compiled step.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from nanonav.engine.compiled import inlined, inlined_callable, uncounted
from nanonav.engine.dynamics import brownian
from nanonav.engine.dynamics.brownian import read_counted
from nanonav.engine.fields import sample_many
from nanonav.engine.qlearning import SIGN_THRESHOLD
from nanonav.engine.state import BEHAVIORS, KernelParams, Swarm, Treatment, World

# Proximity cut-offs, in robot steps: an obstacle surface within 2 steps is 'near', a cell within
# 3 steps is 'near'.
OBSTACLE_NEAR_STEPS = 2.0
CELL_NEAR_STEPS = 3.0
# sensor 'counted': receptor patches, each a sixth of the body's surface, facing each world
# axis's two ways (to first order the estimate's noise is the same whatever way the patches
# face, so they are not turned with the body); in ``Swarm.window_flux``, the patches' columns
# (+x, -x, +y, -y, +z, -z), then the window's steps
RECEPTOR_PATCHES = brownian.RECEPTOR_PATCHES
WINDOW_STEPS = RECEPTOR_PATCHES


@inlined
def sense_all(
    p: KernelParams, w: World, s: Swarm, tr: Treatment, wanted: NDArray[np.bool_]
) -> None:
    """The true field and gradient at every ``wanted`` robot, in one pass over the swarm (the
    sources' loop vectorises there, unlike inside the robot loop)."""
    sample_many(
        p.model, w.sx, w.sy, w.sz, p.weight, p.length, p.softening, s.pos, wanted,
        s.reading, s.reading_grad, tr.tx[: tr.treated_sources[0]], tr.ty[: tr.treated_sources[0]],
        tr.tz[: tr.treated_sources[0]], p.weight * (1.0 - p.treated_secretion),
    )  # fmt: skip


@inlined_callable
def noisy_reading(p: KernelParams, rng: np.random.Generator, s: Swarm, i: int) -> tuple[float, ...]:
    """Robot ``i``'s reading of the concentration and its gradient, with relative sensor noise."""
    c = s.reading[i]
    gx = s.reading_grad[i, 0]
    gy = s.reading_grad[i, 1]
    gz = s.reading_grad[i, 2]
    if p.noise > 0.0:
        c *= 1.0 + p.noise * rng.standard_normal()
        gx *= 1.0 + p.noise * rng.standard_normal()
        gy *= 1.0 + p.noise * rng.standard_normal()
        gz *= 1.0 + p.noise * rng.standard_normal()
    if p.noise_floor > 0.0:
        c += p.noise_floor * rng.standard_normal()
        gx += p.gradient_noise * rng.standard_normal()
        gy += p.gradient_noise * rng.standard_normal()
        gz += p.gradient_noise * rng.standard_normal()
    if p.detection_threshold > 0.0 and c < p.detection_threshold:
        return 0.0, 0.0, 0.0, 0.0  # below the threshold a robot senses nothing
    return c, gx, gy, gz


@inlined
def tabular_state(
    p: KernelParams,
    c: float,
    prev_c: float,
    gx: float,
    gy: float,
    gz: float,
    obstacle_gap: float,
    cell_d: float,
) -> int:
    """Mixed-radix state index, in the order of ``qlearning.behavior_states`` or
    ``qlearning.direction_states``."""
    near_obstacle = obstacle_gap <= OBSTACLE_NEAR_STEPS * p.speed
    if p.action_set == BEHAVIORS:
        level = int(c > p.level_1) + int(c > p.level_2) + int(c > p.level_3)
        trend = 1 if c > prev_c else 0
        obstacle = 0
        if obstacle_gap <= p.sensing_radius:
            obstacle = 2 if near_obstacle else 1
        cell = 0
        if cell_d <= p.cell_sensing_radius:
            cell = 2 if cell_d <= CELL_NEAR_STEPS * p.speed else 1
        return ((level * 2 + trend) * 3 + obstacle) * 3 + cell
    g = math.sqrt(gx * gx + gy * gy + gz * gz)
    index = 0
    for v in (gx, gy, gz):
        sign = 1
        if g > 0.0:
            if v >= SIGN_THRESHOLD * g:
                sign = 2
            elif v <= -SIGN_THRESHOLD * g:
                sign = 0
        index = index * 3 + sign
    return index * 2 + (1 if near_obstacle else 0)


@inlined
def berg_purcell_reading(p: KernelParams, rng: np.random.Generator, c: float) -> float:
    """One reading over a step of the true concentration c (nM) by a robot at the Berg-Purcell
    limit of its size: relative error 1 / sqrt(pi D_m a c dt) (``dynamics.brownian``)."""
    return read_counted(rng, c, p.counting * c)


# Below this mean a Poisson draw is found by inversion, above by transformed rejection
INVERSION_BELOW = 10.0


@uncounted
def poisson_count(rng: np.random.Generator, mean: float) -> float:
    """A Poisson draw of ``mean``. Numba's own allocates (it needs reference counting, which
    the engine is compiled without), so: by inversion, a search up the cumulative
    distribution, for a small mean; else by Hoermann's transformed rejection with squeeze
    (PTRS: W. Hoermann, Insurance Math. Econom. 12, 39 (1993)), as NumPy draws it."""
    if mean <= 0.0:
        return 0.0
    if mean < INVERSION_BELOW:
        u = rng.random()
        k = 0
        term = math.exp(-mean)
        below = term
        while u > below and k < 200:  # P(k > 200) < 1e-150 at a mean under 10
            k += 1
            term *= mean / k
            below += term
        return float(k)
    root = math.sqrt(mean)
    log_mean = math.log(mean)
    b = 0.931 + 2.53 * root
    a = -0.059 + 0.02483 * b
    inverse_alpha = 1.1239 + 1.1328 / (b - 3.4)
    v_r = 0.9277 - 3.6224 / (b - 2.0)
    while True:
        u = rng.random() - 0.5
        v = rng.random()
        u_s = 0.5 - abs(u)
        k = math.floor((2.0 * a / u_s + b) * u + mean + 0.43)
        if u_s >= 0.07 and v <= v_r:
            return float(k)
        if k < 0 or (u_s < 0.013 and v > u_s):
            continue
        accept = math.log(v) + math.log(inverse_alpha) - math.log(a / (u_s * u_s) + b)
        if accept <= -mean + k * log_mean - math.lgamma(k + 1.0):
            return float(k)


@inlined
def absorb(
    flux: NDArray[np.float64], first: int, rate: float, gradient_rate: float, c: float,
    gx: float, gy: float, gz: float, steps: float,
) -> None:  # fmt: skip
    """What six receptor patches (+x, -x, +y, -y, +z, -z) of an absorbing body take in over
    ``steps`` steps at a concentration c at its centre and a gradient g, on average, added to
    ``flux[first:first + 6]``: ``rate`` * c a patch and ``gradient_rate`` * g more toward it
    (the field to first order across the body; none where that order would give less than
    none). The biomarker's and the signals' counts both take in so."""
    for k in range(3):
        g = gx if k == 0 else (gy if k == 1 else gz)
        flux[first + 2 * k] += steps * max(rate * c + gradient_rate * g, 0.0)
        flux[first + 2 * k + 1] += steps * max(rate * c - gradient_rate * g, 0.0)


@inlined
def count_patches(
    rng: np.random.Generator, flux: NDArray[np.float64], first: int
) -> tuple[float, float, float, float]:
    """The six patches' Poisson counts of what they took in (``flux[first:first + 6]``, from
    ``absorb``): their sum, and along each axis the count ahead less the count behind."""
    total = 0.0
    dx = 0.0
    dy = 0.0
    dz = 0.0
    for k in range(3):
        ahead = poisson_count(rng, flux[first + 2 * k])
        behind = poisson_count(rng, flux[first + 2 * k + 1])
        total += ahead + behind
        if k == 0:
            dx = ahead - behind
        elif k == 1:
            dy = ahead - behind
        else:
            dz = ahead - behind
    return total, dx, dy, dz


@inlined
def take_in(p: KernelParams, s: Swarm, i: int, steps: float) -> None:
    """Robot ``i``'s receptor patches take in ``steps`` steps' molecules where it is now, on
    average (``absorb``), added to its window's."""
    absorb(
        s.window_flux[i], 0, p.patch_rate, p.patch_gradient_rate, s.reading[i],
        s.reading_grad[i, 0], s.reading_grad[i, 1], s.reading_grad[i, 2], steps,
    )  # fmt: skip
    s.window_flux[i, WINDOW_STEPS] += steps


@inlined
def count_molecules(
    p: KernelParams, rng: np.random.Generator, s: Swarm, i: int, first: bool
) -> None:
    """Robot ``i`` counts the molecules its six receptor patches took in over the window just
    past (sensor 'counted'): each patch's count is Poisson, of mean what it took in along the
    robot's path (``take_in``), so that a count is known only once its window has ended. The
    reading is the counts' sum over what the whole body takes in a window at 1 nM, the
    gradient along an axis the difference of its two patches' counts over twice a patch's
    gradient rate: a reading of 0.01 molecules is 0 99 % of the time, and turns nothing. Both
    are held (``sensed``, ``sensed_grad``) until the next count; the gradient held is the
    counts' exponential average (``gradient_weight``, from physics.gradient_memory_s) but at
    the ``first`` count. The window starts anew."""
    steps = s.window_flux[i, WINDOW_STEPS]
    total, dx, dy, dz = count_patches(rng, s.window_flux[i], 0)
    for k in range(3):
        difference = dx if k == 0 else (dy if k == 1 else dz)
        g_count = difference / (2.0 * steps * p.patch_gradient_rate)
        if first or p.gradient_weight >= 1.0:
            s.sensed_grad[i, k] = g_count
        else:
            s.sensed_grad[i, k] += p.gradient_weight * (g_count - s.sensed_grad[i, k])
    s.sensed[i] = total / (RECEPTOR_PATCHES * steps * p.patch_rate)
    s.window_flux[i, :] = 0.0


@inlined
def _across_body(p: KernelParams, rng: np.random.Generator, c: float, g: float) -> float:
    """One component of the sensed gradient: two readings at the two ends of the body along
    that axis, (read(c + a g) - read(c - a g)) / 2a, the field taken to first order across it."""
    a = p.robot_radius
    ahead = berg_purcell_reading(p, rng, c + a * g)
    behind = berg_purcell_reading(p, rng, max(c - a * g, 0.0))
    return (ahead - behind) / (2.0 * a)


@inlined
def sensed_gradient(
    p: KernelParams, rng: np.random.Generator, s: Swarm, i: int
) -> tuple[float, float, float]:
    """Robot ``i``'s spatial gradient, each component read across its body (with sensor
    'counted', the one its last count gave)."""
    if p.counted:
        return s.sensed_grad[i, 0], s.sensed_grad[i, 1], s.sensed_grad[i, 2]
    c = s.reading[i]
    return (
        _across_body(p, rng, c, s.reading_grad[i, 0]),
        _across_body(p, rng, c, s.reading_grad[i, 1]),
        _across_body(p, rng, c, s.reading_grad[i, 2]),
    )


@inlined
def steering_state(p: KernelParams, c: float, rising: bool, touching: bool, sensed: bool) -> int:
    """Mixed-radix state index, in the order of ``qlearning.steering_states``."""
    level = int(c > p.level_1) + int(c > p.level_2) + int(c > p.level_3)
    return ((level * 2 + int(rising)) * 2 + int(touching)) * 2 + int(sensed)
