"""A Q-table as data: the greedy action of every state, whether a table fits a run, and the
checks a table made elsewhere passes before it is kept as a policy.

These functions read the arrays a job stores (``states``, ``actions``, ``values``, ``visits``)
or a policy was sent with, and touch no database: the API shows the greedy table, checks a sent
table and checks ``policy_from`` at submit, and the worker checks it again before the run, with
the same rule.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, get_args

import numpy as np
from numpy.typing import NDArray

from nanonav.engine import qlearning
from nanonav.engine.observations import (
    BODY_GRADIENT_LABELS,
    OBSERVATION_LABELS,
    observation_of,
    possible_observations,
)
from nanonav.scenario import (
    ActionSet,
    CommunicationModel,
    Scenario,
    Steering,
)
from nanonav.scenario.work import REMEMBERS_AT_ONCE, decides_at_once
from nanonav.store.errors import JobNotFound, ResultsUnavailable
from nanonav.store.models import JobStatus
from nanonav.store.policies import (
    NETWORK,
    PolicyNotFound,
    PolicyRecord,
    PolicySource,
    policy_number,
)

UNVISITED = "unvisited"
ACTION_SETS: tuple[ActionSet, ...] = get_args(ActionSet)
COMMUNICATION_MODELS: tuple[CommunicationModel, ...] = get_args(CommunicationModel)
# A policy holds one table every robot starts from, or one per robot, at most this many.
MAX_TABLES = 1000
# The largest |Q| a sent table may hold. An update of eq. 2.7 moves Q(s, a) toward
# r + gamma max Q(s', .) by alpha, both at most 1, so it raises the table's largest |Q| by at
# most the largest |r| of a step: reach, collision and step rewards of at most 1e6 each, and
# 1e6 per length unit closed toward a cell, of which a step closes far under 2000 (a robot
# moves at most 100, a cell's random walk has at most 10 per axis, the cube's side is at most
# 1000), so under 2e9. A job makes at most robots x max_steps x episodes <= 1e16 updates: a
# table it learns from zeros stays under 2e25, one it learns from a sent table moves at most
# that far from it. The bound keeps means over robots and pictures' colour scales finite.
MAX_Q = 1e30
# The rules a sent table may break, as a 422 types them: labels that are no layout's, and
# values or greedy choices that do not fill the layout's table.
LAYOUT_RULE = "policy_layout"
TABLE_RULE = "policy_table"

TableReader = Callable[[PolicySource], Mapping[str, NDArray[Any]]]


@dataclass(frozen=True)
class Layout:
    """What a Q-table's rows and columns are: the states a robot senses and the actions it
    takes, with ``actions`` under ``communication`` (``qlearning.labels``). Models that sense
    the same states share a layout (the attractant's and the attractant and repellent's)."""

    actions: ActionSet
    communication: tuple[CommunicationModel, ...]
    state_labels: tuple[str, ...]
    action_labels: tuple[str, ...]

    @property
    def title(self) -> str:
        """How a message names it: ``'behaviors' with communication.model 'none'``."""
        if self.actions not in qlearning.SIGNAL_ACTION:
            return f"'{self.actions}'"
        return f"'{self.actions}' with communication.model {_either(self.communication)}"


def _layouts() -> tuple[Layout, ...]:
    """Every layout a scenario can learn or evaluate: an action set that cannot follow signals
    (``directions``) is used without communication only."""
    found: dict[tuple[ActionSet, tuple[str, ...], tuple[str, ...]], list[CommunicationModel]] = {}
    for action_set in ACTION_SETS:
        signals = action_set in qlearning.SIGNAL_ACTION
        for model in COMMUNICATION_MODELS if signals else ("none",):
            states, actions = qlearning.labels(action_set, model)
            found.setdefault((action_set, tuple(states), tuple(actions)), []).append(model)
    return tuple(
        Layout(action_set, tuple(models), states, actions)
        for (action_set, states, actions), models in found.items()
    )


LAYOUTS = _layouts()
MAX_STATES = max(len(layout.state_labels) for layout in LAYOUTS)
MAX_ACTIONS = max(len(layout.action_labels) for layout in LAYOUTS)


def _either(names: Sequence[str]) -> str:
    """``'a'``, ``'a' or 'b'``, ``'a', 'b' or 'c'``."""
    quoted = [f"'{name}'" for name in names]
    return quoted[0] if len(quoted) == 1 else ", ".join(quoted[:-1]) + " or " + quoted[-1]


def _named(source: PolicySource) -> tuple[str, str]:
    """How messages name what a ``policy_from`` names, and the verb for what its table holds."""
    if isinstance(source, str):
        return f"policy {policy_number(source)}", "has"
    return f"job {source}", "learned"


@dataclass(frozen=True)
class GreedyState:
    """What a greedy robot does in one state."""

    state: str
    action: str  # the label of the best action, or UNVISITED
    value: float | None  # its Q; None when unvisited
    visits: int  # times any action was chosen in this state
    learned: bool  # False: never visited and all zeros, so no action is preferred
    ties: list[str]  # every action sharing the best value when there are several
    # the action gap: the best Q minus the next best (0 when tied); None when unvisited or with
    # one action. How much the choice matters to the learner: a small gap is a choice made by
    # noise or by visits (Tallec, Blier & Ollivier 2019).
    gap: float | None = None

    def to_dict(self) -> dict[str, Any]:
        return {
            "state": self.state,
            "action": self.action,
            "value": self.value,
            "visits": self.visits,
            "learned": self.learned,
            "ties": self.ties,
            "gap": self.gap,
        }


def swarm_table(
    values: NDArray[np.float64], visits: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """One ``(states, actions)`` table: a shared one as it is; per-robot tables ``(robots,
    states, actions)`` as the mean over robots weighted by each pair's visits (a robot's value
    for a pair it never chose is its starting value, not something learned), the plain mean
    for a pair no robot chose, and visits summed.

    Each value is scaled by its weight before the sum, and the mean kept within the robots'
    least and largest value, as a mean is: values of any finite size give a finite mean."""
    values = np.asarray(values, dtype=np.float64)
    visits = np.asarray(visits, dtype=np.int64)
    if values.ndim == 2:
        return values, visits
    total = visits.sum(axis=0)
    weighted = (values * (visits / np.maximum(total, 1))).sum(axis=0)
    plain = (values / values.shape[0]).sum(axis=0)
    mean = np.where(total > 0, weighted, plain)
    return np.clip(mean, values.min(axis=0), values.max(axis=0)), total


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
        gap = None
        if len(row) > 1:
            # kept finite: a table at the float range's ends would otherwise give inf
            gap = min(best - float(np.sort(row)[-2]), float(np.finfo(np.float64).max))
        found.append(
            GreedyState(
                state, tied[0], best, state_visits, True, tied if len(tied) > 1 else [], gap
            )
        )
    return found


class UnusablePolicy(ValueError):
    """A ``policy_from`` whose table cannot drive the scenario; the message says why."""


def fit_problem(
    scenario: Scenario, source: PolicySource, table: Mapping[str, NDArray[Any]]
) -> str | None:
    """Why the table ``table`` that ``source`` names (a job's learned one, or a policy's) cannot
    be evaluated in ``scenario``, or None when it fits.

    It fits when its labels are those the engine has now for the scenario's action set and
    communication model (its layout), and its shape fits the learners: a shared table fits
    shared or per-robot learners (every robot starts from it), a per-robot table needs
    per-robot learners and the same number of robots."""
    name, verb = _named(source)
    if "model" in table:
        return _network_problem(scenario, name, table)
    if "values" not in table:
        return f"{name} learned no Q-table: only q_learning jobs do"
    wanted = scenario.learning.actions
    communication = scenario.communication.model
    states, actions = qlearning.labels(wanted, communication)
    table_states, table_actions = table["states"].tolist(), table["actions"].tolist()
    same_actions, problem = _action_set_problem(name, verb, table_actions, wanted)
    if problem is not None:
        return problem
    if table_states != states or table_actions != actions:
        layout = next((la for la in same_actions if list(la.state_labels) == table_states), None)
        if layout is None:
            sensed = f"'{wanted}'" + (
                "" if communication == "none" else f" and communication.model '{communication}'"
            )
            return (
                f"{name}'s table has {len(table_states)} states that are not the {len(states)} "
                f"this engine senses with {sensed}; it was made by another version"
            )
        models = layout.communication
        return (
            f"{name}'s table is laid out for communication.model {_either(models)} and this "
            f"scenario's is '{communication}': communication.model must be "
            + ("the same" if len(models) == 1 else "one of them")
        )
    shape = table["values"].shape
    if shape[-2:] != (len(states), len(actions)) or len(shape) not in (2, 3):
        return f"{name}'s table has the shape {shape}, not (states, actions) of '{wanted}'"
    if len(shape) == 3:
        robots = scenario.robots.count
        if scenario.learning.shared_table:
            return (
                f"{name} {verb} a table per robot and this scenario's robots share one: "
                "learning.shared_table must be false"
            )
        if shape[0] != robots:
            return (
                f"{name} {verb} a table for each of its {shape[0]} robots and this "
                f"scenario has {robots}: robots.count must be the same"
            )
    return None


def _action_set_problem(
    name: str, verb: str, given: list[str], wanted: str
) -> tuple[list[Layout], str | None]:
    """The layouts whose actions are ``given``, and why they are not the scenario's action set
    ``wanted`` (None when they are): a table's and a network's actions alike."""
    same = [layout for layout in LAYOUTS if list(layout.action_labels) == given]
    if not same:
        return same, f"{name}'s actions are not those of any action set this engine knows"
    if same[0].actions != wanted:
        return same, (
            f"{name} {verb} the '{same[0].actions}' actions and this scenario uses "
            f"'{wanted}': learning.actions must be the same"
        )
    return same, None


def _network_problem(
    scenario: Scenario, name: str, table: Mapping[str, NDArray[Any]]
) -> str | None:
    """Why a network cannot decide for ``scenario``'s robots, or None when it can: it must
    choose among the scenario's actions, from what its robots observe."""
    wanted = scenario.learning.actions
    communication = scenario.communication.model
    actions = qlearning.labels(wanted, communication)[1]
    given = table["actions"].tolist()
    steering = steering_of(given)
    if steering == "continuous":
        if scenario.physics.model != "active_brownian":
            return (
                f"{name} steers by a continuous turn ({', '.join(given)}): physics.model must "
                "be 'active_brownian'"
            )
    elif given != actions:
        same, problem = _action_set_problem(name, "chooses among", given, wanted)
        if problem is not None:
            return problem
        models = sorted({model for layout in same for model in layout.communication})
        return (
            f"{name} chooses among actions laid out for communication.model {_either(models)} "
            f"and this scenario's is '{communication}': communication.model must be the same"
        )
    if int(table.get("memory", np.zeros(())).sum()) and not decides_at_once(scenario):
        return f"{name} has a memory: {REMEMBERS_AT_ONCE}"
    observed = list(observation_of(scenario, steering).labels)
    reads = table["observation"].tolist()
    if reads != observed:
        return (
            f"{name} reads ({', '.join(reads)}) and this scenario's robots observe "
            f"({', '.join(observed)}): physics.model and communication.model must be those "
            "it was trained in"
        )
    return None


