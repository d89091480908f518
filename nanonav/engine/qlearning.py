"""The Q-learning vocabulary: states, actions, their labels, and the exploration schedule.

The kernel encodes a state as a mixed-radix index over the dimensions listed here; the labels
are built in the same order, so ``labels[i]`` names the state the kernel calls ``i``.
"""

from __future__ import annotations

import itertools

import numpy as np
from numpy.typing import NDArray

from nanonav.scenario import Learning

# The 'behaviors' action set (paper 2.5).
FOLLOW_GRADIENT = 0
APPROACH_CELL = 1
AVOID_OBSTACLE = 2
EXPLORE = 3
BEHAVIOR_ACTIONS = ["follow_gradient", "approach_cell", "avoid_obstacle", "explore"]
# With a communication model, one more action in either set: follow what the robot receives
# (up the attractant, down the repellent, toward a message), and one more state dimension, last.
FOLLOW_SIGNAL = 4
STEER_TO_SIGNAL = 4
SIGNAL_ACTION = {"behaviors": "follow_signal", "steering": "steer_to_signal"}
CHEMICAL_SIGNALS = ["none", "attractant_rising", "attractant_falling", "repellent"]
RADIO_SIGNALS = ["none", "message"]

# State dimensions of the 'behaviors' set, in index order (most significant first).
CONCENTRATION_LEVELS = ["trace", "low", "mid", "high"]
TRENDS = ["falling", "rising"]
OBSTACLE_PROXIMITY = ["none", "sensed", "near"]
CELL_PROXIMITY = ["none", "sensed", "near"]
# Concentration levels are cut at the lone-cell profile's value at these multiples of the
# sensing radius: beyond 3x is 'trace', within 0.5x is 'high'.
LEVEL_DISTANCES = (3.0, 1.5, 0.5)

# The 'directions' action set: the 26 lattice directions, unit length.
LATTICE = np.array([d for d in itertools.product((-1, 0, 1), repeat=3) if any(d)], dtype=np.float64)
DIRECTIONS: NDArray[np.float64] = LATTICE / np.linalg.norm(LATTICE, axis=1, keepdims=True)
SIGNS = ["-", "0", "+"]
OBSTACLE_NEAR = ["clear", "near"]
# A gradient component counts as non-zero when it carries at least this share of the norm
# (sin 22.5 degrees: the gradient then lies within the lattice direction's cone).
SIGN_THRESHOLD = 0.3827


# The 'steering' action set of active Brownian robots, which cannot choose where they will be,
# only turn their own diffusing heading (at most physics.max_turn_rate_rad_s).
KEEP_HEADING = 0
STEER_UP_GRADIENT = 1  # toward the sensed (noisy) spatial gradient
TUMBLE = 2  # a new heading at random
STEER_TO_CELL = 3  # toward a cell within the receptor range, else as keep_heading
# A continuous turn in the body frame, by an agent outside (``Worlds(steering="continuous")``);
# no table learns it, so it is no action number of any set.
TURN = 5
TURN_ACTIONS = ["turn_side", "turn_up"]
STEERING_ACTIONS = ["keep_heading", "steer_up_gradient", "tumble", "steer_to_cell"]
OBSTACLE_CONTACT = ["clear", "touching"]  # touching: the last move was stopped by an obstacle
CELL_SENSED = ["none", "sensed"]
# The steering state's levels are cut at the lone cell's field at these multiples of its
# radius from its centre.
STEERING_LEVEL_RADII = (6.0, 3.0, 1.5)


def _axis_label(v: float) -> str:
    return "0" if v == 0 else ("+" if v > 0 else "-")


DIRECTION_ACTIONS = [
    "move(" + ",".join(f"{_axis_label(v)}{axis}" for v, axis in zip(d, "xyz", strict=True)) + ")"
    for d in LATTICE
]


def behavior_states() -> list[str]:
    return [
        f"conc={c}|trend={t}|obstacle={o}|cell={k}"
        for c, t, o, k in itertools.product(
            CONCENTRATION_LEVELS, TRENDS, OBSTACLE_PROXIMITY, CELL_PROXIMITY
        )
    ]


def direction_states() -> list[str]:
    return [
        f"grad=({sx}x,{sy}y,{sz}z)|obstacle={o}"
        for sx, sy, sz, o in itertools.product(SIGNS, SIGNS, SIGNS, OBSTACLE_NEAR)
    ]


def steering_states() -> list[str]:
    return [
        f"conc={c}|trend={t}|obstacle={o}|cell={k}"
        for c, t, o, k in itertools.product(
            CONCENTRATION_LEVELS, TRENDS, OBSTACLE_CONTACT, CELL_SENSED
        )
    ]


def signal_states(communication: str) -> list[str]:
    """What a robot can receive under a communication model (none: no such dimension)."""
    if communication == "none":
        return []
    return RADIO_SIGNALS if communication == "broadcast" else CHEMICAL_SIGNALS


def labels(actions: str, communication: str = "none") -> tuple[list[str], list[str]]:
    """(state labels, action labels) of an action set, and with a communication model its
    'signal' dimension (the least significant) and its follow-the-signal action."""
    if actions == "behaviors":
        states, names = behavior_states(), BEHAVIOR_ACTIONS
    elif actions == "steering":
        states, names = steering_states(), STEERING_ACTIONS
    else:
        return direction_states(), DIRECTION_ACTIONS
    received = signal_states(communication)
    if not received:
        return states, names
    return (
        [f"{state}|signal={r}" for state in states for r in received],
        [*names, SIGNAL_ACTION[actions]],
    )


# Without a decay factor given, epsilon reaches its floor after this share of training episodes.
FLOOR_AT = 0.8
# An exponential decay never reaches 0: a floor of 0 is reached, in effect, at this rate.
NEGLIGIBLE_EPSILON = 1e-3


def epsilon_decay(learning: Learning) -> float:
    """The per-episode factor: the one given, or the one that reaches the floor after
    ``FLOOR_AT`` of the training episodes."""
    if learning.epsilon_decay is not None:
        return learning.epsilon_decay
    floor = max(learning.epsilon_end, NEGLIGIBLE_EPSILON)
    if learning.epsilon_start <= floor:
        return 1.0
    episodes = max(1.0, FLOOR_AT * learning.episodes)
    return float((floor / learning.epsilon_start) ** (1.0 / episodes))


def epsilon(learning: Learning, episode: int) -> float:
    """Exploration rate of training episode ``episode``: exponential decay to a floor."""
    return max(learning.epsilon_end, learning.epsilon_start * epsilon_decay(learning) ** episode)
