"""A fresh world for each episode: cells, robot starts, obstacles and emitters, drawn at random.

Worlds come from a generator of their own, in a fixed order, and how many numbers a world takes
depends on the scenario alone: the same seed gives the same sequence of worlds whatever the
policy, so methods compared on the same seeds face the same worlds.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from nanonav.engine.compiled import episodic, inlined
from nanonav.engine.contacts import CellList, first_within, relist
from nanonav.engine.state import KernelParams, Swarm, World
from nanonav.scenario import Scenario, ScenarioError

# Robots start within this share of the half-width (unless in the corner octant).
ROBOT_EXTENT = 0.95
PLACEMENT_ATTEMPTS = 10_000
NO_ROOM_FOR_ROBOTS = -1
NO_ROOM_TO_START_APART = -2  # robots that take up space found no free start


WORLD_STREAM = 0
DYNAMICS_STREAM = 1
EVALUATION_STREAM = 2  # the evaluation's worlds: the same for every policy run with a seed
TRAINING_STREAM = 3  # a trainer's worlds in a job: apart from every seed's evaluation worlds


def stream(seed: int, which: int, *more: int) -> np.random.Generator:
    """One of a seed's independent generators: ``WORLD_STREAM`` draws nothing but the worlds, so
    the same seed gives the same world for each episode whatever happens in the episodes.
    ``more`` names further independent ones within ``which`` (one per world of a batch)."""
    key = (which, *more)
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=key)))


@inlined
def _uniform(rng: np.random.Generator, out: NDArray[np.float64], low: float, high: float) -> None:
    for k in range(out.shape[0]):
        out[k] = low + (high - low) * rng.random()


@inlined
def _clear(point: NDArray[np.float64], others: NDArray[np.float64], distance: float) -> bool:
    for j in range(others.shape[0]):
        d2 = 0.0
        for a in range(3):
            d = point[a] - others[j, a]
            d2 += d * d
        if d2 < distance * distance:
            return False
    return True


@episodic
def draw_world(  # noqa: C901  # the order of its draws is the seed's contract: kept in one
    p: KernelParams, rng: np.random.Generator, w: World, s: Swarm, near: CellList,
    everyone: NDArray[np.bool_],
) -> int:  # fmt: skip
    """Draw cells, robot starts and headings, obstacles clear of both, and emitter offsets, in
    place; with exclusion, robots start apart, listed in ``near`` as they are placed. Returns
    0; ``NO_ROOM_FOR_ROBOTS``; or 1 + the index of an obstacle with no room."""
    half = p.half
    for j in range(w.cells.shape[0]):
        _uniform(rng, w.cells[j], -p.cell_extent * half, p.cell_extent * half)
    if p.exclusion:
        near.heads[:] = -1
        near.cell[:] = -1
        near.next[:] = -1
    for i in range(s.pos.shape[0]):
        for attempt in range(PLACEMENT_ATTEMPTS + 1):
            if attempt == PLACEMENT_ATTEMPTS:
                return NO_ROOM_TO_START_APART if p.exclusion else NO_ROOM_FOR_ROBOTS
            if p.robot_corner:
                _uniform(rng, s.pos[i], -half, -0.5 * half)
            else:
                _uniform(rng, s.pos[i], -ROBOT_EXTENT * half, ROBOT_EXTENT * half)
            if _clear(s.pos[i], w.cells, 2.0 * p.reach_distance) and (
                not p.exclusion
                or first_within(
                    near, s.pos, everyone, s.pos[i, 0], s.pos[i, 1], s.pos[i, 2], p.contact, i
                )
                < 0
            ):
                break
        if p.exclusion:
            relist(near, i, s.pos[i, 0], s.pos[i, 1], s.pos[i, 2])
        n = 0.0
        while n < 1e-12:
            for a in range(3):
                s.heading[i, a] = rng.standard_normal()
            n = math.sqrt(s.heading[i, 0] ** 2 + s.heading[i, 1] ** 2 + s.heading[i, 2] ** 2)
        for a in range(3):
            s.heading[i, a] /= n
            s.start[i, a] = s.pos[i, a]
    # cells keep a robot's step plus the reach distance free around them, so they stay reachable
    cell_clearance = p.obstacle_radius + p.reach_distance + p.speed
    for k in range(w.obstacles.shape[0]):
        for attempt in range(PLACEMENT_ATTEMPTS + 1):
            if attempt == PLACEMENT_ATTEMPTS:
                return k + 1
            _uniform(rng, w.obstacles[k], -half + p.obstacle_radius, half - p.obstacle_radius)
            # robots start at least one step clear of every obstacle's surface
            if _clear(w.obstacles[k], w.cells, cell_clearance) and _clear(
                w.obstacles[k], s.pos, p.obstacle_radius + p.speed
            ):
                break
    for k in range(w.offsets.shape[0]):
        for a in range(3):
            w.offsets[k, a] = p.emitter_scatter * rng.standard_normal()
    return 0


def raise_for_layout(status: int, scenario: Scenario) -> None:
    """Turn ``draw_world``'s status into the error a user can act on."""
    if status == NO_ROOM_TO_START_APART:
        raise ScenarioError(
            "robots.count",
            f"no room for {scenario.robots.count} robots that take up space to start apart and "
            "out of reach of the cells; use fewer or smaller robots, or a larger space",
        )
    if status == NO_ROOM_FOR_ROBOTS:
        raise ScenarioError("reach_distance", "no room for the robots to start out of reach")
    if status > 0:
        raise ScenarioError(
            "obstacles.count",
            f"could not place obstacle {status} of {scenario.obstacles.count} clear of the "
            "cells and robot starts; use fewer or smaller obstacles, or fewer robots",
        )