@dataclass(frozen=True)
class Network:
    """A network a ``policy_from`` names: its ONNX model, what it reads and chooses, and the
    multiply-adds an observation its check counted (None for one kept before costs were
    counted: its job's check counts them)."""

    model: bytes
    observation: tuple[str, ...]
    actions: tuple[str, ...]
    multiply_adds: int | None = None


def learned_policy(scenario: Scenario, read: TableReader) -> NDArray[np.float64] | Network:
    """What ``scenario.policy_from`` names: the values of a Q-table, for ``simulate(policy=)``,
    or a network, for ``rl.evaluate``.

    ``read`` is how a stored table is read (``JobStore.qtable``, which reads a job's or a
    policy's). Raises ``UnusablePolicy`` when the job or policy does not exist, the job has not
    succeeded, or the table or network does not fit."""
    source = scenario.policy_from
    if source is None:
        raise ValueError("the scenario names no policy_from")
    name, _ = _named(source)
    try:
        table = read(source)
    except (JobNotFound, PolicyNotFound):
        raise UnusablePolicy(f"there is no {name}") from None
    except ResultsUnavailable as error:
        if error.status is JobStatus.SUCCEEDED:
            raise UnusablePolicy(f"{name} stored no results") from None
        raise UnusablePolicy(
            f"{name} is {error.status.value}: only a succeeded job's table can be evaluated"
        ) from None
    problem = fit_problem(scenario, source, table)
    if problem is not None:
        raise UnusablePolicy(problem)
    if "model" in table:
        counted = table.get("cost_multiply_adds")
        return Network(
            table["model"].tobytes(),
            tuple(table["observation"].tolist()),
            tuple(table["actions"].tolist()),
            None if counted is None else int(counted),
        )
    values: NDArray[np.float64] = np.asarray(table["values"], dtype=np.float64)
    return values


