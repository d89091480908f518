"""The evaluation's history: still obstacles kept once, moving ones per row."""

from typing import Any

import numpy as np

from nanonav.engine import SimulationResult, Trajectory, simulate
from nanonav.engine.simulate import CHUNK_ROBOT_STEPS, _params, _Run
from nanonav.scenario import Scenario

HISTORY = ("step", "robots", "cells", "obstacles", "concentration", "distance")


def scenario(**fields: Any) -> Scenario:
    return Scenario.model_validate(fields)


def history_bytes(t: Trajectory) -> int:
    return sum(getattr(t, name).nbytes for name in HISTORY)


def trajectory(result: SimulationResult) -> Trajectory:
    assert result.trajectory is not None
    return result.trajectory


# 40 drifting robots among obstacles; the cells drift too, so every row differs
SWARM: dict[str, Any] = {
    "seed": 3,
    "robots": {"count": 40, "policy": "q_learning"},
    "cells": {"count": 3},
    "learning": {"episodes": 2, "max_steps": 300},
}


def test_still_obstacles_are_recorded_once_as_the_worlds_obstacles() -> None:
    s = scenario(**SWARM, obstacles={"count": 25})
    run = _Run(s, _params(s))
    while run.episode <= s.learning.episodes:
        run.advance(CHUNK_ROBOT_STEPS)
    t = run.trajectory()
    assert t.obstacles.shape == (1, 25, 3)
    assert len(t.step) > 2 and t.stride == 1
    assert np.array_equal(t.obstacles[0], run.world.obstacles)
    assert not t.obstacles_move
    assert np.array_equal(t.obstacles_at(-1), run.world.obstacles)
    gaps = np.linalg.norm(t.robots[:, :, None, :] - t.obstacles[0][None, None], axis=3)
    assert gaps.min() >= s.obstacles.radius


def test_the_world_is_the_same_whether_obstacles_move_or_not() -> None:
    still = trajectory(simulate(scenario(**SWARM, obstacles={"count": 25})))
    moving = trajectory(simulate(scenario(**SWARM, obstacles={"count": 25, "motion_std": 0.2})))
    assert np.array_equal(still.obstacles[0], moving.obstacles[0])


def test_moving_obstacles_are_recorded_on_every_row() -> None:
    t = trajectory(simulate(scenario(**SWARM, obstacles={"count": 25, "motion_std": 0.2})))
    rows = len(t.step)
    assert t.obstacles.shape == (rows, 25, 3) and rows > 2
    assert t.obstacles_move
    # they drift: each recorded row differs from the one before
    assert (np.abs(np.diff(t.obstacles, axis=0)).max(axis=(1, 2)) > 0).all()
    assert np.array_equal(t.obstacles_at(-1), t.obstacles[-1])
    assert np.array_equal(t.obstacles_at(1), t.obstacles[1])


def test_a_thousand_still_obstacles_no_longer_fill_the_history() -> None:
    # 1 robot x 2,000 steps used to record 2,001 copies of 1,000 centres (48 MB)
    s = scenario(obstacles={"count": 1000}, learning={"episodes": 0, "max_steps": 2000})
    t = trajectory(simulate(s))
    assert t.obstacles.shape == (1, 1000, 3)
    assert history_bytes(t) < 200_000
