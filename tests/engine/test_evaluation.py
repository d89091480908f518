"""Evaluation over many worlds, and swarm metrics that mean one thing each."""

from __future__ import annotations

import statistics
from typing import Any

import numpy as np
import pytest

from nanonav import stats
from nanonav.engine import metrics, simulate
from nanonav.scenario import Scenario


def scenario(**fields: Any) -> Scenario:
    return Scenario.model_validate(fields)


def test_the_summary_is_the_mean_over_the_evaluation_worlds_with_its_uncertainty() -> None:
    result = simulate(
        scenario(
            preset="paper-swarm",
            seed=2,
            learning={"episodes": 3, "max_steps": 300},
            evaluation={"worlds": 6},
        )
    )
    assert len(result.worlds) == 6 and result.summary["worlds"] == 6
    for key in ("success_rate", "total_steps", "average_concentration", "path_efficiency"):
        sample = [w[key] for w in result.worlds]
        assert result.summary[key] == pytest.approx(statistics.fmean(sample), rel=1e-12)
        spread = result.uncertainty[key]
        assert spread["n"] == 6
        if len(set(sample)) > 1:
            assert spread["sd"] == pytest.approx(statistics.stdev(sample), rel=1e-9)
            assert spread["ci_low"] < result.summary[key] < spread["ci_high"]
    assert result.summary["reached"] == sum(w["reached"] for w in result.worlds)


def test_a_share_of_robots_pools_the_worlds_robots_into_its_interval() -> None:
    """Ten worlds of 20 robots that all reach a cell are 200 successes of 200, not ten: the
    interval is Wilson's over the pooled trials, [0.981, 1], where ten trials gave [0.72, 1]."""
    perfect = [
        {"success_rate": 1.0, "robots": 20, "reached": 20, "swept_up": 0, "total_steps": 5.0}
        for _ in range(10)
    ]
    _, uncertainty = metrics.over_worlds(perfect, cells=1)
    share = uncertainty["success_rate"]
    assert share["method"] == stats.POOLED_WILSON and share["n"] == 10
    assert share["ci_high"] == 1.0 and share["ci_low"] == pytest.approx(0.9812, abs=1e-4)
    one_miss = [*perfect[:9], {**perfect[0], "success_rate": 0.95, "reached": 19}]
    _, missed = metrics.over_worlds(one_miss, cells=1)
    assert missed["success_rate"]["ci_low"] < share["ci_low"], "a miss widens the interval"


def test_every_policy_on_a_seed_is_judged_in_the_same_worlds() -> None:
    firsts = []
    for policy, episodes in (("q_learning", 4), ("gradient", 0), ("rule", 7)):
        result = simulate(
            scenario(
                seed=9,
                robots={"policy": policy, "count": 3},
                learning={"episodes": episodes, "max_steps": 100},
            )
        )
        assert result.trajectory is not None
        firsts.append((result.trajectory.robots[0], result.trajectory.cells[0]))
    for robots, cells in firsts[1:]:
        assert np.array_equal(robots, firsts[0][0])
        assert np.array_equal(cells, firsts[0][1])


def test_swarm_metrics_follow_their_definitions() -> None:
    # bacterial chemotaxis with a short step limit: some reach their cell, some do not
    result = simulate(
        scenario(
            preset="paper-swarm",
            seed=1,
            robots={"policy": "run_and_tumble"},
            learning={"episodes": 0, "max_steps": 200},
            evaluation={"worlds": 1},
        )
    )
    world = result.worlds[0]
    rows = result.robots
    reached = [r for r in rows if r["reached"]]
    failed = [r for r in rows if not r["reached"]]
    assert reached and failed
    assert world["total_steps"] == statistics.median(
        r["steps_to_reach"] if r["reached"] else 200 for r in rows
    )
    assert all(r["total_steps"] == 200 and r["steps_to_reach"] is None for r in failed)
    assert world["mean_steps_to_reach"] == statistics.fmean(r["steps_to_reach"] for r in reached)
    searched = [r for r in reached if not r["swept_up"]]
    assert all(r["reached"] for r in rows if r["swept_up"])
    assert world["success_rate"] == len(searched) / len(rows)
    assert world["swept_up"] == len(reached) - len(searched)
    assert world["final_distance_reached"] == pytest.approx(
        statistics.fmean(r["final_distance"] for r in reached)
    )
    assert world["final_distance_unreached"] == pytest.approx(
        statistics.fmean(r["final_distance"] for r in failed)
    )
    assert world["final_distance_reached"] <= 0.5 < world["final_distance_unreached"]
    assert world["episode_steps"] == 200


def test_a_cell_that_drifts_onto_a_parked_robot_is_counted_apart_from_a_search() -> None:
    # robots that climb the exact gradient park at the field's maximum, where the drifting
    # cells then run into them
    found = simulate(
        scenario(
            preset="paper-swarm", seed=3, robots={"policy": "gradient"},
            learning={"episodes": 0, "max_steps": 800}, evaluation={"worlds": 4},
        )
    )  # fmt: skip
    worlds = found.worlds
    swept = sum(w["swept_up"] for w in worlds)
    reached = sum(w["reached"] for w in worlds)
    assert swept > 0 and found.summary["swept_up"] == swept
    robots = worlds[0]["robots"]
    searched = sum(w["success_rate"] for w in worlds) * robots
    assert searched == pytest.approx(reached - swept)
