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
UNCONTROLLED = 6  # active Brownian: swims along its own diffusing heading, never steers
EXACT_GRADIENT = 7  # active Brownian: steers by the true gradient (an upper bound)
STEER_AND_TUMBLE = 8  # active Brownian: steers up the sensed gradient, tumbles as run_and_tumble
BLIND_TUMBLE = 9  # active Brownian: tumbles at one rate whatever it reads (uses no information)
POLICY_CODES = {"q_learning": Q_LEARNING, "gradient": GRADIENT, "run_and_tumble": RUN_AND_TUMBLE,
                "random": RANDOM, "rule": RULE, "simple_rule": SIMPLE_RULE,
                "uncontrolled": UNCONTROLLED, "exact_gradient": EXACT_GRADIENT,
                "steer_and_tumble": STEER_AND_TUMBLE, "blind_tumble": BLIND_TUMBLE}  # fmt: skip
BEHAVIORS = 0
DIRECTIONS = 1
STEERING = 2
ACTION_SET_CODES = {"behaviors": BEHAVIORS, "directions": DIRECTIONS, "steering": STEERING}
LATTICE = 0
ACTIVE_BROWNIAN = 1
PHYSICS_CODES = {"lattice": LATTICE, "active_brownian": ACTIVE_BROWNIAN}
NO_SIGNAL = 0
ATTRACTANT = 1
ATTRACTANT_REPELLENT = 2
BROADCAST = 3
COMMUNICATION_CODES = {
    "none": NO_SIGNAL,
    "attractant": ATTRACTANT,
    "attractant_repellent": ATTRACTANT_REPELLENT,
    "broadcast": BROADCAST,
}
ALPHA_CONSTANT = 0
ALPHA_VISITS = 1
ALPHA_SCHEDULE_CODES = {"constant": ALPHA_CONSTANT, "visits": ALPHA_VISITS}
# The order of a step's phases over the robots (PettingZoo's names): robot i perceives, decides
# and acts before robot i + 1 perceives (AEC), or every robot perceives, then every robot acts
# (parallel).
SEQUENTIAL = 0
SIMULTANEOUS = 1
SCHEDULE_CODES = {"sequential": SEQUENTIAL, "simultaneous": SIMULTANEOUS}


class KernelParams(NamedTuple):
    """Constants of one episode, flattened from the scenario for the compiled code."""

    model: int
    weight: float
    length: float
    softening: float
    noise: float
    half: float
    cell_std: float  # per-axis sd of a cell's step: cells.motion_std, or sqrt(2 D_cell dt)
    cell_margin: float  # a cell's centre stays this far from an obstacle's
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
    # active Brownian physics (um, s, nM); in the lattice physics these keep their defaults
    physics: int = LATTICE
    jiggle: float = 0.0  # sqrt(2 D_T dt), um: the sd of each axis's Brownian displacement
    heading_sigma: float = 0.0  # Rayleigh scale of the heading's rotation per step
    turn: float = 0.0  # the largest commanded turn per step, rad
    robot_radius: float = 0.0  # um
    counting: float = 0.0  # pi D_m a dt N_A: a reading of c nM counts counting * c molecules
    tumble: float = 0.0  # run_and_tumble: chance of a tumble per step, reading not rising
    tumble_rising: float = 0.0  # and while it rises
    memory_weight: float = 1.0  # dt / memory_s: how fast the reading's memory follows it
    # sensor 'counted': molecules are counted every ``window`` steps (the integration time), a
    # receptor patch taking in, on average in a step, ``patch_rate`` * c of them at c nM at the
    # body's centre and ``patch_gradient_rate`` * g more with a gradient g (nM/um) toward it
    counted: bool = False
    window: int = 1
    patch_rate: float = 0.0
    patch_gradient_rate: float = 0.0
    # the weight of a new count's gradient in the held one (1: it replaces it)
    gradient_weight: float = 1.0
    # dt / short_memory_s: how fast the recent mean follows the reading (1: it is the reading)
    recent_weight: float = 1.0
    # cells that can be treated, robots that take up space, and signals (issue: the swarm)
    capacity: int = 0  # payloads that treat a cell; 0: never treated
    treated_secretion: float = 0.0  # share of its field a treated cell keeps
    exclusion: bool = False  # robots keep ``contact`` apart (centre to centre)
    contact: float = 0.0
    signal: int = NO_SIGNAL
    signal_states: int = 1  # values of the Q-learning state's 'signal' dimension
    signal_every: int = 1  # engine steps per update of the signal's grid
    signal_substeps: int = 1  # solver steps per update
    signal_diffusion: float = 0.0  # per engine step (length^2)
    signal_decay: float = 0.0  # rate per engine step
    signal_release: float = 0.0  # amount one bound robot releases per engine step
    signal_threshold: float = 0.0  # a net signal above it is received
    signal_counting: float = 0.0  # active Brownian: molecules counted per nM of signal read
    # sensor 'counted': what a receptor patch takes in of a signal in a step, per nM at the
    # body's centre and per nM/um toward it (its counts share the biomarker's ``window``)
    signal_patch_rate: float = 0.0
    signal_patch_gradient_rate: float = 0.0
    signal_origin: float = 0.0
    signal_spacing: float = 1.0
    signal_dims: int = 1
    broadcast_range: float = 0.0
    schedule: int = SEQUENTIAL
    # steps a decision by action number (the Q-learner's, or an environment's agent's) is held:
    # the decision interval in steps (active Brownian); 1 in the lattice and for fixed rules
    hold: int = 1
    # active Brownian, driven from outside: robots steer by a continuous turn in their body
    # frame (``dynamics.brownian.turn_in_body``) and observe their sensed gradient in that frame
    turning: bool = False


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
    blocked: NDArray[np.bool_]  # its last move was stopped by an obstacle
    sensed: NDArray[np.float64]  # the reading it took this step (with noise)
    # sensor 'counted': the gradient its last count gave, (N, 3), world frame, held as
    # ``sensed`` is until the next count
    sensed_grad: NDArray[np.float64]
    # its readings' mean over physics.short_memory_s, compared with prev_conc's longer one
    recent: NDArray[np.float64]
    # sensor 'counted': the molecules each receptor patch (+x, -x, +y, -y, +z, -z) takes in on
    # average over the count's window so far, summed step by step along the robot's path, and
    # (column WINDOW_STEPS) the window's steps so far
    window_flux: NDArray[np.float64]


