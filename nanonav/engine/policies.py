"""Choosing an action: the epsilon-greedy choice over a Q-table row, the fixed baselines
(gradient, run_and_tumble, rule, simple_rule, random), and the paper's behaviours (2.5) turned
into a direction to move along; in the active Brownian physics, the steering a robot's policy
commands of its own diffusing heading.

A room of its own because what a robot decides is apart from how the world then moves it and
from how it learns. Everything here runs under numba, inlined into the compiled step.
"""

from __future__ import annotations

import numpy as np
from numba.np.random.random_methods import buffered_bounded_lemire_uint32
from numpy.typing import NDArray

from nanonav.engine.communication import ATTRACTANT_RISING, REPELLENT
from nanonav.engine.compiled import inlined
from nanonav.engine.dynamics.brownian import turn_toward
from nanonav.engine.dynamics.lattice import random_unit, slide, unit_or_random
from nanonav.engine.qlearning import (
    APPROACH_CELL,
    AVOID_OBSTACLE,
    EXPLORE,
    FOLLOW_SIGNAL,
    KEEP_HEADING,
    STEER_TO_CELL,
    STEER_UP_GRADIENT,
    TUMBLE,
)
from nanonav.engine.state import (
    BLIND_TUMBLE,
    EXACT_GRADIENT,
    GRADIENT,
    RULE,
    RUN_AND_TUMBLE,
    SIMPLE_RULE,
    STEER_AND_TUMBLE,
    KernelParams,
    Swarm,
    World,
)

# The behaviour code of a choice that is a direction already, not one of the paper's behaviours.
NO_BEHAVIOR = -1


@inlined
def below(rng: np.random.Generator, n: int) -> int:
    """A uniform integer of 0 .. n - 1, as ``rng.integers(0, n)`` draws it (the same bits, the
    same number) without allocating, so that the uncounted step may call it; for ``n`` of 1
    it draws nothing, as ``integers`` draws nothing."""
    if n <= 1:
        return 0
    drawn = buffered_bounded_lemire_uint32(rng.bit_generator, n - 1)  # type: ignore[no-untyped-call]
    return int(np.int64(drawn))  # int() of a uint32 would type as float under numba


@inlined
def epsilon_greedy(
    epsilon: float, rng: np.random.Generator, q: NDArray[np.float64], table: int, state: int
) -> int:
    """Epsilon-greedy over one row of the table; ties among the best are broken at random."""
    actions = q.shape[2]
    if epsilon > 0.0 and rng.random() < epsilon:
        return below(rng, actions)
    best = q[table, state, 0]
    ties = 1
    for a in range(1, actions):
        v = q[table, state, a]
        if v > best:
            best = v
            ties = 1
        elif v == best:
            ties += 1
    pick = 0 if ties == 1 else below(rng, ties)
    for a in range(actions):
        if q[table, state, a] == best:
            if pick == 0:
                return a
            pick -= 1
    return 0


@inlined
def baseline_action(
    p: KernelParams, rng: np.random.Generator, heading: NDArray[np.float64], i: int,
    c: float, prev_c: float, gx: float, gy: float, gz: float, cell_d: float, heard: int,
) -> tuple[int, float, float, float, float, float, float]:  # fmt: skip
    """A fixed policy's choice for robot ``i`` from its reading ``c`` (and the last one,
    ``prev_c``), sensed gradient ``g``, distance to the nearest cell and ``heading``:
    ``(behavior, dx, dy, dz, gx, gy, gz)``. Either one of the paper's behaviours, for
    ``behavior_direction`` to turn into a move up the gradient ``g`` returned (``rule`` blanks
    it to go straight on), or ``NO_BEHAVIOR`` and the unit direction ``d`` to move along.
    ``heard``: what the robot receives (``communication``'s codes). ``rule`` follows it
    (``FOLLOW_SIGNAL``) where it senses no cell and no reading above the 'mid' level, while an
    attractant rises, from a repellent, or to a message; an attractant that no longer rises is
    a peak with no cell the robot can sense (a treated cell's, or one drifted off), and the
    rule goes on as without signals."""
    behavior = NO_BEHAVIOR
    dx = 0.0
    dy = 0.0
    dz = 0.0
    if p.policy == GRADIENT:
        behavior = AVOID_OBSTACLE  # up the gradient, round obstacles
    elif p.policy == SIMPLE_RULE:
        sensed = cell_d <= p.cell_sensing_radius and cell_d > 0.0
        behavior = APPROACH_CELL if sensed else AVOID_OBSTACLE
    elif p.policy == RULE:
        # advance on a sensed cell; on a reading above the 'mid' level, run and
        # tumble (a gradient is flat and noisy there, between cells and round a
        # field's maximum); below it, climb the gradient
        behavior = AVOID_OBSTACLE
        if cell_d <= p.cell_sensing_radius and cell_d > 0.0:
            behavior = APPROACH_CELL
        elif c > p.level_2:
            if c > prev_c:
                gx = 0.0  # no gradient to climb: straight on, round obstacles
                gy = 0.0
                gz = 0.0
            else:
                behavior = EXPLORE
        elif heard in (ATTRACTANT_RISING, REPELLENT):  # MESSAGE is ATTRACTANT_RISING
            behavior = FOLLOW_SIGNAL
    elif p.policy == RUN_AND_TUMBLE and c > prev_c:
        dx = heading[i, 0]
        dy = heading[i, 1]
        dz = heading[i, 2]
    else:
        dx, dy, dz = random_unit(rng)
    return behavior, dx, dy, dz, gx, gy, gz


