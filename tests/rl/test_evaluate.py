"""A policy from outside, evaluated as a job evaluates a table: in the same worlds, the first
recorded and all of them measured, into the same result. A decision that always picks one
action meets, world for world, what ``simulate`` gives a table whose greedy action it is."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from nanonav.engine import qlearning, simulate
from nanonav.engine.observations import observation_of
from nanonav.rl import evaluate as evaluate_module
from nanonav.rl.evaluate import evaluate
from nanonav.rl.rules import TurnUpGradient
from nanonav.rl.stops import PolicyFailed
from nanonav.scenario import Scenario, ScenarioError

TIMINGS = ("duration_s",)


def scenario(**changes: Any) -> Scenario:
    base: dict[str, Any] = {
        "seed": 3,
        "learning": {"episodes": 0, "max_steps": 200},
        "evaluation": {"worlds": 4},
    }
    for key, value in changes.items():
        base[key] = {**base.get(key, {}), **value}
    return Scenario.model_validate(base)


def table_of(s: Scenario, action: int) -> Any:
    states, actions = qlearning.labels(s.learning.actions, s.communication.model)
    values = np.zeros((len(states), len(actions)))
    values[:, action] = 1.0
    return values


def always(action: int) -> Any:
    return lambda rows: np.full(rows.shape[0], action, dtype=np.int64)


def untimed(summary: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in summary.items() if k not in TIMINGS}


@pytest.mark.parametrize(
    "changes",
    [
        {},
        {"physics": {"model": "active_brownian"}, "learning": {"max_steps": 400}},
    ],
    ids=["lattice", "active_brownian"],
)
def test_one_action_always_meets_what_simulate_gives_its_greedy_table(
    changes: dict[str, Any],
) -> None:
    s = scenario(**changes)
    action = 1
    by_table = simulate(s, policy=table_of(s, action))
    by_outside = evaluate(s, always(action))
    # the same worlds: every world starts as simulate's evaluation world of that index
    assert by_outside.trajectory is not None and by_table.trajectory is not None
    assert np.array_equal(by_outside.trajectory.cells[0], by_table.trajectory.cells[0])
    # the first world runs on simulate's own dynamics stream: the same episode exactly
    assert np.array_equal(by_outside.trajectory.robots, by_table.trajectory.robots)
    assert untimed(by_outside.worlds[0]) == untimed(by_table.worlds[0])
    assert [untimed(r) for r in by_outside.robots] == [untimed(r) for r in by_table.robots]
    assert len(by_outside.worlds) == 4 and by_outside.completed
    assert set(by_outside.summary) == set(by_table.summary)


def test_the_worlds_after_the_first_are_simulates_worlds_too() -> None:
    """With nothing random after the draw of a world (still cells, a noiseless sensor, a rule
    with no chance in it), an episode is its world's alone: every world's tallies then match
    simulate's, though the others run on dynamics streams of their own."""
    s = scenario(robots={"count": 2}, cells={"motion_std": 0.0}, evaluation={"worlds": 5})
    by_table = simulate(s, policy=table_of(s, 0))  # follow_gradient
    by_outside = evaluate(s, always(0))
    assert [untimed(w) for w in by_outside.worlds] == [untimed(w) for w in by_table.worlds]
    assert len({w["total_steps"] for w in by_table.worlds}) > 1  # the worlds do differ


def test_every_robot_of_every_world_is_decided_in_one_call() -> None:
    s = scenario(robots={"count": 5, "schedule": "simultaneous"}, evaluation={"worlds": 3})
    calls = []

    def decide(rows: Any) -> Any:
        calls.append(rows.shape)
        return np.zeros(rows.shape[0], dtype=np.int64)

    result = evaluate(s, decide)
    width = observation_of(s).columns.size
    assert calls and all(shape == (15, width) for shape in calls)
    assert result.trajectory is not None and result.trajectory.robots.shape[1] == 5


def test_under_the_sequential_schedule_each_call_decides_one_robot_a_world() -> None:
    s = scenario(robots={"count": 3, "schedule": "sequential"}, evaluation={"worlds": 2})
    calls = []

    def decide(rows: Any) -> Any:
        calls.append(rows.shape[0])
        return np.zeros(rows.shape[0], dtype=np.int64)

    evaluate(s, decide)
    assert calls and set(calls) == {2}


