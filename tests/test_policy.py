"""The learned policy as data: the greedy table (ties, unvisited states, per-robot tables) and
the rule for which stored tables a scenario can evaluate."""

from __future__ import annotations

from typing import Any, cast

import numpy as np
import pytest
from numpy.typing import NDArray
from pydantic import BaseModel

from nanonav.engine import qlearning
from nanonav.policy import (
    MAX_Q,
    UNVISITED,
    GreedyState,
    UnusablePolicy,
    chemotaxis,
    fit_problem,
    greedy_table,
    habits,
    learned_policy,
    swarm_table,
)
from nanonav.scenario import Cells, Learning, Rewards, Robots, Scenario
from nanonav.store import JobNotFound, JobStatus, ResultsUnavailable

STATES = ["s0", "s1", "s2"]
ACTIONS = ["a", "b", "c"]


def scenario(**fields: Any) -> Scenario:
    return Scenario.model_validate({"learning": {"episodes": 0}, "policy_from": 7, **fields})


def stored(actions: str, robots: int | None = None, fill: float = 0.5) -> dict[str, NDArray[Any]]:
    """A table as a job stores it: shared, or one per robot."""
    states, labels = qlearning.labels(actions)
    shape = (len(states), len(labels)) if robots is None else (robots, len(states), len(labels))
    return {
        "states": np.array(states, dtype=np.str_),
        "actions": np.array(labels, dtype=np.str_),
        "values": np.full(shape, fill),
        "visits": np.ones(shape, dtype=np.int64),
    }


# ---------------------------------------------------------------- the greedy table


def test_each_state_names_its_best_action_with_its_value_and_visits() -> None:
    values = np.array([[0.1, 2.5, -1.0], [-3.0, -2.0, -0.5], [0.0, 0.0, 0.0]])
    visits = np.array([[3, 4, 1], [0, 2, 5], [0, 0, 0]])
    table = greedy_table(STATES, ACTIONS, values, visits)
    assert table[0] == GreedyState("s0", "b", 2.5, 8, True, [], 2.4)
    assert table[1] == GreedyState("s1", "c", -0.5, 7, True, [], 1.5)
    assert table[1].to_dict() == {
        "state": "s1",
        "action": "c",
        "value": -0.5,
        "visits": 7,
        "learned": True,
        "ties": [],
        "gap": 1.5,
    }


def test_a_state_never_visited_with_a_zero_row_names_no_action() -> None:
    values = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    visits = np.array([[1, 0, 0], [0, 0, 0], [0, 0, 0]])
    table = greedy_table(STATES, ACTIONS, values, visits)
    assert [(g.action, g.learned, g.value, g.visits) for g in table[1:]] == [
        (UNVISITED, False, None, 0),
        (UNVISITED, False, None, 0),
    ]


def test_ties_name_the_first_and_list_every_tied_action() -> None:
    values = np.array([[1.0, -1.0, 1.0], [0.0, 0.0, 0.0], [2.0, 2.0, 2.0]])
    visits = np.array([[1, 1, 1], [2, 0, 0], [1, 1, 1]])
    table = greedy_table(STATES, ACTIONS, values, visits)
    assert (table[0].action, table[0].ties) == ("a", ["a", "c"])
    # visited, still all zeros: learned, and every action is as good
    assert (table[1].action, table[1].learned, table[1].ties) == ("a", True, ["a", "b", "c"])
    assert table[2].ties == ["a", "b", "c"] and table[2].value == 2.0