# ---------------------------------------------------------------- a table made elsewhere


class InvalidPolicy(ValueError):
    """A table sent as a policy that the engine could not evaluate. ``loc`` is the field at
    fault in what was sent (``("states",)``, ``("greedy", 3, "state")``), ``rule`` the rule
    broken (``LAYOUT_RULE`` or ``TABLE_RULE``)."""

    def __init__(self, loc: tuple[str | int, ...], message: str, rule: str) -> None:
        super().__init__(message)
        self.loc = loc
        self.rule = rule


def layout_of(states: Sequence[str], actions: Sequence[str]) -> Layout:
    """The layout whose state and action labels ``states`` and ``actions`` are, in order;
    ``InvalidPolicy`` naming the one that is not, and saying what would be."""
    states, actions = list(states), list(actions)
    same_actions = [layout for layout in LAYOUTS if list(layout.action_labels) == actions]
    if not same_actions:
        raise InvalidPolicy(("actions",), _actions_problem(actions), LAYOUT_RULE)
    for layout in same_actions:
        if list(layout.state_labels) == states:
            return layout
    raise InvalidPolicy(("states",), _states_problem(states, same_actions), LAYOUT_RULE)


def _actions_problem(actions: list[str]) -> str:
    kinds: dict[tuple[str, ...], list[Layout]] = {}
    for layout in LAYOUTS:
        kinds.setdefault(layout.action_labels, []).append(layout)
    for labels, layouts in kinds.items():
        if sorted(labels) == sorted(actions):
            return (
                f"these are the actions of {_actions_title(layouts)} in another order: the "
                f"columns must be in the engine's order, {', '.join(labels)}"
            )
    known = "; ".join(
        f"{_actions_title(layouts)}: {len(labels)} ({_preview(labels)})"
        for labels, layouts in kinds.items()
    )
    return f"{len(actions)} actions that are not those of any action set; the engine's are {known}"


