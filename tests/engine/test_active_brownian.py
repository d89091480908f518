"""The active Brownian physics through ``simulate``: bit-identical per seed, passive and active
motion against theory, readings at the Berg-Purcell limit as the trajectory reports them,
obstacles that nothing passes through, cells reached at their surface, and the derived numbers
in the results."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from nanonav.engine import simulate
from nanonav.engine.dynamics import brownian
from nanonav.engine.result import without_timings
from nanonav.scenario import Scenario


def swimmers(**fields: Any) -> Scenario:
    base: dict[str, Any] = {
        "physics": {"model": "active_brownian"},
        "space": {"size": 400.0},
        "obstacles": {"count": 0},
        "robots": {"count": 400, "policy": "uncontrolled", "cell_sensing_radius": 0.0},
        "learning": {"episodes": 0, "max_steps": 200},
        "evaluation": {"worlds": 1},
        "seed": 5,
    }
    for key, value in fields.items():
        base[key] = {**base.get(key, {}), **value} if isinstance(value, dict) else value
    return Scenario.model_validate(base)


def test_the_same_scenario_and_seed_give_the_same_results_bit_for_bit() -> None:
    s = swimmers(robots={"count": 20, "policy": "q_learning"}, obstacles={"count": 8},
                 learning={"episodes": 3, "max_steps": 300})  # fmt: skip
    a, b = simulate(s), simulate(s)
    assert without_timings(a.to_dict()) == without_timings(b.to_dict())
    assert a.trajectory is not None and b.trajectory is not None
    for name, array in a.arrays().items():
        assert np.array_equal(array, b.arrays()[name]), name
    other = simulate(s.model_copy(update={"seed": 6}))
    assert not np.array_equal(a.arrays()["robots"], other.arrays()["robots"])


def displacement_check(s: Scenario, row: int) -> tuple[float, float, float]:
    """Mean squared displacement at history row ``row`` over the robots, its standard error,
    and the theory at that time."""
    t = simulate(s).trajectory
    assert t is not None
    squared = np.sum((t.robots[row] - t.robots[0]) ** 2, axis=1)
    ph = s.physics
    assert ph.diffusion_um2_s is not None and ph.rotational_diffusion_s is not None
    lag = float(t.step[row]) * ph.step_s
    theory = brownian.mean_squared_displacement_um2(
        ph.diffusion_um2_s, ph.swim_speed_um_s, ph.rotational_diffusion_s, lag
    )
    return float(squared.mean()), float(squared.std(ddof=1) / math.sqrt(len(squared))), theory


@pytest.mark.parametrize("speed", [0.0, 10.0])
def test_robots_far_from_everything_move_as_active_brownian_particles(speed: float) -> None:
    # no cell within reach in 2 s, no obstacle, walls 200 um away: free motion, MSD as theory
    s = swimmers(physics={"model": "active_brownian", "swim_speed_um_s": speed})
    mean, error, theory = displacement_check(s, -1)
    assert abs(mean - theory) < 4 * error + 0.01 * theory, (mean, error, theory)


def test_the_recorded_heading_decorrelates_as_exp_minus_two_d_r_t() -> None:
    s = swimmers(physics={"model": "active_brownian", "robot_radius_um": 0.5, "dt_s": 0.005})
    t = simulate(s).trajectory
    assert t is not None and t.headings is not None
    d_r = s.physics.rotational_diffusion_s
    assert d_r is not None
    assert np.allclose(np.linalg.norm(t.headings, axis=2), 1.0, atol=1e-12)
    for row in (20, 100, 200):
        dots = np.sum(t.headings[row] * t.headings[0], axis=1)
        lag = float(t.step[row]) * s.physics.step_s
        error = 4 * dots.std(ddof=1) / math.sqrt(len(dots))
        assert abs(dots.mean() - math.exp(-2 * d_r * lag)) < error, row


def test_readings_carry_the_berg_purcell_error_the_readme_states() -> None:
    # near a cell, where a reading counts a few hundred molecules: the sensed reading over the
    # true concentration, scaled by the stated relative error, is a unit-variance residual (a
    # reading each step, over dt_s; counted readings have tests of their own, test_counting.py)
    s = swimmers(
        robots={"count": 300, "policy": "uncontrolled", "start": "anywhere"},
        physics={"model": "active_brownian", "secretion_molecules_s": 1e6, "swim_speed_um_s": 0.0,
                 "sensor": "each_step"},
        space={"size": 60.0}, learning={"episodes": 0, "max_steps": 50},
    )  # fmt: skip
    t = simulate(s).trajectory
    assert t is not None and t.sensed is not None
    ph = s.physics
    searching = t.step[1:, None] <= t.robot_steps[None, :]  # rows while each robot was active
    true = t.concentration[1:][searching]
    sensed = t.sensed[1:][searching]
    relative = np.array([
        brownian.berg_purcell_relative_error(ph.molecule_diffusion_um2_s, ph.robot_radius_um, c,
                                             ph.step_s) for c in true
    ])  # fmt: skip
    # the reading is taken at the start of a step, the true value recorded at its end: the
    # robots do not swim here and jiggle little, so the two agree to first order
    z = (sensed - true) / (true * relative)
    # in the quarter of readings with the largest error and the quarter with the smallest (over
    # twice the concentration): the residual's spread is 1 in
    # both, so the error scales as 1 / sqrt(c) as stated
    low = relative > np.quantile(relative, 0.75)
    high = relative < np.quantile(relative, 0.25)
    assert relative[low].mean() > 1.4 * relative[high].mean()
    for part in (low, high):
        n = int(part.sum())
        assert n > 1000
        assert abs(z[part].mean()) < 4 / math.sqrt(n) + 0.02
        assert abs(z[part].std() - 1.0) < 4 * math.sqrt(0.5 / n) + 0.03


def test_no_robot_ever_enters_an_obstacle_and_cells_are_reached_at_their_surface() -> None:
    s = swimmers(
        robots={"count": 60, "policy": "exact_gradient", "cell_sensing_radius": 0.0},
        obstacles={"count": 40, "radius": 4.0}, space={"size": 120.0},
        physics={"model": "active_brownian", "swim_speed_um_s": 20.0, "dt_s": 0.02},
        learning={"episodes": 0, "max_steps": 3000},
    )  # fmt: skip
    result = simulate(s)
    t = result.trajectory
    assert t is not None and t.stride == 1
    centres = t.obstacles_at(0)
    gaps = np.linalg.norm(t.robots[:, :, None, :] - centres[None, None], axis=3)
    assert gaps.min() >= s.obstacles.radius + s.physics.robot_radius_um  # surfaces never overlap
    assert result.summary["collisions"] > 0  # and the noise did push robots against them
    touch = s.physics.robot_radius_um + s.physics.cell_radius_um
    for robot in np.flatnonzero(t.reached):
        last = int(t.robot_steps[robot])
        assert t.distance[last, robot] <= touch + 1e-9
        assert t.distance[max(last - 1, 0), robot] > touch - s.physics.swim_speed_um_s * 0.02 - 1
    assert t.reached.mean() > 0.5  # the exact gradient finds the cell


def test_the_results_carry_the_derived_physics_in_seconds() -> None:
    s = swimmers(robots={"count": 10, "policy": "exact_gradient"}, space={"size": 100.0},
                 learning={"episodes": 0, "max_steps": 2000})  # fmt: skip
    result = simulate(s)
    physics = result.physics
    assert physics["persistence_length_um"] == pytest.approx(10.0 / (2 * 0.2469256), rel=1e-4)
    assert physics["peclet_rotational"] == pytest.approx(10.0 / 0.2469256, rel=1e-4)
    assert physics["time_to_reach_s"] == pytest.approx(result.summary["total_steps"] * 0.01)
    assert physics["time_limit_s"] == pytest.approx(20.0)
    assert result.to_dict()["physics"] == physics
    assert (
        "physics" not in simulate(Scenario.model_validate({"learning": {"episodes": 1}})).to_dict()
    )
