"""What a robot observes, as plain data and pure functions: the engine's columns
(``OBS_*``), their names, their bounds in a scenario's units, and which of them a scenario's
robots fill (``observation_of``); with the names of the actions and states. The API's schemas,
the policies' layouts and the environments read them without loading the compiled engine."""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from typing import Any, NamedTuple, get_args

import numpy as np
from numpy.typing import NDArray

from nanonav.engine import qlearning
from nanonav.scenario import CommunicationModel, PhysicsModel, Scenario, Steering

# The observation's columns: what the tabular state is built from, before it is cut into levels.
OBS_READING = 0  # the reading it took (with the sensor's noise; 0 below the detection threshold)
OBS_CHANGE = 1  # the reading minus the last (lattice, 0 at first) or its memory (brownian)
OBS_GRADIENT = 2  # 2, 3, 4: the sensed gradient (x, y, z); 0 in active_brownian (read when steered)
OBS_OBSTACLE = 5  # lattice: distance to the nearest obstacle's surface, capped at the sensing
# radius; active_brownian: 1 if its last move was stopped by an obstacle, else 0
OBS_CELL = 6  # distance to the nearest untreated cell (active_brownian: between their surfaces),
# capped at the cell sensor's range (the cap: none sensed)
OBS_SIGNAL = 7  # the net signal it read (attractant - repellent), or 1 while a message waits
OBS_SIGNAL_CHANGE = 8  # minus the last net signal (0 with broadcast or without communication)
FEATURES = 9

OBSERVATION_LABELS = (
    "reading",
    "reading_change",
    "gradient_x",
    "gradient_y",
    "gradient_z",
    "obstacle",
    "cell",
    "signal",
    "signal_change",
)
# The gradient's columns where robots steer continuously: read each step in the body frame.
BODY_GRADIENT_LABELS = ("gradient_forward", "gradient_side", "gradient_up")

# The bound of a column with none (as Gymnasium's CartPole bounds its velocities): finite, so
# that a learner may normalise by it.
UNBOUNDED = float(np.finfo(np.float32).max)


def as_scenario(scenario: Scenario | Mapping[str, Any] | None) -> Scenario:
    """A scenario from a ``Scenario``, its JSON as a mapping (validated as the API does), or
    None (the defaults)."""
    if isinstance(scenario, Scenario):
        return scenario
    return Scenario.model_validate(dict(scenario or {}))


def with_robots(scenario: Scenario, count: int) -> Scenario:
    """``scenario`` with ``count`` robots (validated again: a count that does not fit is
    refused as a scenario would be)."""
    if scenario.robots.count == count:
        return scenario
    data = scenario.model_dump(mode="json")
    data["robots"]["count"] = count
    return Scenario.model_validate(data)


