"""The arrays one episode runs on, grouped for the compiled kernel, and the codes that stand
for the scenario's choices inside it."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

Q_LEARNING = 0
GRADIENT = 1
RUN_AND_TUMBLE = 2
RANDOM = 3
RULE = 4
SIMPLE_RULE = 5
POLICY_CODES = {"q_learning": Q_LEARNING, "gradient": GRADIENT, "run_and_tumble": RUN_AND_TUMBLE,
                "random": RANDOM, "rule": RULE, "simple_rule": SIMPLE_RULE}  # fmt: skip
BEHAVIORS = 0
DIRECTIONS = 1
ACTION_SET_CODES = {"behaviors": BEHAVIORS, "directions": DIRECTIONS}
ALPHA_CONSTANT = 0
ALPHA_VISITS = 1
ALPHA_SCHEDULE_CODES = {"constant": ALPHA_CONSTANT, "visits": ALPHA_VISITS}


class KernelParams(NamedTuple):
    """Constants of one episode, flattened from the scenario for the compiled code."""

    model: int
    weight: float
    length: float
    softening: float
    noise: float
    half: float
    cell_std: float
    obstacle_radius: float
    obstacle_std: float
    speed: float
    sensing_radius: float
    reach_distance: float
    policy: int
    action_set: int
    shared: bool
    learn: bool  # the policy learns (q_learning) in training episodes
    alpha: float
    gamma: float
    reward_reach: float
    reward_collision: float
    reward_approach: float
    level_1: float
    level_2: float
    level_3: float
    max_steps: int
    record_stride: int
    emitter_scatter: float
    noise_floor: float  # additive noise on a concentration reading (concentration units)
    gradient_noise: float  # additive noise on each sensed gradient component
    detection_threshold: float  # readings below it are read as nothing
    cell_sensing_radius: float  # a cell within it is sensed (its position)
    reward_step: float
    alpha_schedule: int
    alpha_exponent: float
    cell_extent: float  # cells start within this share of the half-width
    walls: bool  # the cube's walls reflect robots, cells and obstacles
    robot_corner: bool  # robots start in the (-,-,-) octant


class Swarm(NamedTuple):
    """Per-robot state arrays, all shaped ``(robots, ...)``."""

    pos: NDArray[np.float64]  # (N, 3)
    heading: NDArray[np.float64]  # (N, 3) unit vector of the last move
    active: NDArray[np.bool_]  # not yet reached a cell
    steps: NDArray[np.int64]  # steps taken while active
    prev_conc: NDArray[np.float64]  # last sensed concentration
    returns: NDArray[np.float64]  # summed reward
    collisions: NDArray[np.int64]
    path_length: NDArray[np.float64]
    pending: NDArray[np.bool_]  # a transition awaits its next state for the Q-update
    last_state: NDArray[np.int64]
    last_action: NDArray[np.int64]
    last_reward: NDArray[np.float64]
    start: NDArray[np.float64]  # (N, 3) start positions
    sum_conc: NDArray[np.float64]  # true concentration summed over the robot's steps
    sum_dist: NDArray[np.float64]  # distance to the nearest cell summed likewise
    last_dist: NDArray[np.float64]  # distance at the robot's last step
    reading: NDArray[np.float64]  # true concentration at the robot this step, before noise
    reading_grad: NDArray[np.float64]  # (N, 3) its gradient
    swept: NDArray[np.bool_]  # reached by a drifting cell while heading away from it


class World(NamedTuple):
    """The environment's moving parts and the field's sources."""

    cells: NDArray[np.float64]  # (C, 3)
    obstacles: NDArray[np.float64]  # (O, 3)
    offsets: NDArray[np.float64]  # (K, 3) emitter offsets from their cell
    sx: NDArray[np.float64]  # (K,) source positions
    sy: NDArray[np.float64]
    sz: NDArray[np.float64]


class Learner(NamedTuple):
    """Q-table(s) ``(tables, states, actions)`` with visit counts, and the lattice directions."""

    q: NDArray[np.float64]
    visits: NDArray[np.int64]
    directions: NDArray[np.float64]  # (26, 3)


class Recording(NamedTuple):
    """History of the evaluation episode, a row every ``record_stride`` steps and one for the
    last step: R = ceil(T / record_stride) + 1 rows, within ``simulate``'s ``record_bytes``."""

    pos: NDArray[np.float64]  # (R, N, 3)
    cells: NDArray[np.float64]  # (R, C, 3)
    obstacles: NDArray[np.float64]  # (R, O, 3) if obstacles move, else (1, O, 3)
    conc: NDArray[np.float64]  # (R, N)
    dist: NDArray[np.float64]  # (R, N)
    step: NDArray[np.int64]  # (R,) the step each row shows
    offsets: NDArray[np.float64]  # (K, 3) the recorded world's emitter offsets


# counters[] slots: where the run is, and what it has spent
ROBOT_STEPS = 0  # robot-steps simulated so far
LAYOUT_STATUS = 1  # non-zero when a world had no room (see world.draw_world)
EPISODE = 2  # the episode in progress (training episodes, then the evaluation)
STEP = 3  # its step
EPISODE_START = 4  # ROBOT_STEPS when it began
COUNTERS = 5

# evaluation[world, robot, ...] columns written by the kernel when an evaluation episode ends
EV_STEPS = 0  # steps the robot was active (to its reach, or the episode's end)
EV_REACHED = 1  # 1 if it reached a cell
EV_FINAL_DISTANCE = 2  # distance to the nearest cell at its last step
EV_SUM_DISTANCE = 3  # distance to the nearest cell summed over its steps 0..EV_STEPS
EV_SUM_CONCENTRATION = 4  # true concentration summed likewise
EV_COLLISIONS = 5
EV_PATH_LENGTH = 6
EV_STRAIGHT = 7  # straight-line distance from its start to where it ended
EV_RETURN = 8
EV_SWEPT = 9  # 1 if its cell drifted onto it while it headed elsewhere (it did not search it out)
EV_COLUMNS = 10

# curve[episode, ...] columns written by the kernel when an episode ends
CURVE_STEPS = 0
CURVE_REACHED = 1
CURVE_RETURN = 2
CURVE_COLLISIONS = 3
CURVE_ROBOT_STEPS = 4
CURVE_COLUMNS = 5
