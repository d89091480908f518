"""Whole runs: reproducibility, obstacles, the baselines, learning, stopping, Table 1."""

from typing import Any

import numpy as np
import pytest
from pydantic import ValidationError

from nanonav.engine import Progress, SimulationResult, simulate, without_timings
from nanonav.engine.qlearning import behavior_states, direction_states
from nanonav.scenario import Scenario, ScenarioError


def scenario(**fields: Any) -> Scenario:
    return Scenario.model_validate(fields)


def assert_identical(a: SimulationResult, b: SimulationResult) -> None:
    assert without_timings(a.to_dict()) == without_timings(b.to_dict())
    arrays_a, arrays_b = a.arrays(), b.arrays()
    assert arrays_a.keys() == arrays_b.keys()
    for key in arrays_a:
        assert arrays_a[key].dtype == arrays_b[key].dtype
        assert np.array_equal(arrays_a[key], arrays_b[key]), key


SWARM = {
    "preset": "paper-swarm",
    "learning": {"episodes": 4, "max_steps": 150},
    "biomarker": {"model": "inverse_square", "sensor_noise": 0.1},
    "obstacles": {"count": 20, "motion_std": 0.1},
}


@pytest.mark.parametrize("policy", ["q_learning", "gradient", "run_and_tumble", "random"])
def test_same_scenario_and_seed_give_bit_identical_results(policy: str) -> None:
    s = scenario(**SWARM, robots={"policy": policy, "count": 15}, seed=11)
    assert_identical(simulate(s), simulate(s))


def test_different_seeds_give_different_results() -> None:
    a = simulate(scenario(**SWARM, seed=1))
    b = simulate(scenario(**SWARM, seed=2))
    assert a.trajectory is not None and b.trajectory is not None
    assert not np.array_equal(a.trajectory.robots[0], b.trajectory.robots[0])
    assert without_timings(a.to_dict()["episodes"]) != without_timings(b.to_dict()["episodes"])


def test_per_robot_tables_are_reproducible_too() -> None:
    s = scenario(**{**SWARM, "learning": {"shared_table": False, "episodes": 3, "max_steps": 100}})
    assert_identical(simulate(s), simulate(s))


@pytest.mark.parametrize("policy", ["q_learning", "gradient", "run_and_tumble", "random"])
def test_no_robot_ever_ends_a_step_inside_an_obstacle(policy: str) -> None:
    s = scenario(
        seed=5,
        robots={"count": 40, "policy": policy},
        obstacles={"count": 150, "radius": 2.0, "motion_std": 0.3},
        cells={"count": 2},
        learning={"episodes": 0, "max_steps": 400, "actions": "directions"},
    )
    result = simulate(s)
    t = result.trajectory
    assert t is not None and t.stride == 1
    gaps = np.linalg.norm(t.robots[:, :, None, :] - t.obstacles[:, None, :, :], axis=3)
    assert gaps.min() >= t.obstacle_radius
    assert result.summary["collisions"] > 0, "the test should exercise blocked moves"


def test_gradient_reaches_a_static_cell_in_an_obstacle_free_world() -> None:
    for seed in range(5):
        s = scenario(
            seed=seed,
            cells={"motion_std": 0.0},
            obstacles={"count": 0},
            robots={"policy": "gradient", "count": 5},
            learning={"episodes": 0, "max_steps": 400},
        )
        result = simulate(s)
        assert result.summary["success_rate"] == 1.0
        assert result.summary["final_distance"] <= s.reach_distance
        # a straight climb: the path is hardly longer than the start-to-cell line
        assert result.summary["path_efficiency"] > 0.95


def test_q_learning_with_directions_learns_chemotaxis() -> None:
    first, last, trained, random = [], [], [], []
    for seed in range(4):
        base: dict[str, Any] = {"seed": seed, "learning": {"actions": "directions", "episodes": 40}}
        learned = simulate(scenario(**base))
        steps = [e["steps"] for e in learned.episodes]
        first.append(np.mean(steps[:10]))
        last.append(np.mean(steps[-10:]))
        trained.append(learned.summary["success_rate"])
        walk = simulate(scenario(**base, robots={"policy": "random"}))
        random.append(walk.summary["success_rate"])
    assert np.mean(last) < 0.5 * np.mean(first), (first, last)
    assert np.mean(trained) > np.mean(random), (trained, random)
    assert np.mean(trained) >= 0.75


