"""Honest sensing (noise floor, detection threshold, the cell sensor's own range), fair
baselines (slide round obstacles, the rule policy), moves checked along their whole segment,
starts clear of obstacles, the step cost and the presets' worlds."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from nanonav.engine import qlearning, sensing, simulate
from nanonav.engine.result import without_timings
from nanonav.engine.simulation import Run, kernel_params
from nanonav.scenario import Scenario, preset_scenario


def scenario(**fields: Any) -> Scenario:
    return Scenario.model_validate(fields)


def segment_clearance(a: np.ndarray, b: np.ndarray, centres: np.ndarray) -> float:
    """Least distance from the segment a-b to any of ``centres``."""
    u = b - a
    length2 = float(u @ u)
    c = centres - a
    f = np.clip((c @ u) / length2, 0.0, 1.0) if length2 > 0 else np.zeros(len(centres))
    return float(np.linalg.norm(c - f[:, None] * u, axis=1).min())


def test_each_sensed_gradient_component_carries_the_noise_of_two_readings_a_baseline_apart() -> (
    None
):
    # (c(x + b) + e1 - c(x) - e2) / b, with e1 and e2 N(0, floor^2): sd sqrt(2) * floor / b
    floor, baseline = 0.02, 0.25
    s = scenario(biomarker={"noise_floor": floor}, robots={"sensor_baseline": baseline})
    run = Run(s, kernel_params(s))
    run.swarm.reading[0] = 1.0  # above any threshold; the true gradient is 0
    rng = np.random.default_rng(11)
    samples = np.array(
        [sensing.noisy_reading(run.params, rng, run.swarm, 0) for _ in range(20_000)]
    )
    expected = math.sqrt(2.0) * floor / baseline
    # the sample sd of n normal draws has a relative standard error of 1 / sqrt(2 (n - 1))
    tolerance = 4.0 / math.sqrt(2.0 * (len(samples) - 1))
    for component in (1, 2, 3):
        assert np.std(samples[:, component]) == pytest.approx(expected, rel=tolerance)
    assert np.std(samples[:, 0]) == pytest.approx(floor, rel=tolerance)


def test_below_the_detection_threshold_a_robot_senses_nothing_and_keeps_its_heading() -> None:
    blind = scenario(
        seed=1, space={"size": 200}, obstacles={"count": 0}, cells={"motion_std": 0.0},
        biomarker={"detection_threshold": 2.0},  # above the field's peak: never sensed
        robots={"policy": "gradient", "count": 2},
        learning={"episodes": 0, "max_steps": 20}, evaluation={"worlds": 1},
    )  # fmt: skip
    t = simulate(blind).trajectory
    assert t is not None
    moves = np.diff(t.robots, axis=0)
    for robot in range(2):
        directions = moves[:, robot] / np.linalg.norm(moves[:, robot], axis=1, keepdims=True)
        assert np.allclose(directions, directions[0], atol=1e-12)  # straight on: nothing to climb


def test_the_simple_rule_is_gradient_climbing_when_cells_cannot_be_sensed() -> None:
    world = {"preset": "paper-swarm", "seed": 3, "learning": {"episodes": 0, "max_steps": 200},
             "evaluation": {"worlds": 2}}  # fmt: skip
    simple = {"policy": "simple_rule", "cell_sensing_radius": 0.0}
    rule = simulate(scenario(**world, robots=simple))
    gradient = simulate(scenario(**world, robots={"policy": "gradient"}))
    assert without_timings(rule.worlds) == without_timings(gradient.worlds)
    sensing = simulate(scenario(**world, robots={"policy": "simple_rule"}))
    assert sensing.summary["success_rate"] > gradient.summary["success_rate"]


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_rule_runs_and_tumbles_above_the_mid_level_and_climbs_below(seed: int) -> None:
    # one still cell, exact readings, no cell sensor: a reading is a function of the distance
    # alone, and every move can be checked against what the rule says for its reading
    s = scenario(
        seed=seed, robots={"count": 1, "policy": "rule", "cell_sensing_radius": 0.0},
        cells={"count": 1, "motion_std": 0.0}, obstacles={"count": 0},
        biomarker={"sensor_noise": 0.0, "noise_floor": 0.0, "detection_threshold": 0.0},
        learning={"episodes": 0, "max_steps": 400}, evaluation={"worlds": 1},
        reach_distance=0.01,  # so that it passes the cell and tumbles
    )  # fmt: skip
    mid = kernel_params(s).level_2
    t = simulate(s).trajectory
    assert t is not None and t.stride == 1
    rows = int(t.robot_steps[0]) + 1
    path, reading, cell = t.robots[:rows, 0], t.concentration[:rows, 0], t.cells[0, 0]
    moves = np.diff(path, axis=0)
    units = moves / np.linalg.norm(moves, axis=1, keepdims=True)
    kept = off_gradient = tumbled = climbed = 0
    for k in range(1, len(moves)):  # move k starts at row k, on reading k (the last: k - 1)
        if np.abs(path[k + 1]).max() >= s.space.size / 2 - 1e-9:
            continue  # a wall reflected this move
        toward = (cell - path[k]) / np.linalg.norm(cell - path[k])
        up = np.allclose(units[k], toward, atol=1e-6)
        if reading[k] > mid and reading[k] > reading[k - 1]:
            assert np.allclose(units[k], units[k - 1], atol=1e-9), k  # rising: straight on
            kept += 1
            off_gradient += not up
        elif reading[k] > mid:
            assert not np.allclose(units[k], units[k - 1], atol=1e-3), k  # a new heading,
            assert not up, k  # at random, not up the gradient
            tumbled += 1
        else:
            assert np.allclose(units[k], toward, atol=1e-9), k  # up the gradient
            climbed += 1
    # straight on is not climbing: after a tumble the robot keeps a heading off the gradient
    assert off_gradient and tumbled and climbed, (kept, off_gradient, tumbled, climbed)


def test_moves_never_pass_through_an_obstacle_and_start_a_step_clear() -> None:
    # fast robots among small obstacles: an end-point check alone would let them tunnel
    s = scenario(
        seed=5, obstacles={"count": 60, "radius": 0.6}, robots={"count": 20, "speed": 2.0,
        "policy": "random"}, learning={"episodes": 0, "max_steps": 150},
        evaluation={"worlds": 1},
    )  # fmt: skip
    t = simulate(s).trajectory
    assert t is not None
    centres = t.obstacles[0]
    starts = np.linalg.norm(t.robots[0][:, None] - centres[None], axis=2)
    assert starts.min() >= s.obstacles.radius + s.robots.speed
    for row in range(len(t.step) - 1):
        for robot in range(s.robots.count):
            a, b = t.robots[row, robot], t.robots[row + 1, robot]
            if np.array_equal(a, b):
                continue
            assert segment_clearance(a, b, centres) >= s.obstacles.radius - 1e-9


def test_gradient_slides_round_obstacles_instead_of_pushing_into_them() -> None:
    crowded = {"preset": "paper-swarm", "obstacles": {"count": 80}, "robots":
               {"policy": "gradient"}, "learning": {"episodes": 0}, "evaluation":
               {"worlds": 5}}  # fmt: skip
    climbers = simulate(scenario(**crowded, seed=2)).summary
    walkers = simulate(scenario(**{**crowded, "robots": {"policy": "random"}}, seed=2)).summary
    # a blocked move is rare for a robot that slides (only when a second obstacle is in the way)
    assert climbers["collisions"] < 0.1 * walkers["collisions"]


def test_a_return_is_the_distance_closed_the_arrival_and_the_steps_it_took() -> None:
    s = scenario(
        seed=6, obstacles={"count": 0}, cells={"motion_std": 0.0},
        robots={"policy": "gradient", "count": 4}, rewards={"step": -0.25},
        learning={"episodes": 0, "max_steps": 400}, evaluation={"worlds": 1},
    )  # fmt: skip
    result = simulate(s)
    t = result.trajectory
    assert t is not None
    for row in result.robots:
        i = row["robot"]
        closed = t.distance[0, i] - row["final_distance"]
        expected = closed + 10.0 * row["reached"] - 0.25 * int(t.robot_steps[i])
        assert row["return"] == pytest.approx(expected, abs=1e-9)


def test_epsilon_reaches_its_floor_after_most_of_the_training() -> None:
    learning = scenario(learning={"episodes": 100, "epsilon_end": 0.05}).learning
    assert qlearning.epsilon(learning, 79) > 0.05
    assert qlearning.epsilon(learning, 80) == pytest.approx(0.05)
    assert qlearning.epsilon(learning, 99) == 0.05
    given = scenario(learning={"episodes": 100, "epsilon_decay": 0.99}).learning
    assert qlearning.epsilon(given, 99) == pytest.approx(0.99**99)  # may stay above the floor


def test_the_authors_script_world() -> None:
    s = preset_scenario("authors-script", seed=2, learning={"episodes": 5},
                        evaluation={"worlds": 3})  # fmt: skip
    result = simulate(s)
    t = result.trajectory
    assert t is not None
    start = t.robots[0, 0]
    assert ((start >= -50.0) & (start <= -25.0)).all()  # the corner octant
    assert t.obstacles.shape[1] == 0
    # the sampled field: the mean of exp(-d^2/40^2) over points redrawn near the cell
    d = t.distance[0, 0]
    assert t.concentration[0, 0] == pytest.approx(math.exp(-(d**2) / 1600), rel=0.25)
    assert all(w["final_distance"] <= 0.5 for w in result.worlds)