def _actions_title(layouts: Sequence[Layout]) -> str:
    """What layouts that share their actions have in common: the action set, and with a
    follow-the-signal action, a communication model."""
    action_set = layouts[0].actions
    models = [model for layout in layouts for model in layout.communication]
    if models == ["none"] or action_set not in qlearning.SIGNAL_ACTION:
        return f"'{action_set}'"
    return f"'{action_set}' with communication.model {_either(models)}"


def _states_problem(states: list[str], layouts: Sequence[Layout]) -> str:
    for layout in layouts:
        if sorted(layout.state_labels) == sorted(states):
            return (
                f"these are the states of {layout.title} in another order: the rows must be in "
                f"the engine's order ({_preview(layout.state_labels)})"
            )
    for layout in layouts:
        if len(layout.state_labels) == len(states):
            pairs = zip(states, layout.state_labels, strict=True)
            i = next(i for i, (given, known) in enumerate(pairs) if given != known)
            return (
                f"states[{i}] is {states[i]!r} where the {len(states)} states of {layout.title} "
                f"have {layout.state_labels[i]!r}: the rows must be the engine's states, in its "
                "order"
            )
    sizes = " or ".join(f"{len(la.state_labels)} ({la.title})" for la in layouts)
    return (
        f"{len(states)} states, and the actions are those of {_actions_title(layouts)}, whose "
        f"layouts have {sizes}"
    )


