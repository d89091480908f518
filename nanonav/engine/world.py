"""A fresh world for each episode: cells, robot starts, obstacles and emitters, drawn at random.

Everything is drawn in a fixed order from the episode's own world generator, so the same seed
and episode give the same world whatever the policy or field model: methods compared on the same
seeds face the same worlds.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from nanonav.scenario import Scenario, ScenarioError

# Cells start within this fraction of the half-width, robots within the next.
CELL_EXTENT = 0.8
ROBOT_EXTENT = 0.95
PLACEMENT_ROUNDS = 200
CANDIDATES_PER_ROUND = 64


class Layout(NamedTuple):
    """Initial positions of one episode."""

    cells: NDArray[np.float64]  # (C, 3)
    robots: NDArray[np.float64]  # (N, 3)
    headings: NDArray[np.float64]  # (N, 3) unit vectors
    obstacles: NDArray[np.float64]  # (O, 3)
    emitter_offsets: NDArray[np.float64]  # (C, E, 3); E = 0 unless inverse-square


def episode_generators(seed: int, episode: int) -> tuple[np.random.Generator, np.random.Generator]:
    """Independent (world, dynamics) generators of one episode of one seed."""
    world = np.random.Generator(
        np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(episode, 0)))
    )
    dynamics = np.random.Generator(
        np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(episode, 1)))
    )
    return world, dynamics


def _pairwise_clear(
    points: NDArray[np.float64], others: NDArray[np.float64], distance: float
) -> NDArray[np.bool_]:
    if others.shape[0] == 0:
        return np.ones(points.shape[0], dtype=bool)
    d2 = ((points[:, None, :] - others[None, :, :]) ** 2).sum(axis=2)
    return np.asarray((d2 >= distance * distance).all(axis=1))


def _unit(v: NDArray[np.float64]) -> NDArray[np.float64]:
    n = np.linalg.norm(v, axis=1, keepdims=True)
    n[n == 0] = 1.0
    unit: NDArray[np.float64] = v / n
    return unit


def draw_layout(scenario: Scenario, rng: np.random.Generator) -> Layout:
    """Draw an episode's starting world; raises ScenarioError if obstacles cannot be placed."""
    half = scenario.space.size / 2
    n_cells = scenario.cells.count
    n_robots = scenario.robots.count
    reach = scenario.reach_distance
    cells = rng.uniform(-CELL_EXTENT * half, CELL_EXTENT * half, (n_cells, 3))

    robots = rng.uniform(-ROBOT_EXTENT * half, ROBOT_EXTENT * half, (n_robots, 3))
    for _ in range(PLACEMENT_ROUNDS):
        close = ~_pairwise_clear(robots, cells, 2 * reach)
        if not close.any():
            break
        robots[close] = rng.uniform(
            -ROBOT_EXTENT * half, ROBOT_EXTENT * half, (int(close.sum()), 3)
        )
    else:
        raise ScenarioError("reach_distance", "no room for the robots to start out of reach")
    headings = _unit(rng.standard_normal((n_robots, 3)))

    radius = scenario.obstacles.radius
    obstacles = np.empty((scenario.obstacles.count, 3))
    for k in range(scenario.obstacles.count):
        for _ in range(PLACEMENT_ROUNDS):
            candidates = rng.uniform(-half + radius, half - radius, (CANDIDATES_PER_ROUND, 3))
            ok = _pairwise_clear(candidates, cells, radius + reach + scenario.robots.speed)
            ok &= _pairwise_clear(candidates, robots, radius)
            hits = np.flatnonzero(ok)
            if hits.size:
                obstacles[k] = candidates[hits[0]]
                break
        else:
            raise ScenarioError(
                "obstacles.count",
                f"could not place obstacle {k + 1} of {scenario.obstacles.count} clear of the "
                "cells and robot starts; use fewer or smaller obstacles, or fewer robots",
            )

    per_cell = (
        scenario.biomarker.emitters_per_cell if scenario.biomarker.model == "inverse_square" else 0
    )
    offsets = rng.normal(0.0, scenario.biomarker.emitter_scatter, (n_cells, per_cell, 3))
    return Layout(cells, robots, headings, obstacles, offsets)
