"""``Scenario.work``: what a run can cost, weighed by the sources, obstacles and moves its steps
go through, unlike ``robot_steps_budget``."""

from typing import Any

from nanonav.scenario import WORK_PAIR, WORK_SOURCE, Scenario


def scenario(**fields: Any) -> Scenario:
    return Scenario.model_validate(fields)


BASE: dict[str, Any] = {
    "robots": {"count": 20},
    "cells": {"count": 4},
    "obstacles": {"count": 10},
    "learning": {"episodes": 9, "max_steps": 500},
    "evaluation": {"worlds": 1},
}
INVERSE = {"model": "inverse_square"}


def with_(**changes: dict[str, Any]) -> Scenario:
    return scenario(**{**BASE, **{k: {**BASE.get(k, {}), **v} for k, v in changes.items()}})


def test_work_is_the_cost_of_every_robot_active_for_every_step() -> None:
    s = with_()
    robot_steps = 20 * 500 * 10
    assert s.robot_steps_budget == robot_steps
    assert s.work == s.work_for(robot_steps, 500 * 10, 10, 500)
    assert s.work > s.work_for(robot_steps // 2, 500 * 10, 10, 500)


def test_sources_are_cells_or_their_emitters() -> None:
    assert with_().sources == 4
    inverse = with_(biomarker={**INVERSE, "emitters_per_cell": 30})
    assert inverse.sources == 120


def test_work_grows_with_every_source_each_robot_step_sums() -> None:
    few = with_(biomarker={**INVERSE, "emitters_per_cell": 10})
    many = with_(biomarker={**INVERSE, "emitters_per_cell": 1000})
    robot_steps = few.robot_steps_budget
    added = (many.sources - few.sources) * WORK_SOURCE["inverse_square"] * robot_steps
    assert many.work - few.work >= added
    assert many.robot_steps_budget == few.robot_steps_budget
    # 100 cells x 1,000 emitters: a robot-step costs hundreds of times the default's
    huge = with_(cells={"count": 100}, biomarker={**INVERSE, "emitters_per_cell": 1000})
    assert huge.work / huge.robot_steps_budget > 100 * with_().work / with_().robot_steps_budget


def test_an_exponential_source_costs_more_than_an_inverse_square_emitter() -> None:
    gaussian = with_(cells={"count": 100})
    inverse = with_(cells={"count": 100}, biomarker={**INVERSE, "emitters_per_cell": 1})
    assert gaussian.sources == inverse.sources == 100
    assert gaussian.work > inverse.work
    assert with_(biomarker={"model": "diffusion"}).work == with_().work


def test_work_grows_with_obstacles_scanned_twice_per_robot_step() -> None:
    none = with_(obstacles={"count": 0})
    many = with_(obstacles={"count": 1000})
    assert many.work - none.work >= 2 * WORK_PAIR * 1000 * none.robot_steps_budget
    assert many.robot_steps_budget == none.robot_steps_budget


def test_moving_things_cost_their_checks_every_step() -> None:
    still = with_(obstacles={"count": 1000, "motion_std": 0.0}, cells={"motion_std": 0.0})
    drifting = with_(obstacles={"count": 1000, "motion_std": 0.1}, cells={"motion_std": 0.0})
    steps = 500 * 10
    # every obstacle tests every robot and cell before it moves
    assert drifting.work - still.work >= WORK_PAIR * 1000 * (20 + 4) * steps
    cells_drift = with_(obstacles={"count": 1000, "motion_std": 0.0}, cells={"motion_std": 0.2})
    # every cell tests every obstacle before it moves
    assert cells_drift.work - still.work >= WORK_PAIR * 4 * 1000 * steps


def test_learning_with_the_papers_behaviours_costs_most_per_robot_step() -> None:
    behaviours = with_(obstacles={"count": 0}).work
    directions = with_(obstacles={"count": 0}, learning={"actions": "directions"}).work
    walk = with_(obstacles={"count": 0}, robots={"policy": "random"}).work
    assert behaviours > directions > walk


def test_work_grows_with_episodes_steps_and_robots() -> None:
    base = with_().work
    assert with_(learning={"episodes": 19}).work > 1.9 * base
    assert with_(learning={"max_steps": 1000}).work > 1.9 * base
    assert with_(robots={"count": 40}).work > 1.9 * base
    assert isinstance(base, int)