def _preview(labels: Sequence[str]) -> str:
    shown = list(labels) if len(labels) <= 6 else [*labels[:3], "...", labels[-1]]
    return ", ".join(shown)


def policy_values(layout: Layout, values: Sequence[Any]) -> NDArray[np.float64]:
    """``values``, nested lists shaped states x actions (or robots x states x actions, one
    table per robot) of ``layout``, as an array; ``InvalidPolicy`` at ``values`` when a row
    or a table has the wrong length, there are over ``MAX_TABLES`` tables, or a value is not
    a finite number within +-``MAX_Q``."""
    states, actions = len(layout.state_labels), len(layout.action_labels)
    per_robot = len(values) > 0 and len(values[0]) > 0 and np.ndim(values[0][0]) > 0
    tables = values if per_robot else [values]
    if len(tables) > MAX_TABLES:
        detail = f"values has {len(tables)} tables, over the {MAX_TABLES} a policy may hold"
        raise InvalidPolicy(("values",), detail, TABLE_RULE)
    for r, table in enumerate(tables):
        where = f"values[{r}]" if per_robot else "values"
        if len(table) != states:
            detail = (
                f"{where} has {len(table)} rows where {layout.title} has {states} states: a "
                "table is states x actions, or robots x states x actions"
            )
            raise InvalidPolicy(("values",), detail, TABLE_RULE)
        for i, row in enumerate(table):
            if np.ndim(row) != 1 or len(row) != actions:
                detail = f"{where}[{i}] is not a row of {actions} values, one per action"
                raise InvalidPolicy(("values",), detail, TABLE_RULE)
    array = np.asarray(values, dtype=np.float64)
    wrong = np.argwhere(~(np.abs(array) <= MAX_Q))
    if wrong.size:
        index = tuple(int(i) for i in wrong[0])
        where = "values" + "".join(f"[{i}]" for i in index)
        value = float(array[index])
        detail = (
            f"{where} is {value}: every value must be a finite number"
            if not np.isfinite(value)
            else f"{where} is {value:g}: every value must be within +-{MAX_Q:g}, beyond what "
            "any job learns"
        )
        raise InvalidPolicy(("values",), detail, TABLE_RULE)
    return array


def greedy_values(layout: Layout, choices: Sequence[tuple[str, str]]) -> NDArray[np.float64]:
    """A table of ``layout`` whose greedy action in each state is the one ``choices`` pairs it
    with: 1.0 there and 0 elsewhere; a row of zeros (no action preferred) for a state paired
    with ``UNVISITED`` or left out. ``InvalidPolicy`` at ``("greedy", i, "state")`` or
    ``"action"`` for a label the layout does not have, or a state given twice."""
    rows = {label: i for i, label in enumerate(layout.state_labels)}
    columns = {label: a for a, label in enumerate(layout.action_labels)}
    table = np.zeros((len(rows), len(columns)))
    given: dict[str, int] = {}
    for k, (state, action) in enumerate(choices):
        if state not in rows:
            detail = (
                f"{state!r} is not a state of {layout.title}, whose "
                f"{len(rows)} states are {_preview(layout.state_labels)}"
            )
            raise InvalidPolicy(("greedy", k, "state"), detail, TABLE_RULE)
        if state in given:
            detail = f"{state!r} is given twice: at greedy/{given[state]} too"
            raise InvalidPolicy(("greedy", k, "state"), detail, TABLE_RULE)
        given[state] = k
        if action == UNVISITED:
            continue
        if action not in columns:
            detail = (
                f"{action!r} is neither an action of {layout.title} "
                f"({', '.join(layout.action_labels)}) nor '{UNVISITED}'"
            )
            raise InvalidPolicy(("greedy", k, "action"), detail, TABLE_RULE)
        table[rows[state], columns[action]] = 1.0
    return table


