"""The scenario schema: defaults, presets, bounds, and errors that name the field."""

import json
import pickle

import pytest
from pydantic import ValidationError

from nanonav.scenario import PRESETS, Scenario, ScenarioError, preset_scenario


def error_locations(data: object) -> list[str]:
    with pytest.raises(ValidationError) as caught:
        Scenario.model_validate(data)
    return [".".join(str(p) for p in e["loc"]) for e in caught.value.errors()]


def test_empty_scenario_is_all_defaults() -> None:
    s = Scenario.model_validate({})
    assert s.space.size == 50.0 and s.robots.count == 1 and s.learning.episodes == 50
    assert s.biomarker.model == "gaussian" and s.robots.policy == "q_learning"


def test_presets_give_the_papers_figures_and_fields_override_them() -> None:
    swarm = preset_scenario("paper-swarm")
    assert (swarm.robots.count, swarm.cells.count, swarm.obstacles.count) == (15, 2, 10)
    single = preset_scenario("paper-single")
    assert (single.robots.count, single.cells.count) == (1, 1)
    mixed = Scenario.model_validate({"preset": "paper-swarm", "robots": {"speed": 1.0}})
    assert mixed.robots.count == 15 and mixed.robots.speed == 1.0
    assert set(PRESETS) == {
        "paper-single",
        "paper-swarm",
        "authors-script",
        "hard-single",
        "hard-swarm",
        "tumour-microswimmers",
        "tumour-nanorobots",
        "tumour-passive",
        "tumour-signals",
        "diffuse-tumour",
        "alonso-kirkegaard",
    }
    # the paper's and the hard worlds keep the paper's physics; the tumour worlds are physical
    for name in PRESETS:
        physics = preset_scenario(name).physics.model
        physical = name.startswith("tumour-") or name == "alonso-kirkegaard"
        assert physics == ("active_brownian" if physical else "lattice"), name


def test_a_resolved_scenario_round_trips() -> None:
    s = preset_scenario("paper-swarm", seed=9, robots={"count": 3})
    again = Scenario.model_validate(json.loads(s.model_dump_json()))
    assert again == s and again.robots.count == 3


@pytest.mark.parametrize(
    ("data", "field"),
    [
        ({"robots": {"count": 0}}, "robots.count"),
        ({"robots": {"count": 100_001}}, "robots.count"),
        ({"robots": {"policy": "teleport"}}, "robots.policy"),
        ({"biomarker": {"model": "laplace"}}, "biomarker.model"),
        ({"biomarker": {"spread": -1}}, "biomarker.spread"),
        ({"learning": {"alpha": 0}}, "learning.alpha"),
        ({"learning": {"gamma": 1.5}}, "learning.gamma"),
        ({"learning": {"episodes": "many"}}, "learning.episodes"),
        ({"space": {"size": "nan"}}, "space.size"),
        ({"biomarker": {"peak": float("inf")}}, "biomarker.peak"),
        ({"seed": -1}, "seed"),
        ({"preset": "paper-huge"}, "preset"),
        ({"robots": {"colour": "blue"}}, "robots.colour"),
        ({"warp": 9}, "warp"),
    ],
)
def test_invalid_fields_are_rejected_by_name(data: dict[str, object], field: str) -> None:
    assert field in error_locations(data)


def test_cross_field_rules_name_their_part() -> None:
    assert error_locations({"learning": {"epsilon_start": 0.1, "epsilon_end": 0.5}}) == [
        "learning.epsilon_end"
    ]
    assert error_locations({"obstacles": {"count": 1000, "radius": 5.0}}) == ["obstacles.count"]
    assert error_locations({"space": {"size": 5}}) == ["obstacles.radius"]
    assert error_locations({"space": {"size": 20}, "reach_distance": 11}) == ["reach_distance"]


def test_every_field_is_documented() -> None:
    schema = Scenario.model_json_schema()

    def walk(properties: dict[str, dict[str, object]]) -> None:
        for name, spec in properties.items():
            if "$ref" in spec or "allOf" in spec:
                continue
            assert spec.get("description"), name

    walk(schema["properties"])
    for definition in schema["$defs"].values():
        walk(definition["properties"])


def test_a_scenario_error_crosses_process_boundaries_intact() -> None:
    error = ScenarioError("obstacles.count", "leave no room")
    copy = pickle.loads(pickle.dumps(error))
    assert isinstance(copy, ScenarioError)
    assert (copy.field, copy.message, str(copy)) == (error.field, error.message, str(error))