class World(NamedTuple):
    """The environment's moving parts and the field's sources."""

    cells: NDArray[np.float64]  # (C, 3)
    obstacles: NDArray[np.float64]  # (O, 3)
    offsets: NDArray[np.float64]  # (K, 3) emitter offsets from their cell
    sx: NDArray[np.float64]  # (K,) source positions
    sy: NDArray[np.float64]
    sz: NDArray[np.float64]


class Social(NamedTuple):
    """What robots do to and with each other, per robot: kept apart from ``Swarm`` because every
    compiled function handed a tuple pays for each array in it, and most need none of these."""

    bound_to: NDArray[np.int64]  # the cell it delivered its payload to, -1 while it carries it
    bumps: NDArray[np.int64]  # moves refused because another robot was in the way
    signal: NDArray[np.float64]  # the net signal it read last (attractant - repellent)
    prev_signal: NDArray[np.float64]  # and the reading before (sensor 'counted': the count)
    # sensor 'counted': the net signal's gradient its last count gave, (N, 3), world frame
    signal_grad: NDArray[np.float64]
    # sensor 'counted': what each species' six receptor patches took in so far in the window,
    # species by species (``SIGNAL_PATCHES`` columns each), then (column ``SIGNAL_STEPS``)
    # the window's steps so far
    signal_flux: NDArray[np.float64]
    message: NDArray[np.float64]  # (N, 3) broadcast: the position it was sent
    has_message: NDArray[np.bool_]


class Treatment(NamedTuple):
    """The cells' treatment: payloads received, when each was treated, and the treated cells'
    sources (whose field is taken off again in part: ``fields.sample_many``)."""

    load: NDArray[np.int64]  # (C,) payloads each cell received
    treated_at: NDArray[np.int64]  # (C,) the step it was treated, -1 while untreated
    tx: NDArray[np.float64]  # (K,) the treated cells' sources, the first treated_sources[0]
    ty: NDArray[np.float64]
    tz: NDArray[np.float64]
    treated_sources: NDArray[np.int64]  # (1,)


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
    heading: NDArray[np.float64]  # (R, N, 3) in the active Brownian physics, else (0, N, 3)
    sensed: NDArray[np.float64]  # (R, N) the reading each robot took, likewise (0, N)
    load: NDArray[np.int64]  # (R, C) payloads each cell had received
    signal: NDArray[
        np.float64
    ]  # (R, N) the net signal each robot read, with communication, else (0, N)


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
EV_CELL = 10  # the cell it delivered to, -1 if none
EV_BUMPS = 11  # moves refused by another robot
EV_COLUMNS = 12

# cell_tallies[world, cell, ...] columns written when an evaluation episode ends
CELL_LOAD = 0  # payloads received
CELL_TREATED_AT = 1  # the step it was treated, -1 if never
CELL_COLUMNS = 2

# curve[episode, ...] columns written by the kernel when an episode ends
CURVE_STEPS = 0
CURVE_REACHED = 1
CURVE_RETURN = 2
CURVE_COLLISIONS = 3
CURVE_ROBOT_STEPS = 4
CURVE_TREATED = 5  # cells treated by the episode's end
CURVE_COLUMNS = 6
