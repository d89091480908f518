"""Decisions held over an interval (``learning.decision_interval_s``, active Brownian): what a
held action does, that the reward is summed over the interval and the table updated at
decisions only, and what a scenario may ask for."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from pydantic import ValidationError

from nanonav.engine import qlearning, simulate
from nanonav.engine.simulation import kernel_params
from nanonav.engine.worlds import Worlds
from nanonav.scenario import Scenario, deep_merge

# a still world: no diffusion, so that a swimmer's path is its steering alone
STILL: dict[str, Any] = {
    "physics": {
        "model": "active_brownian", "time_limit_s": 10.0, "diffusion_um2_s": 0.0,
        "rotational_diffusion_s": 0.0,
    },
    "space": {"size": 200.0},
    "obstacles": {"count": 0},
    "cells": {"count": 1},
}  # fmt: skip


def _scenario(*parts: dict[str, Any]) -> Scenario:
    data: dict[str, Any] = {}
    for part in parts:
        data = deep_merge(data, part)
    return Scenario.model_validate(data)


def _worlds(scenario: Scenario) -> Worlds:
    worlds = Worlds(scenario, 1, "simultaneous")
    worlds.seed([3])
    worlds.step(None, np.ones(1, dtype=np.bool_))
    return worlds


def _action(name: str) -> np.ndarray:
    return np.array([[qlearning.STEERING_ACTIONS.index(name)]], dtype=np.int64)


def test_a_held_tumble_turns_once_then_keeps_its_heading() -> None:
    scenario = _scenario(STILL, {"learning": {"decision_interval_s": 0.5}})
    worlds = _worlds(scenario)
    hold = scenario.decision_steps
    assert hold == round(0.5 / scenario.physics.step_s) > 1
    stay = np.zeros(1, dtype=np.bool_)
    for _ in range(3):
        start = worlds.batch.s.pos[0, 0].copy()
        worlds.step(_action("tumble"), stay)
        heading = worlds.batch.s.heading[0, 0]
        # one tumble at the decision, then a straight run along the new heading
        swim = scenario.physics.swim_speed_um_s * scenario.physics.step_s
        np.testing.assert_allclose(worlds.batch.s.pos[0, 0] - start, hold * swim * heading,
                                   atol=1e-9)  # fmt: skip
        assert worlds.steps(0) % hold == 0


def test_a_held_action_is_its_steps_one_by_one_and_its_reward_their_sum() -> None:
    """Keeping the heading for an interval is the same world as keeping it step by step, and
    the interval's reward is the sum of the steps' (a noisy world: the draws come in the same
    order)."""
    base = deep_merge(STILL, {"physics": {"diffusion_um2_s": None, "rotational_diffusion_s": None}})
    held = _scenario(base, {"learning": {"decision_interval_s": 0.2}})
    each = _scenario(base, {"learning": {"decision_interval_s": held.physics.step_s}})
    assert each.decision_steps == 1
    hold = held.decision_steps
    a, b = _worlds(held), _worlds(each)
    stay = np.zeros(1, dtype=np.bool_)
    for _ in range(5):
        a.step(_action("keep_heading"), stay)
        summed = 0.0
        for _ in range(hold):
            b.step(_action("keep_heading"), stay)
            summed += float(b.reward[0, 0])
        assert float(a.reward[0, 0]) == pytest.approx(summed, rel=1e-12, abs=1e-12)
        np.testing.assert_array_equal(a.obs, b.obs)
        np.testing.assert_array_equal(a.batch.s.pos, b.batch.s.pos)


def test_the_learner_updates_at_decisions_only() -> None:
    """Over two training episodes and one evaluation of 10 s that no robot ends early, a
    decision a second makes 30 choices, each counted in the table's visits; deciding every step
    makes 100 times more."""
    far = {"cells": {"count": 1}, "space": {"size": 400.0}, "learning": {"episodes": 2},
           "evaluation": {"worlds": 1}}  # fmt: skip
    every = simulate(_scenario(STILL, far, {"learning": {"decision_interval_s": 0.01}}))
    held = simulate(_scenario(STILL, far, {"learning": {"decision_interval_s": 1.0}}))
    assert every.qtable is not None and held.qtable is not None
    assert all(row["success_rate"] == 0.0 for row in held.episodes)
    assert int(np.sum(held.qtable.visits)) == 3 * 10
    assert int(np.sum(every.qtable.visits)) == 3 * 1000


@pytest.mark.parametrize(
    ("interval", "says"),
    [
        (0.001, "shorter than one step"),
        (0.015, "not a whole number of steps of physics.dt_s 0.01 s: 0.01 or 0.02 would do"),
        (20.0, "longer than the episode"),
    ],
)
def test_an_interval_that_does_not_fit_is_refused_naming_it(interval: float, says: str) -> None:
    with pytest.raises(ValidationError) as refused:
        _scenario(STILL, {"physics": {"dt_s": 0.01}, "learning": {"decision_interval_s": interval}})
    assert "learning.decision_interval_s" in str(refused.value)
    assert says in str(refused.value)


def test_the_lattice_decides_every_step() -> None:
    with pytest.raises(ValidationError, match="a lattice robot decides every step"):
        _scenario({"learning": {"decision_interval_s": 1.0}})


def test_a_resolved_scenario_with_an_interval_validates_as_it_was() -> None:
    scenario = _scenario({"preset": "tumour-nanorobots"},
                         {"learning": {"decision_interval_s": 0.0016 * 60}})  # fmt: skip
    again = Scenario.model_validate(scenario.model_dump(mode="json"))
    assert again.decision_steps == scenario.decision_steps == 60


def test_an_active_brownian_learner_decides_every_second_unless_told() -> None:
    """The defaults chosen on design seeds: a decision a second (the whole episode if shorter),
    the visits schedule's exponent 0.6; the lattice keeps one decision a step and exponent 1."""
    scenario = _scenario(STILL)
    assert scenario.decision_steps == round(1.0 / scenario.physics.step_s) == 100
    assert scenario.alpha_exponent == 0.6
    short = _scenario(STILL, {"physics": {"time_limit_s": 0.25}})
    assert short.decision_steps == short.learning.max_steps == 25
    told = _scenario(STILL, {"learning": {"alpha_exponent": 0.8}})
    assert told.alpha_exponent == 0.8
    lattice = _scenario({"preset": "paper-swarm"})
    assert (lattice.decision_steps, lattice.alpha_exponent) == (1, 1.0)