def test_q_table_has_readable_labels_and_counts_visits() -> None:
    # still cells: every robot-step is a decision (no cell drifts into a robot's reach)
    result = simulate(scenario(cells={"motion_std": 0}, learning={"episodes": 3, "max_steps": 200}))
    q = result.qtable
    assert q is not None
    assert q.states == behavior_states() and len(q.actions) == 4
    assert q.values.shape == (len(q.states), 4) and q.visits.shape == q.values.shape
    assert q.visits.sum() == result.work["robot_steps"]
    assert np.abs(q.values).sum() > 0
    per_robot = simulate(
        scenario(
            robots={"count": 3},
            learning={
                "episodes": 1,
                "max_steps": 50,
                "shared_table": False,
                "actions": "directions",
            },
        )
    ).qtable
    assert per_robot is not None
    assert per_robot.values.shape == (3, len(direction_states()), 26)
    assert len(set(per_robot.actions)) == 26


def test_baselines_have_no_q_table() -> None:
    result = simulate(scenario(robots={"policy": "gradient"}, learning={"episodes": 1}))
    assert result.qtable is None
    assert "q_values" not in result.arrays()


def test_table_1_agrees_with_the_trajectory() -> None:
    result = simulate(scenario(preset="paper-swarm", learning={"episodes": 2, "max_steps": 300}))
    t = result.trajectory
    assert t is not None
    first = result.worlds[0]  # the recorded evaluation world
    assert first["episode_steps"] == t.length == int(t.robot_steps.max())
    steps = [r["steps_to_reach"] or result.scenario.learning.max_steps for r in result.robots]
    assert first["total_steps"] == float(np.median(steps))
    for row in result.robots:
        i = row["robot"]
        own = slice(0, int(t.robot_steps[i]) + 1)
        assert row["average_distance"] == pytest.approx(t.distance[own, i].mean(), rel=1e-12)
        assert row["average_concentration"] == pytest.approx(
            t.concentration[own, i].mean(), rel=1e-12
        )
        if row["reached"]:
            assert row["final_distance"] <= result.scenario.reach_distance
        assert 0.0 <= row["path_efficiency"] <= 1.0 + 1e-12
    searched = [r for r in result.robots if r["reached"] and not r["swept_up"]]
    assert first["success_rate"] == len(searched) / 15
    assert first["collisions"] == sum(r["collisions"] for r in result.robots)
    for key in ("success_rate", "total_steps", "average_distance"):
        values = [w[key] for w in result.worlds]
        assert result.summary[key] == pytest.approx(float(np.mean(values)), rel=1e-12)
        assert result.uncertainty[key]["n"] == len(result.worlds) == 20


def test_work_counts_every_robot_step() -> None:
    s = scenario(
        robots={"policy": "random", "count": 3},
        learning={"episodes": 2, "max_steps": 50},
        evaluation={"worlds": 4},
    )
    result = simulate(s)
    assert result.work["robot_steps"] == 3 * 50 * (2 + 4)
    assert result.work["engine_s"] > 0


def test_a_callback_can_stop_the_run_and_keep_finished_episodes() -> None:
    seen: list[Progress] = []

    def stop_after_three(p: Progress) -> bool:
        seen.append(p)
        return p.episode < 3

    # 50 random walkers: an episode is about half of the work between two progress reports
    walkers = scenario(
        robots={"count": 50, "policy": "random"}, learning={"episodes": 20, "max_steps": 1000}
    )
    result = simulate(walkers, stop_after_three)
    assert not result.completed
    assert 3 <= len(result.episodes) == seen[-1].episode < 20
    assert [e["episode"] for e in result.episodes] == list(range(len(result.episodes)))
    assert result.trajectory is None and result.summary == {}
    fractions = [p.fraction for p in seen]
    assert fractions == sorted(fractions) and fractions[0] >= 0.0 and fractions[-1] <= 1.0


def test_progress_reaches_one_at_the_end() -> None:
    seen: list[Progress] = []
    result = simulate(scenario(learning={"episodes": 2, "max_steps": 50}), seen.append)
    assert result.completed
    assert seen[-1].fraction == 1.0 and seen[-1].episode == seen[-1].episodes == 2 + 20


