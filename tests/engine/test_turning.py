"""Continuous steering (``Worlds(steering="continuous")``, active Brownian): a robot reads its
sensed gradient each step in its body frame and turns by a command (side, up) in that frame,
at most the largest turn a step allows."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from nanonav.engine import qlearning
from nanonav.engine.dynamics.brownian import body_frame, turn_in_body
from nanonav.engine.observations import OBS_GRADIENT, observation_of
from nanonav.engine.worlds import Worlds
from nanonav.rl.rules import TurnUpGradient
from nanonav.scenario import Scenario, deep_merge

BROWNIAN: dict[str, Any] = {
    "physics": {"model": "active_brownian", "time_limit_s": 5.0},
    "space": {"size": 200.0},
    "obstacles": {"count": 0},
    "cells": {"count": 1},
}
# no diffusion: a swimmer's path is its steering alone
STILL = deep_merge(BROWNIAN, {"physics": {"diffusion_um2_s": 0.0, "rotational_diffusion_s": 0.0}})


def _worlds(data: dict[str, Any], steering: str, seed: int = 11) -> Worlds:
    worlds = Worlds(Scenario.model_validate(data), 1, "simultaneous", steering=steering)  # type: ignore[arg-type]
    worlds.seed([seed])
    worlds.step(None, np.ones(1, dtype=np.bool_))
    return worlds


def _unit(v: np.ndarray) -> np.ndarray:
    unit: np.ndarray = v / np.linalg.norm(v)
    return unit


def _xyz(v: np.ndarray) -> tuple[float, float, float]:
    """``v``'s three components, as the compiled functions take them."""
    x, y, z = v
    return x, y, z


def test_the_body_frame_is_orthonormal_and_carried_along_a_small_turn() -> None:
    rng = np.random.default_rng(5)
    for _ in range(200):
        n = _unit(rng.normal(size=3))
        kept = rng.normal(size=3)
        side = np.array(body_frame(*_xyz(n), *_xyz(kept)))
        e, f = side[:3], side[3:]
        frame = np.array([n, e, f])
        np.testing.assert_allclose(frame @ frame.T, np.eye(3), atol=1e-12)
        np.testing.assert_allclose(np.cross(n, e), f, atol=1e-12)  # right-handed
        # the heading turns a little: the side axis moves by about as little
        turned = _unit(n + 0.01 * rng.normal(size=3))
        e2 = np.array(body_frame(*_xyz(turned), *_xyz(e))[:3])
        assert np.linalg.norm(e2 - e) < 0.05
    # no side axis yet (zeros), or one along the heading: the heading's tangent basis
    n = np.array([0.0, 0.0, 1.0])
    assert abs(np.dot(body_frame(*_xyz(n), 0.0, 0.0, 0.0)[:3], n)) < 1e-12
    assert abs(np.dot(body_frame(*_xyz(n), 0.0, 0.0, 2.0)[:3], n)) < 1e-12


@pytest.mark.parametrize(("u_side", "u_up"), [(1.0, 0.0), (0.0, -0.5), (0.3, 0.4), (3.0, 4.0)])
def test_a_turn_is_its_share_of_the_largest_toward_its_direction(
    u_side: float, u_up: float
) -> None:
    n = _unit(np.array([0.2, -0.5, 0.8]))
    frame = np.array(body_frame(*_xyz(n), 1.0, 0.0, 0.0))
    e, f = frame[:3], frame[3:]
    largest = 0.3
    turned = np.array(turn_in_body(*_xyz(n), *_xyz(e), u_side, u_up, largest))
    size = math.hypot(u_side, u_up)
    assert math.acos(np.clip(np.dot(n, turned), -1, 1)) == pytest.approx(largest * min(1.0, size))
    # toward u_side e + u_up f: the turned heading's part across n points there
    across = turned - np.dot(turned, n) * n
    np.testing.assert_allclose(_unit(across), _unit(u_side * e + u_up * f), atol=1e-12)
    # no command, no turn
    np.testing.assert_allclose(turn_in_body(*_xyz(n), *_xyz(e), 0.0, 0.0, largest), n)


def test_a_held_turn_swims_a_circle_at_the_largest_turn_rate() -> None:
    """In a still world a full side turn held over an interval turns the heading by the
    largest turn each step, in one plane: the robot's steps are the sides of a regular
    polygon, each turned from the last by that angle."""
    data = deep_merge(STILL, {"learning": {"decision_interval_s": 0.5}})
    worlds = _worlds(data, "continuous")
    hold = worlds.scenario.decision_steps
    largest = worlds.params.turn
    assert largest > 0.0 and hold > 1
    start = worlds.batch.s.heading[0, 0].copy()
    where = worlds.batch.s.pos[0, 0].copy()
    worlds.step(np.array([[[1.0, 0.0]]]), np.zeros(1, dtype=np.bool_))
    assert worlds.steps(0) == hold
    end = worlds.batch.s.heading[0, 0]
    assert np.dot(start, end) == pytest.approx(math.cos(hold * largest), abs=1e-9)
    # the chord of hold sides of length v dt, each turned by the largest turn
    side = worlds.scenario.physics.swim_speed_um_s * worlds.scenario.physics.step_s
    chord = side * math.sin(hold * largest / 2) / math.sin(largest / 2)
    moved = np.linalg.norm(worlds.batch.s.pos[0, 0] - where)
    assert moved == pytest.approx(abs(chord), rel=1e-9)
    assert moved < 0.5 * hold * side  # it turned round, not straight on