# ---------------------------------------------------------------- a network made elsewhere


@dataclass(frozen=True)
class NetworkLayout:
    """What a network decides from and among: the observation columns it reads (an
    environment's ``observation_labels``) and the actions it chooses (``action_labels``), and
    the action set and communication models whose scenarios give both."""

    actions: ActionSet
    communication: tuple[CommunicationModel, ...]
    observation: tuple[str, ...]
    action_labels: tuple[str, ...]


def observed_communication(observation: Sequence[str]) -> tuple[CommunicationModel, ...]:
    """The communication models whose robots observe the signal columns ``observation`` has:
    a net signal and its change (the chemical ones), the signal alone (broadcast), or neither."""
    if "signal_change" in observation:
        return ("attractant", "attractant_repellent")
    return ("broadcast",) if "signal" in observation else ("none",)


def steering_of(actions: Sequence[str]) -> Steering:
    """How a network with these actions steers: by a continuous turn when they are its two
    parts (``qlearning.TURN_ACTIONS``), else by the action set's numbers."""
    return "continuous" if list(actions) == qlearning.TURN_ACTIONS else "discrete"


def observed_physics(observation: Sequence[str]) -> str:
    """The physics whose robots observe ``observation``: only the lattice's sense a gradient
    without steering up it."""
    return "lattice" if "gradient_x" in observation else "active_brownian"


def network_layout(observation: Sequence[str], actions: Sequence[str]) -> NetworkLayout:
    """The layout of a network that reads ``observation`` and chooses among ``actions``, in
    order; ``InvalidPolicy`` at ``observation`` or ``actions`` saying what would be.

    An observation is some of ``OBSERVATION_LABELS``, in their order (a scenario leaves out
    the columns it never fills; a network that turns reads the gradient in the body frame,
    ``BODY_GRADIENT_LABELS``); which are there is checked against each scenario that names
    the network."""
    observation, actions = list(observation), list(actions)
    continuous = steering_of(actions) == "continuous"
    known = list(OBSERVATION_LABELS)
    if continuous:
        at = known.index("gradient_x")
        known[at : at + 3] = BODY_GRADIENT_LABELS
        same_actions = [layout for layout in LAYOUTS if layout.actions == "steering"]
    else:
        same_actions = [layout for layout in LAYOUTS if list(layout.action_labels) == actions]
    if not same_actions:
        raise InvalidPolicy(("actions",), _actions_problem(actions), LAYOUT_RULE)
    order = {label: i for i, label in enumerate(known)}
    places = [order.get(label, -1) for label in observation]
    if -1 in places or places != sorted(set(places)):
        detail = (
            f"({', '.join(observation)}) is no robot's observation: an environment's "
            f"observation_labels are some of ({', '.join(known)}), in that order"
        )
        raise InvalidPolicy(("observation",), detail, LAYOUT_RULE)
    if "signal_change" in observation and "signal" not in observation:
        detail = "a robot that observes signal_change observes the signal too"
        raise InvalidPolicy(("observation",), detail, LAYOUT_RULE)
    heard = observed_communication(observation)
    models = [m for layout in same_actions for m in layout.communication if m in heard]
    if not models:
        detail = (
            f"robots that observe ({', '.join(observation)}) communicate by {_either(heard)}, "
            f"and the actions are those of {_actions_title(same_actions)}"
        )
        raise InvalidPolicy(("observation",), detail, LAYOUT_RULE)
    possible = possible_observations("continuous" if continuous else "discrete")
    if tuple(observation) not in possible:
        given = set(observation)
        nearest = sorted(possible, key=lambda labels: (len(given ^ set(labels)), len(labels)))
        shown = " or ".join(f"({', '.join(labels)}) in {_either(possible[labels])}"
                            for labels in nearest[:2])  # fmt: skip
        detail = (
            f"no scenario's robots observe ({', '.join(observation)}): a lattice robot reads "
            "the gradient's three axes, an active_brownian one none unless it steers "
            f"continuously (then in its body's frame); the nearest they observe are {shown}"
        )
        raise InvalidPolicy(("observation",), detail, LAYOUT_RULE)
    if continuous:
        models = list(dict.fromkeys(heard))  # a turn is the same whatever a robot receives
    return NetworkLayout(same_actions[0].actions, tuple(models), tuple(observation), tuple(actions))


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