@inlined
def _climb(
    p: KernelParams, rng: np.random.Generator, w: World, s: Swarm, i: int,
    px: float, py: float, pz: float, gx: float, gy: float, gz: float,
) -> tuple[float, float, float]:  # fmt: skip
    """Up the sensed gradient, sliding round obstacles; straight on where nothing is sensed."""
    if gx * gx + gy * gy + gz * gz > 0.0:
        dx, dy, dz = unit_or_random(rng, gx, gy, gz)
    else:
        dx = s.heading[i, 0]
        dy = s.heading[i, 1]
        dz = s.heading[i, 2]
    return slide(p, rng, w, px, py, pz, dx, dy, dz, p.speed)


@inlined
def behavior_direction(
    p: KernelParams,
    rng: np.random.Generator,
    w: World,
    s: Swarm,
    robot: int,
    action: int,
    px: float,
    py: float,
    pz: float,
    gx: float,
    gy: float,
    gz: float,
    cell: int,
    cell_d: float,
) -> tuple[float, float, float, float]:
    """Unit direction and step length of one of the paper's behaviours. (Arrays are indexed
    element by element here: taking row views in this hot path costs reference counting.)"""
    if action == EXPLORE:
        dx, dy, dz = random_unit(rng)
        return dx, dy, dz, p.speed
    if action == APPROACH_CELL:
        if cell_d <= p.cell_sensing_radius and cell_d > 0.0:
            return (
                (w.cells[cell, 0] - px) / cell_d,
                (w.cells[cell, 1] - py) / cell_d,
                (w.cells[cell, 2] - pz) / cell_d,
                min(p.speed, cell_d),
            )
        return s.heading[robot, 0], s.heading[robot, 1], s.heading[robot, 2], p.speed
    if action == AVOID_OBSTACLE:
        # up the gradient, and round an obstacle only if the step would run into it
        dx, dy, dz = _climb(p, rng, w, s, robot, px, py, pz, gx, gy, gz)
        return dx, dy, dz, p.speed
    if gx * gx + gy * gy + gz * gz > 0.0:
        dx, dy, dz = unit_or_random(rng, gx, gy, gz)
        return dx, dy, dz, p.speed
    return s.heading[robot, 0], s.heading[robot, 1], s.heading[robot, 2], p.speed


@inlined
def steering_baseline(p: KernelParams, rng: np.random.Generator, rising: bool) -> int:
    """A fixed active Brownian policy's steering action this step: 'uncontrolled' keeps its
    heading; 'blind_tumble' tumbles with probability 1 - exp(-rate dt) whatever it reads;
    'run_and_tumble' tumbles so, at a lower rate while the reading rises; 'steer_and_tumble'
    tumbles so too, and otherwise steers up the gradient (temporal and spatial sensing
    combined); 'gradient' and 'exact_gradient' steer up the
    gradient (the sensed one, or the true one: an upper bound no robot can have)."""
    if p.policy == BLIND_TUMBLE:
        return TUMBLE if rng.random() < p.tumble else KEEP_HEADING
    if p.policy in (RUN_AND_TUMBLE, STEER_AND_TUMBLE):
        chance = p.tumble_rising if rising else p.tumble
        if rng.random() < chance:
            return TUMBLE
        return KEEP_HEADING if p.policy == RUN_AND_TUMBLE else STEER_UP_GRADIENT
    if p.policy == GRADIENT or p.policy == EXACT_GRADIENT:
        return STEER_UP_GRADIENT
    return KEEP_HEADING


@inlined
def steer(
    p: KernelParams, rng: np.random.Generator, s: Swarm, i: int, action: int,
    gx: float, gy: float, gz: float, tx: float, ty: float, tz: float,
) -> None:  # fmt: skip
    """Turn robot ``i``'s heading as ``action`` says: up the gradient g, or toward a sensed
    cell at t, by at most ``turn`` radians this step; or tumble to a random heading."""
    hx = s.heading[i, 0]
    hy = s.heading[i, 1]
    hz = s.heading[i, 2]
    if action == STEER_UP_GRADIENT:
        hx, hy, hz = turn_toward(hx, hy, hz, gx, gy, gz, p.turn)
    elif action == STEER_TO_CELL:
        hx, hy, hz = turn_toward(hx, hy, hz, tx, ty, tz, p.turn)
    elif action == TUMBLE:
        hx, hy, hz = random_unit(rng)
    s.heading[i, 0] = hx
    s.heading[i, 1] = hy
    s.heading[i, 2] = hz
