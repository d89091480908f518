"""A learned Q-table as data: the greedy action of every state, and whether a table fits a run.

These functions read the arrays a job stores (``states``, ``actions``, ``values``, ``visits``)
and touch no database: the API shows the greedy table and checks ``policy_from`` at submit, and
the worker checks it again before the run, with the same rule.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from nanonav.engine import qlearning
from nanonav.scenario import ActionSet, Scenario
from nanonav.store.errors import JobNotFound, ResultsUnavailable
from nanonav.store.models import JobStatus

UNVISITED = "unvisited"
ACTION_SETS: tuple[ActionSet, ...] = ("behaviors", "directions")


@dataclass(frozen=True)
class GreedyState:
    """What a greedy robot does in one state."""

    state: str
    action: str  # the label of the best action, or UNVISITED
    value: float | None  # its Q; None when unvisited
    visits: int  # times any action was chosen in this state
    learned: bool  # False: never visited and all zeros, so no action is preferred
    ties: list[str]  # every action sharing the best value when there are several

    def to_dict(self) -> dict[str, Any]:
        return {
            "state": self.state,
            "action": self.action,
            "value": self.value,
            "visits": self.visits,
            "learned": self.learned,
            "ties": self.ties,
        }


def swarm_table(
    values: NDArray[np.float64], visits: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """One ``(states, actions)`` table: a shared one as it is; per-robot tables ``(robots,
    states, actions)`` as the mean over robots weighted by each pair's visits (a robot's value
    for a pair it never chose is its starting value, not something learned), the plain mean
    for a pair no robot chose, and visits summed."""
    values = np.asarray(values, dtype=np.float64)
    visits = np.asarray(visits, dtype=np.int64)
    if values.ndim == 2:
        return values, visits
    total = visits.sum(axis=0)
    weighted = (values * visits).sum(axis=0) / np.maximum(total, 1)
    return np.where(total > 0, weighted, values.mean(axis=0)), total


def greedy_table(
    states: Sequence[str],
    actions: Sequence[str],
    values: NDArray[np.float64],
    visits: NDArray[np.int64],
) -> list[GreedyState]:
    """The greedy action of every state, of a shared table or of the visit-weighted mean of
    per-robot tables (``swarm_table``).

    Ties are exact, as the engine compares values: the first tied action is named and all of
    them are listed (a greedy robot picks among them at random). A state never visited whose
    row is all zeros names no action: its argmax would be arbitrary. A row that is not all
    zeros counts as learned even unvisited: a table evaluated from another job keeps what that
    job learned, while its visits count only this run."""
    table, counts = swarm_table(values, visits)
    found = []
    for i, state in enumerate(states):
        row = table[i]
        state_visits = int(counts[i].sum())
        learned = state_visits > 0 or bool(np.any(row != 0.0))
        if not learned:
            found.append(GreedyState(state, UNVISITED, None, 0, False, []))
            continue
        best = float(row.max())
        tied = [actions[int(a)] for a in np.flatnonzero(row == best)]
        found.append(
            GreedyState(state, tied[0], best, state_visits, True, tied if len(tied) > 1 else [])
        )
    return found


class UnusablePolicy(ValueError):
    """A ``policy_from`` whose table cannot drive the scenario; the message says why."""


def _action_set(actions: Sequence[str]) -> str | None:
    for name in ACTION_SETS:
        if list(actions) == qlearning.labels(name)[1]:
            return name
    return None


def fit_problem(scenario: Scenario, job_id: int, table: Mapping[str, NDArray[Any]]) -> str | None:
    """Why job ``job_id``'s stored Q-table ``table`` cannot be evaluated in ``scenario``, or
    None when it fits.

    It fits when it was learned with the same action set (the same state and action labels as
    the engine has now) and its shape fits the learners: a shared table fits shared or
    per-robot learners (every robot starts from it), a per-robot table needs per-robot
    learners and the same number of robots."""
    if "values" not in table:
        return f"job {job_id} learned no Q-table: only q_learning jobs do"
    wanted = scenario.learning.actions
    states, actions = qlearning.labels(wanted)
    learned_with = _action_set(table["actions"].tolist())
    if learned_with is None:
        return f"job {job_id}'s actions are not those of any action set this engine knows"
    if learned_with != wanted:
        return (
            f"job {job_id} learned the '{learned_with}' actions and this scenario uses "
            f"'{wanted}': learning.actions must be the same"
        )
    if table["states"].tolist() != states:
        return (
            f"job {job_id}'s table has {len(table['states'])} states that are not the "
            f"{len(states)} this engine senses with '{wanted}'; it was learned by another version"
        )
    shape = table["values"].shape
    if shape[-2:] != (len(states), len(actions)) or len(shape) not in (2, 3):
        return f"job {job_id}'s table has the shape {shape}, not (states, actions) of '{wanted}'"
    if len(shape) == 3:
        robots = scenario.robots.count
        if scenario.learning.shared_table:
            return (
                f"job {job_id} learned a table per robot and this scenario's robots share one: "
                "learning.shared_table must be false"
            )
        if shape[0] != robots:
            return (
                f"job {job_id} learned a table for each of its {shape[0]} robots and this "
                f"scenario has {robots}: robots.count must be the same"
            )
    return None


def learned_table(
    scenario: Scenario, read: Callable[[int], Mapping[str, NDArray[Any]]]
) -> NDArray[np.float64]:
    """The values of the Q-table ``scenario.policy_from`` names, for ``simulate(policy=)``.

    ``read`` is how a stored table is read (``JobStore.qtable``). Raises ``UnusablePolicy``
    when the job does not exist, has not succeeded, or its table does not fit."""
    job_id = scenario.policy_from
    if job_id is None:
        raise ValueError("the scenario names no policy_from")
    try:
        table = read(job_id)
    except JobNotFound:
        raise UnusablePolicy(f"there is no job {job_id}") from None
    except ResultsUnavailable as error:
        if error.status is JobStatus.SUCCEEDED:
            raise UnusablePolicy(f"job {job_id} stored no results") from None
        raise UnusablePolicy(
            f"job {job_id} is {error.status.value}: only a succeeded job's table can be evaluated"
        ) from None
    problem = fit_problem(scenario, job_id, table)
    if problem is not None:
        raise UnusablePolicy(problem)
    values: NDArray[np.float64] = np.asarray(table["values"], dtype=np.float64)
    return values


@dataclass(frozen=True)
class Chemotaxis:
    """How many states that sense a gradient move up it: of ``states`` such visited states of a
    'directions' table, ``agree`` have a greedy move with a positive component along the sensed
    gradient's signs, and ``strict_agree`` a greedy move in the sensed direction itself (its
    sign on every axis, zero where the gradient has none). ``chance`` and ``strict_chance`` are
    what a greedy move drawn at random would score in the same states: a positive component
    is easy (9 or 10 of the 26 moves), the sensed direction is one move in 26."""

    agree: int
    states: int
    strict_agree: int = 0
    chance: float | None = None
    strict_chance: float | None = None

    @property
    def share(self) -> float | None:
        return self.agree / self.states if self.states else None

    @property
    def strict_share(self) -> float | None:
        return self.strict_agree / self.states if self.states else None


def _signs(label: str) -> NDArray[np.float64]:
    """(+1, 0, -1) per axis from a label such as ``grad=(+x,0y,-z)|...`` or ``move(+x,0y,-z)``."""
    inside = label[label.index("(") + 1 : label.index(")")]
    return np.array([{"+": 1.0, "-": -1.0, "0": 0.0}[part[0]] for part in inside.split(",")])


def chemotaxis(
    states: Sequence[str],
    actions: Sequence[str],
    values: NDArray[np.float64],
    visits: NDArray[np.int64],
    *,
    near_obstacles: bool = True,
) -> Chemotaxis:
    """Whether a learned 'directions' table climbs the gradient: in every visited state whose
    sensed gradient has a sign on some axis (with an obstacle near, too, unless
    ``near_obstacles`` is false), is the greedy move's dot product with those signs positive?"""
    table, counts = swarm_table(values, visits)
    moves = np.array([_signs(a) for a in actions])
    agree = strict = counted = 0
    chance = strict_chance = 0.0
    for index, label in enumerate(states):
        signs = _signs(label)
        if not signs.any() or counts[index].sum() == 0:
            continue
        if not near_obstacles and label.endswith("obstacle=near"):
            continue
        counted += 1
        greedy = moves[int(np.argmax(table[index]))]
        agree += bool(greedy @ signs > 0)
        strict += bool(np.array_equal(greedy, signs))
        chance += float(np.mean(moves @ signs > 0))
        strict_chance += float(np.mean(np.all(moves == signs, axis=1)))
    return Chemotaxis(
        agree=agree,
        states=counted,
        strict_agree=strict,
        chance=chance / counted if counted else None,
        strict_chance=strict_chance / counted if counted else None,
    )