def test_a_row_from_another_job_is_learned_though_this_run_never_visited_it() -> None:
    values = np.array([[0.0, 0.0, 0.3], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    table = greedy_table(STATES, ACTIONS, values, np.zeros((3, 3), dtype=np.int64))
    assert table[0] == GreedyState("s0", "c", 0.3, 0, True, [], 0.3)


def test_per_robot_tables_are_averaged_by_visits() -> None:
    values = np.array(
        [
            [[4.0, 1.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]],
            [[0.0, 2.0, 0.0], [0.0, 5.0, 0.0], [0.0, 0.0, 0.0]],
        ]
    )
    visits = np.array(
        [
            [[1, 3, 0], [0, 0, 0], [0, 0, 0]],
            [[0, 1, 0], [0, 2, 0], [0, 0, 0]],
        ]
    )
    mean, total = swarm_table(values, visits)
    # robot 1 never chose a in s0: its 0 is no evidence, so a keeps robot 0's 4.0;
    # b is (3 x 1.0 + 1 x 2.0) / 4 = 1.25; c was chosen by no robot: the plain mean, 0
    np.testing.assert_allclose(mean[0], [4.0, 1.25, 0.0])
    np.testing.assert_array_equal(total[0], [1, 4, 0])
    table = greedy_table(STATES, ACTIONS, values, visits)
    assert table[0] == GreedyState("s0", "a", 4.0, 5, True, [], 2.75)
    assert table[1] == GreedyState("s1", "b", 5.0, 2, True, [], 5.0)
    assert table[2].action == UNVISITED


def test_per_robot_tables_evaluated_unvisited_keep_their_plain_mean() -> None:
    values = np.array([[[1.0, 3.0, 0.0]], [[1.0, -1.0, 0.0]]])
    mean, _ = swarm_table(values, np.zeros((2, 1, 3), dtype=np.int64))
    np.testing.assert_allclose(mean, [[1.0, 1.0, 0.0]])
    assert greedy_table(["s0"], ACTIONS, values, np.zeros((2, 1, 3), dtype=np.int64))[0].ties == [
        "a",
        "b",
    ]


def test_per_robot_tables_of_any_finite_size_have_a_finite_mean() -> None:
    biggest = np.finfo(np.float64).max
    values = np.array([[[biggest, -biggest, 1.0]], [[biggest, -biggest, 3.0]]])
    for visits in (np.zeros((2, 1, 3), dtype=np.int64), np.full((2, 1, 3), 2**40)):
        mean, _ = swarm_table(values, visits)
        np.testing.assert_array_equal(mean, [[biggest, -biggest, 2.0]])
    weighted, _ = swarm_table(values, np.array([[[0, 0, 3]], [[0, 0, 1]]]))
    assert weighted[0, 2] == 1.5
    assert greedy_table(["s0"], ACTIONS, values, np.ones((2, 1, 3), dtype=np.int64))[0] == (
        GreedyState("s0", "a", float(biggest), 6, True, [], float(biggest))
    )
    extremes = np.array([[biggest, -biggest, -biggest]])
    assert greedy_table(["s0"], ACTIONS, extremes, np.ones((1, 3), dtype=np.int64))[0].gap == (
        biggest  # the gap is kept finite, as JSON needs it
    )


def _bound(model: type[BaseModel], name: str) -> float:
    """The largest magnitude the field ``name`` of ``model`` takes."""
    metadata = model.model_fields[name].metadata
    return max(
        abs(float(getattr(m, attr))) for m in metadata for attr in ("ge", "le") if hasattr(m, attr)
    )


def test_the_bound_on_sent_values_is_far_beyond_what_any_job_learns() -> None:
    # each update raises the largest |Q| by at most the largest reward of one step (MAX_Q):
    # the distance a step closes is a robot's move and a cell's (ten sd of its walk per axis)
    closed = 2000.0
    assert _bound(Robots, "speed") + 10 * np.sqrt(3) * _bound(Cells, "motion_std") < closed
    reward = sum(_bound(Rewards, name) for name in ("reach", "collision", "step"))
    reward += _bound(Rewards, "approach") * closed
    updates = _bound(Robots, "count") * _bound(Learning, "max_steps") * _bound(Learning, "episodes")
    assert reward * updates < MAX_Q / 1e4


# ---------------------------------------------------------------- which tables fit


def test_a_shared_table_fits_shared_and_per_robot_learners_of_its_action_set() -> None:
    table = stored("directions")
    directions = {"actions": "directions", "episodes": 0}
    assert fit_problem(scenario(learning=directions), 7, table) is None
    per_robot = {**directions, "shared_table": False}
    assert fit_problem(scenario(learning=per_robot, robots={"count": 5}), 7, table) is None


def test_a_table_of_the_other_action_set_does_not_fit() -> None:
    problem = fit_problem(scenario(), 7, stored("directions"))
    assert problem == (
        "job 7 learned the 'directions' actions and this scenario uses 'behaviors': "
        "learning.actions must be the same"
    )


def test_a_per_robot_table_needs_per_robot_learners_and_as_many_robots() -> None:
    table = stored("behaviors", robots=3)
    shared = fit_problem(scenario(robots={"count": 3}), 7, table)
    assert shared is not None and "learning.shared_table must be false" in shared
    own = {"episodes": 0, "shared_table": False}
    fewer = fit_problem(scenario(robots={"count": 2}, learning=own), 7, table)
    assert fewer is not None and "each of its 3 robots and this scenario has 2" in fewer
    assert fit_problem(scenario(robots={"count": 3}, learning=own), 7, table) is None


def test_no_table_or_a_table_of_other_labels_or_shape_does_not_fit() -> None:
    assert fit_problem(scenario(), 7, {}) == "job 7 learned no Q-table: only q_learning jobs do"
    renamed = {**stored("behaviors"), "actions": np.array(["up", "down"], dtype=np.str_)}
    assert "not those of any action set" in str(fit_problem(scenario(), 7, renamed))
    fewer_states = {**stored("behaviors"), "states": np.array(["s0"], dtype=np.str_)}
    assert "another version" in str(fit_problem(scenario(), 7, fewer_states))
    wrong_shape = {**stored("behaviors"), "values": np.zeros((72, 3))}
    assert "the shape (72, 3)" in str(fit_problem(scenario(), 7, wrong_shape))


def test_learned_policy_reads_the_named_job_and_says_why_it_cannot() -> None:
    table = stored("behaviors", fill=1.5)

    def read(job_id: int | str) -> dict[str, NDArray[Any]]:
        if job_id == 7:
            return table
        if job_id == 8:
            raise ResultsUnavailable(8, JobStatus.FAILED)
        raise JobNotFound(cast(int, job_id))  # this test names jobs by number only

    values = learned_policy(scenario(), read)
    assert isinstance(values, np.ndarray)
    assert values.shape == (72, 4) and float(values[0, 0]) == 1.5
    with pytest.raises(UnusablePolicy, match=r"^there is no job 9$"):
        learned_policy(scenario(policy_from=9), read)
    with pytest.raises(UnusablePolicy, match="job 8 is failed: only a succeeded job's table"):
        learned_policy(scenario(policy_from=8), read)
    with pytest.raises(UnusablePolicy, match="'behaviors' actions and this scenario uses"):
        learned_policy(scenario(learning={"episodes": 0, "actions": "directions"}), read)


def test_chemotaxis_counts_visited_gradient_states_whose_greedy_move_climbs() -> None:
    states, actions = qlearning.labels("directions")
    values = np.zeros((len(states), len(actions)))
    visits = np.zeros_like(values, dtype=np.int64)
    up_x = actions.index("move(+x,0y,0z)")
    down_x = actions.index("move(-x,0y,0z)")
    climbing = states.index("grad=(+x,0y,0z)|obstacle=clear")
    backwards = states.index("grad=(+x,+y,0z)|obstacle=near")
    flat = states.index("grad=(0x,0y,0z)|obstacle=clear")
    for state, action in ((climbing, up_x), (backwards, down_x), (flat, down_x)):
        values[state, action] = 1.0
        visits[state, action] = 3
    found = chemotaxis(states, actions, values, visits)
    assert (found.agree, found.states, found.share) == (1, 2, 0.5)  # the flat state has no sign
    assert (found.strict_agree, found.strict_share) == (1, 0.5)
    # one axis sensed: 9 of the 26 moves have a positive component; two axes: 9 too
    assert found.chance == pytest.approx(9 / 26) and found.strict_chance == pytest.approx(1 / 26)
    clear = chemotaxis(states, actions, values, visits, near_obstacles=False)
    assert (clear.agree, clear.states) == (1, 1)
    assert chemotaxis(states, actions, values, np.zeros_like(visits)).share is None


def test_a_table_of_random_greedy_moves_climbs_at_its_chance_level() -> None:
    states, actions = qlearning.labels("directions")
    rng = np.random.default_rng(5)
    values = rng.random((len(states), len(actions)))
    visits = np.ones_like(values, dtype=np.int64)
    found = chemotaxis(states, actions, values, visits)
    assert found.chance is not None and 0.34 < found.chance < 0.39
    assert found.share is not None and found.strict_share is not None
    # a few dozen states: the random table's shares lie within a few standard errors of chance
    tolerance = 4 * np.sqrt(found.chance * (1 - found.chance) / found.states)
    assert abs(found.share - found.chance) < tolerance
    assert found.strict_share < 0.2


# ---------------------------------------------------------------- habits over seeds


def _kept(values: list[list[float]], visits: list[list[int]]) -> dict[str, np.ndarray]:
    return {
        "states": np.array(STATES, dtype=np.str_),
        "actions": np.array(ACTIONS, dtype=np.str_),
        "values": np.array(values, dtype=np.float64),
        "visits": np.array(visits, dtype=np.int64),
    }


def test_habits_count_each_tables_greedy_action_in_the_most_visited_states() -> None:
    one = _kept([[1.0, 0.0, 0.0], [0.0, 2.0, 0.5], [0.0, 0.0, 0.0]],
                [[5, 0, 0], [10, 10, 10], [0, 0, 0]])  # fmt: skip
    two = _kept([[0.0, 0.0, 3.0], [0.0, 1.0, 0.9], [0.0, 0.0, 0.0]],
                [[1, 1, 3], [20, 0, 0], [0, 0, 0]])  # fmt: skip
    other = {**_kept([[9.0] * 3] * 3, [[9] * 3] * 3), "states": np.array(["x", "y", "z"])}
    found = habits([one, two, other], top=2)
    assert [h.state for h in found] == ["s1", "s0"]  # 50 visits, then 10 (s2: none)
    assert found[0].visit_share == pytest.approx(50 / 60)
    assert found[0].greedy == {"b": 2}
    assert found[0].mean_gap == pytest.approx((1.5 + 0.1) / 2)
    assert found[1].greedy == {"a": 1, "c": 1}
    assert habits([], top=3) == [] and habits([other], top=3)[0].state in {"x", "y", "z"}
