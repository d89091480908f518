"""The evaluation's history: still obstacles kept once, moving ones per row, a cap in bytes that
thins the rows but never changes the run."""

from typing import Any

import numpy as np
import pytest

from nanonav.engine import SimulationResult, Trajectory, simulate, without_timings
from nanonav.engine.simulation import (
    CHUNK_ROBOT_STEPS,
    DEFAULT_RECORD_BYTES,
    Run,
    fixed_history_bytes,
    history_row_bytes,
    history_rows,
    kernel_params,
    record_stride,
)
from nanonav.scenario import Scenario, ScenarioError

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
    "evaluation": {"worlds": 1},  # the world left at the end is the recorded one
}


def test_still_obstacles_are_recorded_once_as_the_worlds_obstacles() -> None:
    s = scenario(**SWARM, obstacles={"count": 25})
    run = Run(s, kernel_params(s))
    while run.episode < s.episodes:
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


def test_the_history_fits_its_byte_cap_and_ends_at_the_episodes_end() -> None:
    s = scenario(**SWARM, obstacles={"count": 25, "motion_std": 0.2})
    cap = 64 * 1024
    row = history_row_bytes(s)
    assert history_rows(s.learning.max_steps, 1) * row > cap  # every step would not fit
    result = simulate(s, record_bytes=cap)
    t = trajectory(result)
    assert history_bytes(t) <= cap
    assert t.stride > 1
    # the smallest stride that fits: one step less would not
    assert history_rows(s.learning.max_steps, t.stride - 1) * row > cap
    assert t.step[0] == 0 and t.step[-1] == result.worlds[0]["episode_steps"] == t.length
    assert (np.diff(t.step)[:-1] == t.stride).all() and 0 < t.step[-1] - t.step[-2] <= t.stride


def test_the_recording_is_allocated_within_the_cap() -> None:
    s = scenario(robots={"count": 300}, learning={"episodes": 0, "max_steps": 5000})
    cap = 1_000_000
    recording = Run(s, kernel_params(s, cap)).recording
    assert sum(a.nbytes for a in recording) <= cap
    everything = Run(s, kernel_params(s, 10**12)).recording
    assert sum(a.nbytes for a in everything) > 50 * cap


def test_a_small_cap_changes_what_is_recorded_never_the_run() -> None:
    s = scenario(**SWARM, obstacles={"count": 25, "motion_std": 0.2})
    full = simulate(s)
    thin = simulate(s, record_bytes=64 * 1024)
    assert without_timings(full.to_dict()) == without_timings(thin.to_dict())
    assert full.qtable is not None and thin.qtable is not None
    assert np.array_equal(full.qtable.values, thin.qtable.values)
    a, b = trajectory(full), trajectory(thin)
    assert a.stride == 1 and b.stride > 1
    # every kept row is the full history's row at that step
    for name in HISTORY[1:]:
        assert np.array_equal(getattr(b, name), getattr(a, name)[b.step]), name
    assert np.array_equal(a.robot_steps, b.robot_steps) and np.array_equal(a.reached, b.reached)


def test_large_swarms_get_a_strided_history_within_the_default_cap() -> None:
    s = scenario(
        robots={"count": 2000, "policy": "random"},
        learning={"episodes": 0, "max_steps": 1500},
        obstacles={"count": 0},
    )
    t = trajectory(simulate(s))
    assert t.stride > 1
    assert history_bytes(t) <= DEFAULT_RECORD_BYTES
    assert t.step[0] == 0 and t.step[-1] == 1500
    assert (np.diff(t.step) > 0).all()


def test_a_cap_that_cannot_hold_the_start_and_end_is_refused_by_field() -> None:
    swarm = scenario(robots={"count": 1000}, learning={"max_steps": 10})
    two_rows = 2 * history_row_bytes(swarm) + fixed_history_bytes(swarm)
    assert record_stride(swarm, two_rows) == 10  # the start and the end only
    with pytest.raises(ScenarioError) as error:
        simulate(swarm, record_bytes=two_rows - 1)
    assert error.value.field == "robots.count"
    drifting = scenario(obstacles={"count": 1000, "motion_std": 0.1})
    with pytest.raises(ScenarioError) as error:
        record_stride(drifting, 30_000)
    assert error.value.field == "obstacles.count"


def test_the_default_cap_holds_every_admissible_scenario() -> None:
    largest = scenario(
        space={"size": 1000},
        robots={"count": 10_000},
        cells={"count": 100},
        obstacles={"count": 1000, "motion_std": 1.0},
        learning={"max_steps": 1_000_000},
    )
    stride = record_stride(largest, DEFAULT_RECORD_BYTES)
    rows = history_rows(largest.learning.max_steps, stride)
    assert rows >= 2
    assert rows * history_row_bytes(largest) <= DEFAULT_RECORD_BYTES