def test_turning_as_the_gradient_rule_steers_reproduces_it() -> None:
    """An agent that turns toward the gradient it reads in its body frame (as far as a step
    allows: ``rl.rules.TurnUpGradient``) swims the path of ``steer_up_gradient`` in a noisy
    world: the same draws in the same order, the gradient read once a step."""
    data = deep_merge(BROWNIAN, {"physics": {"time_limit_s": 3.0}})
    step_s = Scenario.model_validate(data).physics.step_s
    data = deep_merge(data, {"learning": {"decision_interval_s": step_s}})  # a decision a step
    rule = _worlds(data, "discrete")
    turner = _worlds(data, "continuous")
    decide = TurnUpGradient(turner.scenario)
    columns = observation_of(turner.scenario, "continuous").columns
    up = np.array([[qlearning.STEERING_ACTIONS.index("steer_up_gradient")]], dtype=np.int64)
    stay = np.zeros(1, dtype=np.bool_)
    steps = 0
    while not rule.over[0]:
        turn = decide(turner.obs[0][:, columns]).reshape(1, 1, 2)
        rule.step(up, stay)
        turner.step(turn, stay)
        steps += 1
        np.testing.assert_allclose(turner.batch.s.pos, rule.batch.s.pos, atol=1e-6)
        assert turner.over[0] == rule.over[0]
    assert steps > 100
    # the rule never reads its gradient into the observation; the turner does, every step
    assert not rule.obs[0, 0, OBS_GRADIENT : OBS_GRADIENT + 3].any()


def test_a_decision_observes_the_mean_gradient_read_since_the_last() -> None:
    """Held over an interval, a robot integrates its gradient readings: what it observes at a
    decision is the mean of the interval's readings, each in its frame as it read it (the same
    worlds stepped one step a decision give those readings one by one). Read each step, so that
    every reading of the interval is a new one."""
    data = deep_merge(
        BROWNIAN,
        {"learning": {"decision_interval_s": 0.05}, "physics": {"sensor": "each_step"}},
    )
    held = _worlds(data, "continuous")
    hold = held.scenario.decision_steps
    assert hold == 5
    step_s = held.scenario.physics.step_s
    each = _worlds(deep_merge(data, {"learning": {"decision_interval_s": step_s}}), "continuous")
    columns = slice(OBS_GRADIENT, OBS_GRADIENT + 3)
    np.testing.assert_array_equal(held.obs[0, 0, columns], each.obs[0, 0, columns])
    stay = np.zeros(1, dtype=np.bool_)
    still = np.zeros((1, 1, 2))  # no turn: the same draws either way
    for _ in range(4):
        readings = []
        for _ in range(hold):
            each.step(still, stay)
            readings.append(each.obs[0, 0, columns].copy())
        held.step(still, stay)
        np.testing.assert_allclose(held.obs[0, 0, columns], np.mean(readings, axis=0),
                                   rtol=1e-9, atol=1e-300)  # fmt: skip
        assert np.any(readings[0] != readings[-1])
        np.testing.assert_array_equal(held.batch.s.pos, each.batch.s.pos)


def test_the_observation_names_the_body_frames_gradient() -> None:
    scenario = Scenario.model_validate(BROWNIAN)
    discrete = observation_of(scenario)
    continuous = observation_of(scenario, "continuous")
    assert "gradient_x" not in discrete.labels
    labels = continuous.labels
    assert labels[:5] == ("reading", "reading_change", "gradient_forward", "gradient_side",
                          "gradient_up")  # fmt: skip
    assert np.all(continuous.high[2:5] > 1e30)


def test_continuous_steering_refuses_what_it_cannot_do() -> None:
    with pytest.raises(ValueError, match="active_brownian"):
        Worlds(Scenario.model_validate({}), 1, "simultaneous", steering="continuous")
    with pytest.raises(ValueError, match="steering"):
        Worlds(Scenario.model_validate(BROWNIAN), 1, "simultaneous", steering="sideways")  # type: ignore[arg-type]
    worlds = _worlds(BROWNIAN, "continuous")
    stay = np.zeros(1, dtype=np.bool_)
    with pytest.raises(ValueError, match="shape"):
        worlds.step(np.zeros((1, 1)), stay)
    with pytest.raises(ValueError, match="finite"):
        worlds.step(np.array([[[np.nan, 0.0]]]), stay)
    # out of range is clipped: as a full turn
    a = _worlds(STILL, "continuous")
    b = _worlds(STILL, "continuous")
    a.step(np.array([[[5.0, 0.0]]]), stay)
    b.step(np.array([[[1.0, 0.0]]]), stay)
    np.testing.assert_array_equal(a.batch.s.heading, b.batch.s.heading)