def evaluation_scenario(
    policy: PolicyRecord, observation: Sequence[str] | None = None
) -> dict[str, Any]:
    """The smallest scenario that evaluates ``policy`` without learning: its action set
    (steering, in active_brownian physics), its first communication model, and with a table per
    robot, as many robots each with its own; a network's physics from its ``observation``, its
    robots deciding at once; the rest is left to defaults."""
    learning: dict[str, Any] = {"episodes": 0, "actions": policy.action_set}
    scenario: dict[str, Any] = {"policy_from": policy.policy_from, "learning": learning}
    if policy.action_set == "steering" or (
        observation is not None and observed_physics(observation) == "active_brownian"
    ):
        scenario["physics"] = {"model": "active_brownian"}
    if policy.communication[0] != "none":
        scenario["communication"] = {"model": policy.communication[0]}
    if policy.kind == NETWORK:
        scenario["robots"] = {"schedule": "simultaneous"}  # every robot decided at once
    if policy.per_robot:
        scenario["robots"] = {"count": policy.tables}
        learning["shared_table"] = False
    return scenario


@dataclass(frozen=True)
class Habit:
    """What the tables of several runs of one scenario (a study's seeds) do in one state they
    visit: how often it is visited, and the greedy action there counted over the tables."""

    state: str
    visit_share: float  # of every visit of every table
    greedy: dict[str, int]  # action -> tables whose greedy action it is (learned ones only)
    mean_gap: float | None  # the action gap, mean over those tables; None if none learned it


def habits(tables: Sequence[Mapping[str, NDArray[Any]]], top: int) -> list[Habit]:
    """The ``top`` states that ``tables`` (each with ``states``, ``actions``, ``values`` and
    ``visits``, as a job keeps its Q-table) visit most, visits summed over the tables, each with
    the greedy action counted over them: a learned policy read across seeds, which one table
    alone cannot say (science.py's table 4b). Tables with other state labels than the first are
    left out; none learned or none given: an empty list."""
    usable = [t for t in tables if len(t.get("states", ())) and len(t.get("values", ()))]
    if not usable:
        return []
    states = [str(s) for s in usable[0]["states"]]
    same = [t for t in usable if [str(s) for s in t["states"]] == states]
    rows = [
        greedy_table(states, [str(a) for a in t["actions"]], t["values"], t["visits"]) for t in same
    ]
    visits = np.array([[g.visits for g in row] for row in rows], dtype=np.float64).sum(axis=0)
    total = float(visits.sum())
    if total <= 0.0:
        return []
    found = []
    for index in np.argsort(-visits, kind="stable")[:top]:
        learned = [row[index] for row in rows if row[index].learned]
        counted: dict[str, int] = {}
        for g in learned:
            counted[g.action] = counted.get(g.action, 0) + 1
        gaps = [g.gap for g in learned if g.gap is not None]
        found.append(
            Habit(
                states[index],
                float(visits[index]) / total,
                dict(sorted(counted.items(), key=lambda kv: -kv[1])),
                float(np.mean(gaps)) if gaps else None,
            )
        )
    return found