def test_the_episode_ends_on_the_step_the_last_robot_reaches_a_cell() -> None:
    # fast-drifting cells often arrive at a robot rather than the other way round
    for seed in range(6):
        s = scenario(
            seed=seed,
            preset="paper-swarm",
            cells={"motion_std": 1.0},
            learning={"episodes": 0, "max_steps": 2000},
            robots={"policy": "gradient"},
        )
        result = simulate(s)
        t = result.trajectory
        assert t is not None
        if t.reached.all():
            assert result.worlds[0]["episode_steps"] == int(t.robot_steps.max())
        for i in np.flatnonzero(t.reached):
            assert t.distance[t.robot_steps[i], i] <= s.reach_distance
            assert result.robots[i]["final_distance"] == t.distance[t.robot_steps[i], i]


def test_methods_and_fields_compared_on_one_seed_face_the_same_worlds() -> None:
    starts = []
    for policy, model in [
        ("q_learning", "gaussian"),
        ("random", "gaussian"),
        ("gradient", "inverse_square"),
        ("run_and_tumble", "diffusion"),
    ]:
        s = scenario(
            preset="paper-swarm",
            seed=21,
            robots={"policy": policy},
            biomarker={"model": model},
            learning={"episodes": 5, "max_steps": 200},
        )
        t = simulate(s).trajectory
        assert t is not None
        starts.append((t.robots[0], t.cells[0], t.obstacles[0]))
    for robots, cells, obstacles in starts[1:]:
        assert np.array_equal(robots, starts[0][0])
        assert np.array_equal(cells, starts[0][1])
        assert np.array_equal(obstacles, starts[0][2])


def test_a_learned_table_is_evaluated_as_it_was_learned() -> None:
    trained = simulate(
        Scenario.model_validate(
            {"seed": 1, "learning": {"episodes": 20, "max_steps": 200, "actions": "directions"}}
        )
    )
    assert trained.qtable is not None
    fresh = Scenario.model_validate(
        {"seed": 2, "learning": {"episodes": 0, "max_steps": 200, "actions": "directions"}}
    )
    evaluated = simulate(fresh, policy=trained.qtable.values)
    assert evaluated.qtable is not None
    assert np.array_equal(evaluated.qtable.values, trained.qtable.values)  # greedy: no learning
    untrained = simulate(fresh)
    assert evaluated.summary != untrained.summary
    with pytest.raises(ScenarioError, match="does not fit directions"):
        simulate(fresh, policy=np.zeros((3, 3)))


def test_policy_from_needs_q_learning_and_no_training() -> None:
    with pytest.raises(ValidationError) as raised:
        Scenario.model_validate({"policy_from": 3})
    assert raised.value.errors()[0]["loc"] == ("learning", "episodes")
    with pytest.raises(ValidationError) as raised:
        Scenario.model_validate(
            {"policy_from": 3, "robots": {"policy": "gradient"}, "learning": {"episodes": 0}}
        )
    assert raised.value.errors()[0]["loc"] == ("robots", "policy")


def _under(schedule: str, **parts: Any) -> SimulationResult:
    base: dict[str, Any] = {
        "learning": {"episodes": 3, "max_steps": 80},
        "evaluation": {"worlds": 2},
    }
    return simulate(Scenario.model_validate({**base, **parts, "robots": {
        **parts.get("robots", {}), "schedule": schedule}}))  # fmt: skip


def test_the_two_schedules_are_the_same_for_one_robot_and_differ_for_a_swarm() -> None:
    one = [without_timings(_under(s).to_dict()) for s in ("sequential", "simultaneous")]
    for result in one:
        del result["scenario"]  # which names its schedule
    assert one[0] == one[1]
    swarm = {"robots": {"count": 8}, "cells": {"count": 2, "capacity": 1},
             "communication": {"model": "broadcast"}}  # fmt: skip
    seq, sim = (_under(s, **swarm) for s in ("sequential", "simultaneous"))
    assert seq.qtable is not None and sim.qtable is not None
    assert not np.array_equal(seq.qtable.values, sim.qtable.values)


def test_a_schedule_is_one_of_two_names() -> None:
    with pytest.raises(ValidationError) as raised:
        Scenario.model_validate({"robots": {"schedule": "parallel"}})
    assert raised.value.errors()[0]["loc"] == ("robots", "schedule")
