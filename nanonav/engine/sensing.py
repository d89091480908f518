"""What a robot perceives: the field and its gradient where it is, read with the sensor's noise
and detection threshold, and the discrete Q-learning state those readings and the distances to
obstacles and cells map to.

A room of its own because how the robots sense is the same whatever moves them; it holds no
motion and no choice. Everything here runs under numba, inlined into the compiled step.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from nanonav.engine.fields import sample_many
from nanonav.engine.qlearning import SIGN_THRESHOLD
from nanonav.engine.state import BEHAVIORS, KernelParams, Swarm, World

# Proximity cut-offs, in robot steps: an obstacle surface within 2 steps is 'near', a cell within
# 3 steps is 'near'.
OBSTACLE_NEAR_STEPS = 2.0
CELL_NEAR_STEPS = 3.0


@njit(cache=True, error_model="numpy", inline="always")
def _sense_all(p: KernelParams, w: World, s: Swarm, wanted: NDArray[np.bool_]) -> None:
    """The true field and gradient at every ``wanted`` robot, in one pass over the swarm (the
    sources' loop vectorises there, unlike inside the robot loop)."""
    sample_many(
        p.model, w.sx, w.sy, w.sz, p.weight, p.length, p.softening, s.pos, wanted,
        s.reading, s.reading_grad,
    )  # fmt: skip


@njit(cache=True, error_model="numpy", inline="always")
def _sense(p: KernelParams, rng: np.random.Generator, s: Swarm, i: int) -> tuple[float, ...]:
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


@njit(cache=True, error_model="numpy", inline="always")
def _state(
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