def test_the_diffuse_tumour_is_a_swarm_of_robots_that_take_up_space_and_cells_that_need_drug() -> (
    None
):
    s = preset_scenario("diffuse-tumour")
    assert s.physics.model == "lattice"
    assert s.robots.exclusion and s.cells.capacity == 3 and s.cells.count == 20
    assert s.communication.model == "none"  # a study chooses the model
    signalling = preset_scenario("diffuse-tumour", communication={"model": "attractant"})
    assert signalling.communication.release_rate == 10.0
    # the signal's solver step keeps the explicit bound with room: dt (6 D / h^2 + k) <= 1/2
    every, substeps = signalling.signal_solver_steps
    d, k, _ = signalling.signal_rates
    h = s.space.size / s.communication.nodes_per_axis
    assert (every / substeps) * (6 * d / h**2 + k) <= 0.5
    assert s.work < signalling.work  # the grid is priced


def test_a_capacity_more_robots_than_fit_at_a_cell_is_refused_by_name() -> None:
    # spheres of radius r within reach d of a cell's centre: at most 74 % of ((d + r) / r)^3
    with pytest.raises(ValidationError) as refused:
        Scenario.model_validate({"robots": {"exclusion": True}, "cells": {"capacity": 20}})
    assert refused.value.errors()[0]["loc"] == ("cells", "capacity")
    assert "at most 19 robots" in str(refused.value)
    Scenario.model_validate({"robots": {"exclusion": True}, "cells": {"capacity": 19}})
    Scenario.model_validate({"cells": {"capacity": 10**5}})  # points pass through each other


@pytest.mark.parametrize("preset", ["alonso-kirkegaard", "paper-swarm"])
@pytest.mark.parametrize("policy", ["ppo", "recurrent_ppo"])
def test_a_network_the_job_trains_takes_decisions_not_episodes(preset: str, policy: str) -> None:
    s = preset_scenario(preset, robots={"policy": policy}, learning={"decisions": 200_000})
    assert s.trains and s.learning.episodes == 0 and s.training_decisions == 200_000
    assert preset_scenario(preset, robots={"policy": policy}).training_decisions == 1_000_000
    # its training counts in the budgets: every decision holds decision_steps robot-steps
    untrained = preset_scenario(preset, robots={"policy": "gradient"}, learning={"episodes": 0})
    extra = s.robot_steps_budget - untrained.robot_steps_budget
    assert extra == 200_000 * s.decision_steps
    assert s.work > untrained.work
    # it is trained and evaluated as a network given by policy_from is run
    learned = s.network_scenario()
    assert (learned.robots.policy, learned.learning.episodes) == ("q_learning", 0)
    assert learned.learning.decisions is None and learned.seed == s.seed
    # a resolved scenario validates again as it was
    assert Scenario.model_validate(s.model_dump()) == s


def test_a_study_base_may_give_both_trainings_and_each_policy_uses_its_own() -> None:
    base = {"preset": "alonso-kirkegaard", "learning": {"episodes": 40, "decisions": 200_000}}
    network = Scenario.model_validate({**base, "robots": {"policy": "ppo"}})
    table = Scenario.model_validate({**base, "robots": {"policy": "q_learning"}})
    assert (network.training_decisions, network.episodes) == (200_000, 20)
    assert (table.training_decisions, table.episodes) == (0, 60)
    untrained = Scenario.model_validate({**base, "robots": {"policy": "gradient"}})
    assert untrained.robot_steps_budget < network.robot_steps_budget


@pytest.mark.parametrize(
    ("data", "says"),
    [
        ({"robots": {"policy": "ppo"}, "learning": {"decisions": 0}},
         "greater than or equal to 1"),
        ({"robots": {"policy": "ppo"}, "learning": {"checkpoint_decisions": 1000}},
         "greater than or equal to 65536"),
        ({"robots": {"policy": "ppo"}, "learning": {"decisions": 10**11}},
         "less than or equal to 10000000000"),
    ],
)  # fmt: skip
def test_the_trainers_fields_are_bounded(data: dict[str, object], says: str) -> None:
    with pytest.raises(ValidationError) as caught:
        Scenario.model_validate({"preset": "alonso-kirkegaard", **data})
    [error] = caught.value.errors()
    assert says in error["msg"]


def test_the_engine_does_not_train_a_network() -> None:
    from nanonav.engine import simulate

    with pytest.raises(ScenarioError, match="trained outside the engine"):
        simulate(preset_scenario("alonso-kirkegaard", robots={"policy": "ppo"}))