@pytest.mark.parametrize("dt_s", [0.01, 0.002])
def test_a_second_costs_the_step_reward_whatever_dt(dt_s: float) -> None:
    """In active_brownian rewards.step and rewards.collision are per second: a robot swimming
    for one second in open water earns rewards.step in all, at any dt_s, and a blocked step
    costs dt_s times rewards.collision."""
    open_water = _scenario(STILL, {
        "physics": {"dt_s": dt_s, "time_limit_s": 2.0},
        "learning": {"decision_interval_s": 1.0},
        "rewards": {"approach": 0.0, "step": -0.1, "collision": -1.0},
    })  # fmt: skip
    worlds = _worlds(open_water)
    worlds.step(_action("keep_heading"), np.zeros(1, dtype=np.bool_))
    assert float(worlds.reward[0, 0]) == pytest.approx(-0.1, rel=1e-9)
    params = kernel_params(open_water)
    assert (params.reward_step, params.reward_collision) == pytest.approx((-0.1 * dt_s, -dt_s))
    lattice = kernel_params(_scenario({"preset": "paper-swarm"}))
    assert (lattice.reward_step, lattice.reward_collision) == (-0.1, -1.0)


@pytest.mark.parametrize("interval", [0.1, 1.0, 2.0])
def test_a_horizon_in_seconds_discounts_each_decision_by_its_length(interval: float) -> None:
    """learning.horizon_s: a reward t seconds ahead counts exp(-t / horizon_s), so decisions
    held 0.1 s and 2 s look equally far ahead; the kernel is given the discount per decision."""
    scenario = _scenario(STILL, {"learning": {"decision_interval_s": interval, "horizon_s": 10}})
    assert scenario.discount == pytest.approx(np.exp(-interval / 10.0), rel=1e-12)
    assert kernel_params(scenario).gamma == scenario.discount
    # ten seconds ahead count the same whatever the interval: e^-1
    assert scenario.discount ** round(10.0 / interval) == pytest.approx(np.exp(-1.0), rel=1e-9)
    again = Scenario.model_validate(scenario.model_dump(mode="json"))
    assert again.discount == scenario.discount
    # without it, gamma is the discount per decision, as given
    plain = _scenario(STILL, {"learning": {"decision_interval_s": interval, "gamma": 0.8}})
    assert kernel_params(plain).gamma == plain.discount == 0.8


@pytest.mark.parametrize(
    ("parts", "says"),
    [
        ({"preset": "paper-swarm", "learning": {"horizon_s": 10}}, "has no use in physics.model"),
        (
            deep_merge(STILL, {"learning": {"horizon_s": 10, "gamma": 0.99}}),
            "both set the discount: give one of the two",
        ),
        (deep_merge(STILL, {"learning": {"horizon_s": 0}}), "greater than 0"),
    ],
)
def test_a_horizon_that_cannot_be_used_is_refused_naming_it(
    parts: dict[str, Any], says: str
) -> None:
    with pytest.raises(ValidationError) as refused:
        _scenario(parts)
    assert "horizon_s" in str(refused.value)
    assert says in str(refused.value)