def _bounds(
    scenario: Scenario, steering: Steering
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(low, high) of each engine column (``OBS_*``) in this scenario's units
    (``column_bounds`` of what sets them)."""
    return column_bounds(
        scenario.physics.model,
        steering,
        scenario.communication.model,
        scenario.robots.sensing_radius,
        scenario.robots.cell_sensing_radius,
    )


def column_bounds(
    physics: PhysicsModel,
    steering: Steering,
    communication: CommunicationModel,
    sensing_radius: float,
    cell_sensing_radius: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(low, high) of each engine column (``OBS_*``) of robots of ``physics`` steered
    so, that communicate by ``communication`` and sense obstacles and cells within those
    radii: readings, gradients and signals are unbounded (``UNBOUNDED``; a noise floor can
    read below 0), the distances are capped at the sensors' ranges, the obstacle contact of
    active_brownian is 0 or 1; a column never filled is 0 to 0 (active_brownian's gradient,
    unless robots steer continuously)."""
    low = np.full(FEATURES, -UNBOUNDED)
    high = np.full(FEATURES, UNBOUNDED)
    brownian = physics == "active_brownian"
    low[OBS_OBSTACLE] = 0.0
    high[OBS_OBSTACLE] = 1.0 if brownian else sensing_radius
    low[OBS_CELL] = 0.0
    high[OBS_CELL] = cell_sensing_radius
    if brownian and steering == "discrete":
        low[OBS_GRADIENT : OBS_GRADIENT + 3] = 0.0
        high[OBS_GRADIENT : OBS_GRADIENT + 3] = 0.0
    if communication == "none":
        low[OBS_SIGNAL:] = 0.0
        high[OBS_SIGNAL:] = 0.0
    elif communication == "broadcast":
        low[OBS_SIGNAL] = 0.0
        high[OBS_SIGNAL] = 1.0
        low[OBS_SIGNAL_CHANGE] = 0.0
        high[OBS_SIGNAL_CHANGE] = 0.0
    return low, high


def _labels(low: NDArray[np.float64], high: NDArray[np.float64], steering: Steering) -> tuple[
    NDArray[np.int64], tuple[str, ...]
]:  # fmt: skip
    """The columns a robot fills (those whose bounds differ) and their names."""
    columns = np.flatnonzero(low != high)
    names = list(OBSERVATION_LABELS)
    if steering == "continuous":
        names[OBS_GRADIENT : OBS_GRADIENT + 3] = BODY_GRADIENT_LABELS
    return columns, tuple(names[c] for c in columns)


def possible_observations(steering: Steering) -> dict[tuple[str, ...], tuple[PhysicsModel, ...]]:
    """Every observation some scenario's robots make, steered so, and the physics whose
    robots make it: with each communication model, with obstacles and cells sensed or not (a
    radius of 0), in each physics that steers so (only active_brownian's robots turn
    continuously)."""
    found: dict[tuple[str, ...], list[PhysicsModel]] = {}
    physics: tuple[PhysicsModel, ...] = (
        ("active_brownian",) if steering == "continuous" else get_args(PhysicsModel)
    )
    for model, communication, obstacle, cell in itertools.product(
        physics, get_args(CommunicationModel), (0.0, 1.0), (0.0, 1.0)
    ):
        low, high = column_bounds(model, steering, communication, obstacle, cell)
        labels = _labels(low, high, steering)[1]
        if model not in found.setdefault(labels, []):
            found[labels].append(model)
    return {labels: tuple(models) for labels, models in found.items()}


class Observation(NamedTuple):
    """What a robot's observation holds in a scenario: the engine's columns it keeps (those the
    scenario fills), their names, and their bounds."""

    columns: NDArray[np.int64]
    labels: tuple[str, ...]
    low: NDArray[np.float64]
    high: NDArray[np.float64]


def observation_of(scenario: Scenario, steering: Steering = "discrete") -> Observation:
    """The observation of a robot of ``scenario`` steered so (``OBSERVATION_LABELS`` says what
    each column is; a column the scenario never fills, such as the signal without
    communication, is left out). A robot that steers continuously reads its sensed gradient
    each step along its heading, side and up axes, and observes the mean of its readings since
    its last decision (``BODY_GRADIENT_LABELS``)."""
    low, high = _bounds(scenario, steering)
    columns, labels = _labels(low, high, steering)
    return Observation(columns, labels, low[columns], high[columns])


def action_labels(scenario: Scenario, steering: Steering = "discrete") -> list[str]:
    """The scenario's action set, in the order the ``Discrete`` action numbers them; steering
    continuously, the two parts of a turn (``qlearning.TURN_ACTIONS``)."""
    if steering == "continuous":
        return list(qlearning.TURN_ACTIONS)
    return qlearning.labels(scenario.learning.actions, scenario.communication.model)[1]


def state_labels(scenario: Scenario) -> list[str]:
    """The tabular states (``info["state"]`` indexes them), as ``/qtable`` names them."""
    return qlearning.labels(scenario.learning.actions, scenario.communication.model)[0]
