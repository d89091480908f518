"""A study's grid: points in order, values merged into the base, seeds shared by every point."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from nanonav.scenario import Scenario
from nanonav.studies.spec import GRID_KEYS, StudySpec, point_values, points


def spec(**fields: object) -> StudySpec:
    return StudySpec.model_validate({"replicates": 2, **fields})


def test_points_run_through_every_combination_last_key_fastest() -> None:
    study = spec(grid={"robots.policy": ["q_learning", "gradient"], "obstacles.count": [0, 5, 9]})
    assert point_values(study) == [
        {"robots.policy": p, "obstacles.count": n}
        for p in ("q_learning", "gradient")
        for n in (0, 5, 9)
    ]
    assert study.job_count == 12
    assert study.seed_list == [0, 1]


def test_grid_values_override_the_base_and_keep_its_other_fields() -> None:
    study = spec(
        base={"preset": "paper-swarm", "robots": {"speed": 0.7}, "seed": 99},
        grid={"robots.count": [3], "preset": ["paper-swarm", "paper-single"]},
    )
    found = points(study)
    swarm, single = found[0].scenario, found[1].scenario
    assert (swarm.robots.count, swarm.robots.speed, swarm.cells.count) == (3, 0.7, 2)
    assert (single.robots.count, single.robots.speed, single.cells.count) == (3, 0.7, 1)
    assert found[1].with_seed(5).seed == 5
    assert found[1].with_seed(5).robots == single.robots


def test_an_empty_grid_is_one_point_the_base() -> None:
    study = spec(base={"robots": {"count": 4}}, seeds=[3, 1, 2], replicates=None)
    (only,) = points(study)
    assert only.values == {} and only.scenario.robots.count == 4
    assert study.job_count == 3 and study.seed_list == [3, 1, 2]


def test_every_leaf_of_the_scenario_but_the_seed_can_be_swept() -> None:
    assert "robots.policy" in GRID_KEYS and "learning.episodes" in GRID_KEYS
    assert "preset" in GRID_KEYS and "reach_distance" in GRID_KEYS
    assert "seed" not in GRID_KEYS and "robots" not in GRID_KEYS


@pytest.mark.parametrize(
    ("fields", "loc"),
    [
        ({"grid": {"robots.count": []}}, ("grid", "robots.count")),
        ({"grid": {"robots.count": [True, 2.5, {"x": 1}]}}, ("grid", "robots.count", 2)),
        ({"grid": {"robots.speed": [float("nan")]}}, ("grid", "robots.speed", 0)),
        ({"compare": "robots.count", "grid": {"robots.count": [1]}}, ("grid", "robots.count")),
        ({"seeds": [1], "replicates": 2}, ("seeds",)),
    ],
)
def test_a_bad_spec_names_the_place(fields: dict[str, object], loc: tuple[object, ...]) -> None:
    with pytest.raises(ValidationError) as raised:
        spec(**fields)
    assert raised.value.errors()[0]["loc"] == loc


def test_a_study_sweeps_robot_radius_and_gets_a_fitting_step_at_each() -> None:
    spec = StudySpec.model_validate(
        {
            "base": {"preset": "tumour-microswimmers"},
            "grid": {
                "physics.robot_radius_um": [0.2, 1.0, 5.0],
                "robots.policy": ["uncontrolled", "gradient"],
            },
            "seeds": [0, 1],
        }
    )
    found = points(spec)
    assert len(found) == 6
    steps = {p.values["physics.robot_radius_um"]: p.scenario.physics.step_s for p in found}
    assert steps[0.2] < steps[1.0] == steps[5.0] == 0.01
    for point in found:  # 60 s whatever the step
        ph = point.scenario.physics
        assert point.scenario.learning.max_steps * ph.step_s == pytest.approx(60.0, abs=ph.step_s)


def test_a_field_whose_default_is_null_is_swept_through_null() -> None:
    """{"cells.capacity": [null, 2]} was refused: null is a grid value where the field takes
    it, and refused, naming the value, where it does not."""
    swept = spec(grid={"cells.capacity": [None, 2], "physics.dt_s": [None, 0.01]},
                 base={"physics": {"model": "active_brownian"}})  # fmt: skip
    found = points(swept)
    assert [p.scenario.cells.capacity for p in found] == [None, None, 2, 2]
    assert [p.values["physics.dt_s"] for p in found] == [None, 0.01, None, 0.01]
    # null is the field's own default: the step the physics chooses (here also 0.01 s)
    assert found[0].scenario.physics.dt_s == Scenario.model_validate(swept.base).physics.dt_s
    with pytest.raises(ValidationError) as raised:
        points(spec(grid={"robots.count": [None, 2]}))
    assert raised.value.errors()[0]["loc"] == ("grid", "robots.count", 0)
    with pytest.raises(ValidationError) as raised:
        spec(grid={"cells.capacity": [None, 2, None]})
    assert raised.value.errors()[0]["loc"] == ("grid", "cells.capacity", 2)  # listed twice