def test_a_policy_that_answers_nonsense_or_raises_fails_saying_what() -> None:
    s = scenario()
    cases: list[tuple[Callable[[np.ndarray], Any], str]] = [  # answers of any type
        (lambda rows: np.zeros(rows.shape[0] + 1, dtype=np.int64), "shape"),
        (lambda rows: np.zeros(rows.shape[0]), "float64, not integers"),
        (lambda rows: np.full(rows.shape[0], 9, dtype=np.int64), "action 9, not one of 0..3"),
        (lambda rows: 1 / 0, "raised ZeroDivisionError"),
    ]
    for decide, message in cases:
        with pytest.raises(PolicyFailed, match=message):
            evaluate(s, decide)
    with pytest.raises(ScenarioError):
        evaluate(scenario(learning={"episodes": 2}), always(0))


def test_a_progress_callback_that_answers_false_stops_the_run() -> None:
    s = scenario(learning={"max_steps": 100_000}, robots={"count": 50})
    result = evaluate(s, always(0), progress=lambda where: False)
    assert not result.completed and result.summary == {}


def test_worlds_evaluated_in_rounds_give_what_one_round_gives(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Rounds bound the memory and change nothing else: three robots a round (a world alone)
    gives the very tallies of all five worlds at once."""
    s = scenario(robots={"count": 3, "schedule": "simultaneous"}, evaluation={"worlds": 5})
    at_once = evaluate(s, always(1))
    monkeypatch.setattr(evaluate_module, "ROUND_ROBOTS", 3)
    calls = []

    def decide(rows: Any) -> Any:
        calls.append(rows.shape[0])
        return np.ones(rows.shape[0], dtype=np.int64)

    in_rounds = evaluate(s, decide)
    assert [untimed(w) for w in in_rounds.worlds] == [untimed(w) for w in at_once.worlds]
    assert set(calls) == {3}  # one world's robots a call


def test_a_network_with_a_memory_decides_for_every_robot_at_once_only() -> None:
    from nanonav.rl.onnx_policy import NetworkPolicy
    from tests.rl import models

    s = scenario(robots={"count": 3, "schedule": "simultaneous"}, evaluation={"worlds": 2})
    width = observation_of(s).columns.size
    with NetworkPolicy(models.counter(width, 4), width, 4, max_bytes=100_000) as policy:
        assert evaluate(s, policy).completed
        swarm_in_turns = scenario(robots={"count": 3, "schedule": "sequential"})
        with pytest.raises(PolicyFailed, match=r"robots\.schedule must be 'simultaneous'"):
            evaluate(swarm_in_turns, policy)


def test_a_continuous_turn_up_the_gradient_meets_the_gradient_rule() -> None:
    """A turn decided from outside, each step, toward the gradient read in the body frame:
    world for world what ``simulate`` gives the ``gradient`` rule to one robot (the same draws
    in the same order; a path may differ from the rule's in its last digits). In a swarm the
    turning robots read their gradients as they perceive, the rule's as they act: the same
    draws, in another order."""
    s = scenario(
        physics={"model": "active_brownian"}, robots={"count": 1}, learning={"max_steps": 300},
        evaluation={"worlds": 6},
    )  # fmt: skip
    s = Scenario.model_validate(
        {**s.model_dump(mode="json"), "learning": {**s.learning.model_dump(mode="json"),
         "decision_interval_s": s.physics.step_s}}
    )  # fmt: skip
    rule = Scenario.model_validate(
        {**s.model_dump(mode="json"), "robots": {**s.robots.model_dump(mode="json"),
         "policy": "gradient"}}
    )  # fmt: skip
    by_rule = simulate(rule)
    by_turns = evaluate(s, TurnUpGradient(s), steering="continuous")
    assert by_turns.trajectory is not None and by_rule.trajectory is not None
    np.testing.assert_allclose(by_turns.trajectory.robots, by_rule.trajectory.robots, atol=1e-6)
    for turned, ruled in zip(by_turns.worlds, by_rule.worlds, strict=True):
        assert turned["success_rate"] == ruled["success_rate"]
        assert turned["total_steps"] == ruled["total_steps"]
    with pytest.raises(PolicyFailed, match="turn"):
        evaluate(s, always(1), steering="continuous")
