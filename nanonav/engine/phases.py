"""The phases of a world's step, each written once for both physics: ``advance`` the world,
``perceive`` (each robot senses and receives, or takes in a cell that drifted within reach),
``decide`` (an action from the robot's percept), ``act`` (the move, a bump, the reward of
paper 2.7, a delivery) and ``learn`` (the Q update of a transition).

``kernel`` runs them for ``simulate`` and ``stepping`` for the environments, under either
schedule (``state.SEQUENTIAL``: robot i perceives, decides and acts before robot i + 1
perceives; ``state.SIMULTANEOUS``: every robot perceives, then every robot acts). The physics
differ only inside the rooms that differ (``dynamics.lattice`` or ``dynamics.brownian``,
``sensing``, ``policies``); what a phase does with a robot is the same whoever decides: the
engine's own policies choose in ``decide``, an agent outside hands an action to ``command``.

Everything here is compiled once and inlined by LLVM into the compiled schedules
(``compiled.inlined``), which run without reference counting (``compiled.uncounted``), or is
uncounted itself: nothing here allocates, and arrays are indexed element by element.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from nanonav.engine import communication as radio_room
from nanonav.engine import treatment
from nanonav.engine.compiled import episodic, inlined, uncounted
from nanonav.engine.contacts import CellList, bumped_back, relist
from nanonav.engine.dynamics import brownian, lattice
from nanonav.engine.fields import SAMPLED_GAUSSIAN, place_sources, place_treated
from nanonav.engine.learning import q_update, q_update_bootstrapped
from nanonav.engine.observations import (
    FEATURES,
    OBS_CELL,
    OBS_CHANGE,
    OBS_GRADIENT,
    OBS_OBSTACLE,
    OBS_READING,
    OBS_SIGNAL,
    OBS_SIGNAL_CHANGE,
)
from nanonav.engine.policies import (
    NO_BEHAVIOR,
    baseline_action,
    behavior_direction,
    epsilon_greedy,
    steer,
    steering_baseline,
)
from nanonav.engine.qlearning import (
    AVOID_OBSTACLE,
    FOLLOW_SIGNAL,
    KEEP_HEADING,
    STEER_TO_CELL,
    STEER_TO_SIGNAL,
    STEER_UP_GRADIENT,
    TUMBLE,
    TURN,
)
from nanonav.engine.sensing import (
    WINDOW_STEPS,
    berg_purcell_reading,
    count_molecules,
    noisy_reading,
    sense_all,
    sensed_gradient,
    steering_state,
    tabular_state,
    take_in,
)
from nanonav.engine.state import (
    ACTIVE_BROWNIAN,
    BEHAVIORS,
    BROADCAST,
    EXACT_GRADIENT,
    LATTICE,
    NO_SIGNAL,
    Q_LEARNING,
    KernelParams,
    Learner,
    Recording,
    Social,
    Swarm,
    Treatment,
    World,
)

# clock[] slots of a world
CLOCK_STEP = 0  # the step the world is at
CLOCK_OVER = 1  # 1 once its episode is over
CLOCK_NEXT = 2  # sequential schedule, driven from outside: the robot whose turn it is (-1: none)
# driven from outside: 0 measures nothing (an env's worlds); MEASURED adds each step's true field
# and distance to the robots' sums as an evaluation does; RECORDED also keeps the history rows
CLOCK_MEASURE = 3
MEASURED = 1
RECORDED = 2
CLOCK_SLOTS = 4


class Percept(NamedTuple):
    """What every robot perceived this step, for the decision and the act that follow, and
    what it got since its last decision."""

    obs: NDArray[np.float64]  # (N, FEATURES)
    state: NDArray[np.int64]  # (N,) the tabular state
    heard: NDArray[np.int64]  # (N,) what it received (``communication``'s codes)
    target: NDArray[np.int64]  # (N,) the nearest untreated cell (-1 if none)
    target_d: NDArray[np.float64]  # (N,) its distance
    way: NDArray[np.float64]  # (N, 3) where what it receives points
    reward: NDArray[np.float64]  # (N,) reward since the last decision
    clock: NDArray[np.int64]  # (CLOCK_SLOTS,)
    held: NDArray[np.int64]  # (N,) the steering code held until the next decision
    turn: NDArray[np.float64]  # (N, 2) the continuous turn (side, up) held (``TURN``)
    side: NDArray[np.float64]  # (N, 3) the body's side axis (``brownian.body_frame``)


class Sim(NamedTuple):
    """One world's arrays (``simulate.episode_arrays`` makes them), its recording (empty where
    nothing is recorded) and its percept."""

    w: World
    s: Swarm
    so: Social
    tr: Treatment
    near: CellList
    radio: CellList
    everyone: NDArray[np.bool_]
    found: NDArray[np.int64]
    sig: NDArray[np.float64]
    sig_scratch: NDArray[np.float64]
    rec: Recording
    pc: Percept


def percept(robots: int) -> Percept:
    """An empty percept of ``robots`` robots."""
    return Percept(
        obs=np.zeros((robots, FEATURES)),
        state=np.zeros(robots, dtype=np.int64),
        heard=np.zeros(robots, dtype=np.int64),
        target=np.full(robots, -1, dtype=np.int64),
        target_d=np.zeros(robots),
        way=np.zeros((robots, 3)),
        reward=np.zeros(robots),
        clock=np.zeros(CLOCK_SLOTS, dtype=np.int64),
        held=np.zeros(robots, dtype=np.int64),
        turn=np.zeros((robots, 2)),
        side=np.zeros((robots, 3)),
    )


@inlined
def advance(p: KernelParams, rng: np.random.Generator, sim: Sim, t: int) -> None:
    """Advance the world into step ``t``: cells (and in the lattice, obstacles and emitters)
    move, the sources and the signal are placed, and the true field is read at every active
    robot."""
    w = sim.w
    tr = sim.tr
    if p.cell_std > 0.0:
        lattice.move_cells(p, rng, w)
    if p.physics == LATTICE:
        if p.obstacle_std > 0.0 and w.obstacles.shape[0] > 0:
            lattice.move_obstacles(p, rng, w, sim.s)
        if p.model == SAMPLED_GAUSSIAN:
            lattice.redraw_emitters(p, rng, w)
    place_sources(p.model, w.cells, w.offsets, w.sx, w.sy, w.sz)
    if p.capacity > 0:
        tr.treated_sources[0] = place_treated(
            p.model, w.cells, w.offsets, tr.treated_at, tr.tx, tr.ty, tr.tz
        )  # fmt: skip
    if p.signal != NO_SIGNAL and p.signal != BROADCAST and t % p.signal_every == 0:
        radio_room.update_field(p, sim.s.pos, sim.so.bound_to, tr.treated_at, sim.sig,
                                sim.sig_scratch)  # fmt: skip
    sense_all(p, w, sim.s, tr, sim.s.active)


@uncounted
def delivered(p: KernelParams, sim: Sim, i: int, cell: int, t: int) -> None:
    """Robot ``i`` reached ``cell`` in step ``t``: it delivers, is done, and broadcasts."""
    s = sim.s
    s.active[i] = False
    treatment.deliver(p, sim.tr, sim.so, i, cell, t + 1)
    if p.signal == BROADCAST:
        radio_room.broadcast(p, s.pos, s.active, sim.so, sim.radio, sim.found, i)


@uncounted
def body_gradient(p: KernelParams, rng: np.random.Generator, sim: Sim, i: int) -> None:
    """Robot ``i`` reads its spatial gradient (as ``steer_up_gradient`` does) along its
    heading, side and up axes, and its observation's gradient columns keep the mean of its
    readings since its last decision (one reading where it decides every step): a robot that
    holds a turn over an interval integrates its sensor over it, in its own frame. The side
    axis (``brownian.body_frame``) is kept for the turn it may then command."""
    s = sim.s
    pc = sim.pc
    t = pc.clock[CLOCK_STEP]
    kept = 0 if t == 0 else (t - 1) % p.hold  # readings already in the mean
    gx, gy, gz = sensed_gradient(p, rng, s, i)
    hx = s.heading[i, 0]
    hy = s.heading[i, 1]
    hz = s.heading[i, 2]
    ex, ey, ez, fx, fy, fz = brownian.body_frame(hx, hy, hz, pc.side[i, 0], pc.side[i, 1],
                                                 pc.side[i, 2])  # fmt: skip
    pc.side[i, 0] = ex
    pc.side[i, 1] = ey
    pc.side[i, 2] = ez
    forward = gx * hx + gy * hy + gz * hz
    side = gx * ex + gy * ey + gz * ez
    up = gx * fx + gy * fy + gz * fz
    obs = pc.obs
    if kept == 0:
        obs[i, OBS_GRADIENT] = forward
        obs[i, OBS_GRADIENT + 1] = side
        obs[i, OBS_GRADIENT + 2] = up
    else:
        share = 1.0 / (kept + 1)
        obs[i, OBS_GRADIENT] += share * (forward - obs[i, OBS_GRADIENT])
        obs[i, OBS_GRADIENT + 1] += share * (side - obs[i, OBS_GRADIENT + 1])
        obs[i, OBS_GRADIENT + 2] += share * (up - obs[i, OBS_GRADIENT + 2])


@uncounted
def body_turn(p: KernelParams, sim: Sim, i: int) -> None:
    """Robot ``i`` turns as the agent's turn of its decision says, held in the body frame (a
    steady turn). (Neither this nor ``body_gradient`` is inlined: only robots steered
    continuously call them, and inlined at every call site of ``act`` and ``perceive`` they
    would lengthen every schedule's compilation.)"""
    s = sim.s
    pc = sim.pc
    nx, ny, nz = brownian.turn_in_body(
        s.heading[i, 0], s.heading[i, 1], s.heading[i, 2], pc.side[i, 0], pc.side[i, 1],
        pc.side[i, 2], pc.turn[i, 0], pc.turn[i, 1], p.turn,
    )  # fmt: skip
    s.heading[i, 0] = nx
    s.heading[i, 1] = ny
    s.heading[i, 2] = nz


@inlined
def read_state(
    p: KernelParams, rng: np.random.Generator, sim: Sim, i: int, t: int, cell_d: float,
    full: bool,
) -> int:  # fmt: skip
    """Robot ``i`` takes its reading in step ``t`` (and in the lattice, its gradient; with
    sensor 'counted', a count in the steps that begin a window, held between): its observation's
    columns up to the signal's are written, and its tabular state without the signal returned.
    Unless ``full`` or the robot's policy learns, a lattice robot does not look for obstacles
    (no fixed rule needs the distance) and its state is 0."""
    s = sim.s
    obs = sim.pc.obs
    if p.physics == ACTIVE_BROWNIAN:
        fresh = True
        if not p.counted:
            s.sensed[i] = berg_purcell_reading(p, rng, s.reading[i])
        else:
            if s.prev_conc[i] < 0.0 and s.window_flux[i, WINDOW_STEPS] == 0.0:
                # a robot starts having counted a window where it starts, before the first step
                take_in(p, s, i, float(p.window))
            # a window's count is known once it has ended, then held; the next window starts
            fresh = s.window_flux[i, WINDOW_STEPS] >= p.window
            if fresh:
                count_molecules(p, rng, s, i, s.prev_conc[i] < 0.0)
            take_in(p, s, i, 1.0)
        c = s.sensed[i]
        recent = c
        if s.prev_conc[i] < 0.0:
            if fresh:
                s.prev_conc[i] = c  # the first reading starts the memories
                s.recent[i] = c
        elif p.recent_weight < 1.0:
            s.recent[i] += p.recent_weight * (c - s.recent[i])
            recent = s.recent[i]
        gap = cell_d - p.reach_distance
        obs[i, OBS_READING] = c
        # temporal sensing: the recent mean (or the reading) against the longer memory's (none
        # before the first count: a robot that has read nothing has seen nothing change)
        obs[i, OBS_CHANGE] = recent - s.prev_conc[i] if s.prev_conc[i] >= 0.0 else 0.0
        if p.turning:
            # a robot that turns by itself reads its gradient each step, in its body frame
            body_gradient(p, rng, sim, i)
        else:
            obs[i, OBS_GRADIENT] = 0.0
            obs[i, OBS_GRADIENT + 1] = 0.0
            obs[i, OBS_GRADIENT + 2] = 0.0
        obs[i, OBS_OBSTACLE] = 1.0 if s.blocked[i] else 0.0
        obs[i, OBS_CELL] = min(gap, p.cell_sensing_radius)
        rising = obs[i, OBS_CHANGE] > 0.0
        return steering_state(p, c, rising, s.blocked[i], gap <= p.cell_sensing_radius)
    c, gx, gy, gz = noisy_reading(p, rng, s, i)
    obs[i, OBS_READING] = c
    obs[i, OBS_CHANGE] = c - s.prev_conc[i] if s.prev_conc[i] >= 0.0 else 0.0
    obs[i, OBS_GRADIENT] = gx
    obs[i, OBS_GRADIENT + 1] = gy
    obs[i, OBS_GRADIENT + 2] = gz
    obs[i, OBS_CELL] = min(cell_d, p.cell_sensing_radius)
    if not full and p.policy != Q_LEARNING:
        return 0
    gap = lattice.nearest_obstacle(sim.w.obstacles, p.obstacle_radius, s.pos[i, 0], s.pos[i, 1],
                            s.pos[i, 2])[1]  # fmt: skip
    obs[i, OBS_OBSTACLE] = min(max(gap, 0.0), p.sensing_radius)
    return tabular_state(p, c, s.prev_conc[i], gx, gy, gz, gap, cell_d)


@inlined
def perceive(
    p: KernelParams, rng: np.random.Generator, sim: Sim, i: int, t: int, full: bool
) -> bool:  # fmt: skip
    """Robot ``i`` in step ``t``: a cell that drifted within reach is received (the robot
    spends its step so, and is done: returns False); otherwise it senses and receives, and its
    percept (observation, tabular state, nearest cell, what it heard and where that points) is
    written. ``full``: see ``read_state``."""
    s = sim.s
    so = sim.so
    pc = sim.pc
    w = sim.w
    px = s.pos[i, 0]
    py = s.pos[i, 1]
    pz = s.pos[i, 2]
    cell, cell_d = treatment.nearest_target(w.cells, sim.tr.treated_at, px, py, pz)
    if cell_d <= p.reach_distance:
        # Unless its last heading pointed at the cell, the cell found the robot (a robot parked
        # at a field maximum, say), not the robot the cell.
        toward = (
            s.heading[i, 0] * (w.cells[cell, 0] - px)
            + s.heading[i, 1] * (w.cells[cell, 1] - py)
            + s.heading[i, 2] * (w.cells[cell, 2] - pz)
        )
        s.swept[i] = toward <= 0.0
        s.steps[i] += 1
        s.returns[i] += p.reward_reach + p.reward_step
        pc.reward[i] += p.reward_reach + p.reward_step
        delivered(p, sim, i, cell, t)
        return False
    state = read_state(p, rng, sim, i, t, cell_d, full)
    heard = 0
    ux = 0.0
    uy = 0.0
    uz = 0.0
    pc.obs[i, OBS_SIGNAL] = 0.0
    pc.obs[i, OBS_SIGNAL_CHANGE] = 0.0
    if p.signal != NO_SIGNAL:
        arrived = max(p.cell_sensing_radius, p.speed)
        if p.physics == ACTIVE_BROWNIAN:
            arrived = max(p.cell_sensing_radius + p.reach_distance, p.speed)
        heard, ux, uy, uz = radio_room.listen(p, rng, sim.sig, s.pos, so, i, arrived)
        state = state * p.signal_states + heard
        pc.obs[i, OBS_SIGNAL] = so.signal[i]
        if p.signal != BROADCAST:
            pc.obs[i, OBS_SIGNAL_CHANGE] = so.signal[i] - so.prev_signal[i]
    pc.state[i] = state
    pc.heard[i] = heard
    pc.target[i] = cell
    pc.target_d[i] = cell_d
    pc.way[i, 0] = ux
    pc.way[i, 1] = uy
    pc.way[i, 2] = uz
    return True


@inlined
def command(
    p: KernelParams, sim: Sim, i: int, action: int, directions: NDArray[np.float64]
) -> tuple[int, float, float, float, float, float, float]:  # fmt: skip
    """The decision an action of the scenario's action set stands for, as ``act`` takes it:
    ``(code, dx, dy, dz, gx, gy, gz)``. Lattice: one of the paper's behaviours climbing the
    sensed gradient g, or ``NO_BEHAVIOR`` and the unit direction d; active Brownian: the
    steering action (d and g unused)."""
    if p.physics == ACTIVE_BROWNIAN:
        return action, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    obs = sim.pc.obs
    gx = obs[i, OBS_GRADIENT]
    gy = obs[i, OBS_GRADIENT + 1]
    gz = obs[i, OBS_GRADIENT + 2]
    if p.action_set == BEHAVIORS:
        return action, 0.0, 0.0, 0.0, gx, gy, gz
    d = directions[action]
    return NO_BEHAVIOR, d[0], d[1], d[2], gx, gy, gz


@inlined
def decide(
    p: KernelParams, rng: np.random.Generator, sim: Sim, lrn: Learner, i: int, epsilon: float,
) -> tuple[int, int, float, float, float, float, float, float]:  # fmt: skip
    """Robot ``i``'s own choice from its percept: the table's epsilon-greedy action (counted in
    its visits), or a fixed policy's. Returns the action number (0 for a fixed policy) and the
    decision ``command`` describes."""
    s = sim.s
    pc = sim.pc
    if p.policy == Q_LEARNING:
        table = 0 if p.shared else i
        action = epsilon_greedy(epsilon, rng, lrn.q, table, pc.state[i])
        lrn.visits[table, pc.state[i], action] += 1
        code, dx, dy, dz, gx, gy, gz = command(p, sim, i, action, lrn.directions)
        return action, code, dx, dy, dz, gx, gy, gz
    c = pc.obs[i, OBS_READING]
    if p.physics == ACTIVE_BROWNIAN:
        code = steering_baseline(p, rng, pc.obs[i, OBS_CHANGE] > 0.0)
        if code == STEER_UP_GRADIENT and pc.heard[i] > 0 and c <= p.level_1:
            # the written rule: where the biomarker is at trace level, follow the signal
            code = STEER_TO_SIGNAL
        return 0, code, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    code, dx, dy, dz, gx, gy, gz = baseline_action(
        p, rng, s.heading, i, c, s.prev_conc[i], pc.obs[i, OBS_GRADIENT],
        pc.obs[i, OBS_GRADIENT + 1], pc.obs[i, OBS_GRADIENT + 2], pc.target_d[i], pc.heard[i],
    )  # fmt: skip
    return 0, code, dx, dy, dz, gx, gy, gz


# long: a robot's move, bump, reward and delivery, inlined into the compiled step
@inlined
def act(  # noqa: C901  # one robot's move, bump, reward and delivery, compiled inlined into the
    # step: split only with the first compile and the golden digests measured before and after
    p: KernelParams, rng: np.random.Generator, sim: Sim, i: int, t: int, code: int,
    dx: float, dy: float, dz: float, gx: float, gy: float, gz: float,
) -> tuple[float, bool]:  # fmt: skip
    """Robot ``i`` carries out its decision of step ``t`` (``command`` says what the numbers
    are): it moves (a lattice step, or a steered swim), is refused by another robot in the
    way (a bump), earns the reward of paper 2.7, and delivers on arrival. Returns the reward
    and whether it arrived."""
    s = sim.s
    so = sim.so
    pc = sim.pc
    w = sim.w
    px = s.pos[i, 0]
    py = s.pos[i, 1]
    pz = s.pos[i, 2]
    c = pc.obs[i, OBS_READING]
    cell = pc.target[i]
    cell_d = pc.target_d[i]
    hx = s.heading[i, 0]
    hy = s.heading[i, 1]
    hz = s.heading[i, 2]
    path = s.path_length[i]
    if p.physics == ACTIVE_BROWNIAN:
        # what the decision does on the steps it is held (``keep``): a tumble turns once, then
        # the heading is kept; any other steering is done again on each step's new reading
        pc.held[i] = KEEP_HEADING if code == TUMBLE else code
        sx = 0.0
        sy = 0.0
        sz = 0.0
        if code == STEER_UP_GRADIENT:
            if p.policy == EXACT_GRADIENT:
                sx = s.reading_grad[i, 0]
                sy = s.reading_grad[i, 1]
                sz = s.reading_grad[i, 2]
            else:
                sx, sy, sz = sensed_gradient(p, rng, s, i)
        tx = 0.0
        ty = 0.0
        tz = 0.0
        if code == STEER_TO_CELL and cell_d - p.reach_distance <= p.cell_sensing_radius:
            tx = w.cells[cell, 0] - px
            ty = w.cells[cell, 1] - py
            tz = w.cells[cell, 2] - pz
        elif code == STEER_TO_SIGNAL:
            # toward what it receives: as steering toward a cell, along the signal's way
            code = STEER_TO_CELL
            tx = pc.way[i, 0]
            ty = pc.way[i, 1]
            tz = pc.way[i, 2]
        if code == TURN:
            body_turn(p, sim, i)
        else:
            steer(p, rng, s, i, code, sx, sy, sz, tx, ty, tz)
        if s.prev_conc[i] >= 0.0:  # a memory once something was read
            s.prev_conc[i] += p.memory_weight * (c - s.prev_conc[i])
        nx, ny, nz, blocked = brownian.move_robot(p, rng, w, s, i, px, py, pz)
    else:
        step = p.speed
        if code == FOLLOW_SIGNAL:
            # up what it receives, round obstacles (straight on where it receives nothing)
            code = AVOID_OBSTACLE
            gx = pc.way[i, 0]
            gy = pc.way[i, 1]
            gz = pc.way[i, 2]
        if code >= 0:
            dx, dy, dz, step = behavior_direction(
                p, rng, w, s, i, code, px, py, pz, gx, gy, gz, cell, cell_d
            )
        s.prev_conc[i] = c
        nx, ny, nz, blocked = lattice.move_robot(p, w, s, i, px, py, pz, dx, dy, dz, step)
    if p.exclusion and p.physics == ACTIVE_BROWNIAN:
        # another robot in the way: the swimmer stops at contact with it, sliding round it
        bumped = False
        if nx != px or ny != py or nz != pz:
            nx, ny, nz, bumped = brownian.make_way(p, w, sim.near, sim.everyone, s, i, px, py,
                                                   pz)  # fmt: skip
        if bumped:
            so.bumps[i] += 1
            blocked = True
            dx = nx - px
            dy = ny - py
            dz = nz - pz
            s.path_length[i] = path + math.sqrt(dx * dx + dy * dy + dz * dz)
    elif p.exclusion and not blocked and bumped_back(sim.near, s.pos, sim.everyone, i, px, py,
                                                     pz, p.contact):  # fmt: skip
        # another robot is in the way: the move is refused, a bump
        so.bumps[i] += 1
        blocked = True
        s.path_length[i] = path
        s.heading[i, 0] = hx
        s.heading[i, 1] = hy
        s.heading[i, 2] = hz
        nx = px
        ny = py
        nz = pz
    if p.signal == BROADCAST and (nx != px or ny != py or nz != pz):
        # a blocked swimmer may still have moved: it slid on at the contact
        relist(sim.radio, i, nx, ny, nz)
    if p.physics == ACTIVE_BROWNIAN:
        s.blocked[i] = blocked
    reward = p.reward_step
    if blocked:
        reward += p.reward_collision
    s.steps[i] += 1
    target, new_d = treatment.nearest_target(w.cells, sim.tr.treated_at, nx, ny, nz)
    # paper 2.7: +approach per unit moved toward the source, +reach on arrival (no approach
    # once every cell is treated: the episode ends with this step)
    if cell >= 0 and target >= 0:
        reward += p.reward_approach * (cell_d - new_d)
    reached = new_d <= p.reach_distance
    if reached:
        reward += p.reward_reach
        delivered(p, sim, i, target, t)
    s.returns[i] += reward
    pc.reward[i] += reward
    return reward, reached


@inlined
def decides(p: KernelParams, t: int) -> bool:
    """Whether step ``t`` takes a decision by action number (the Q-learner's, or an agent's
    outside): every step, or in active_brownian every ``hold`` steps (the decision interval);
    between decisions a robot ``keep``s to the last."""
    return t % p.hold == 0


@inlined
def keep(p: KernelParams, rng: np.random.Generator, sim: Sim, i: int, t: int) -> tuple[float, bool]:
    """Robot ``i`` carries out in step ``t`` the decision it holds (``act``'s reward and
    arrival): a step between two decisions."""
    return act(p, rng, sim, i, t, sim.pc.held[i], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@inlined
def learn_arrival(p: KernelParams, lrn: Learner, s: Swarm, i: int) -> None:
    """A cell drifted onto robot ``i``: its waiting transition ends its episode, with the
    reward of the step it spent receiving."""
    if s.pending[i]:
        q_update(
            p, lrn.q, lrn.visits, 0 if p.shared else i, s.last_state[i], s.last_action[i],
            s.last_reward[i] + p.reward_reach + p.reward_step,
        )  # fmt: skip
    s.pending[i] = False


@inlined
def learn_last(p: KernelParams, lrn: Learner, s: Swarm, i: int, state: int) -> None:
    """Robot ``i``'s waiting transition, now that its next ``state`` is perceived (eq. 2.7)."""
    if s.pending[i]:
        q_update_bootstrapped(
            p, lrn.q, lrn.visits, 0 if p.shared else i, s.last_state[i], s.last_action[i],
            s.last_reward[i], state,
        )  # fmt: skip


@inlined
def learn(
    p: KernelParams, lrn: Learner, s: Swarm, i: int, state: int, action: int, reward: float,
    reached: bool,
) -> None:  # fmt: skip
    """The transition robot ``i`` just made: learned at once when it ended the robot's
    episode, else kept until its next state is perceived (``learn_last``)."""
    if reached:
        q_update(p, lrn.q, lrn.visits, 0 if p.shared else i, state, action, reward)
        s.pending[i] = False
    else:
        s.pending[i] = True
        s.last_state[i] = state
        s.last_action[i] = action
        s.last_reward[i] = reward


@inlined
def sense(
    p: KernelParams, rng: np.random.Generator, sim: Sim, lrn: Learner, i: int, t: int,
    learning: bool,
) -> bool:  # fmt: skip
    """Robot ``i`` perceives in step ``t`` when the engine decides; a cell that drifted onto
    it ends its episode, and its waiting transition with it (returns False)."""
    if perceive(p, rng, sim, i, t, bool(False)):  # noqa: UP018
        return True
    if learning:
        learn_arrival(p, lrn, sim.s, i)
    sim.s.pending[i] = False
    return False


@inlined
def respond(
    p: KernelParams, rng: np.random.Generator, sim: Sim, lrn: Learner, i: int, t: int,
    epsilon: float, learning: bool,
) -> None:  # fmt: skip
    """Robot ``i``, having perceived, learns its last transition, decides, acts, and learns
    (or keeps) this one; between decisions it keeps to the last, its reward summed into the
    transition that waits."""
    s = sim.s
    if not decides(p, t):
        # between decisions: the held one again, its reward added to the waiting transition's
        reward, reached = keep(p, rng, sim, i, t)
        if learning:
            learn(p, lrn, s, i, s.last_state[i], s.last_action[i], s.last_reward[i] + reward,
                  reached)  # fmt: skip
        return
    state = sim.pc.state[i]
    if learning:
        learn_last(p, lrn, s, i, state)
    action, code, dx, dy, dz, gx, gy, gz = decide(p, rng, sim, lrn, i, epsilon)
    reward, reached = act(p, rng, sim, i, t, code, dx, dy, dz, gx, gy, gz)
    if learning:
        learn(p, lrn, s, i, state, action, reward, reached)


@uncounted
def _heard(p: KernelParams, rng: np.random.Generator, sim: Sim, i: int) -> int:
    """What robot ``i`` would receive where it ended (the state's 'signal'), without taking
    it in, for the episode's last bootstrap (sensor 'counted': its last count, held)."""
    s = sim.s
    if p.signal == BROADCAST:
        return 1 if sim.so.has_message[i] else 0
    if p.counted:
        return radio_room.received(p, sim.so.signal[i], sim.so.prev_signal[i])
    net = radio_room.receive(p, rng, sim.sig, s.pos[i, 0], s.pos[i, 1], s.pos[i, 2])[0]
    return radio_room.received(p, net, sim.so.signal[i])


@episodic
def learn_at_limit(p: KernelParams, rng: np.random.Generator, sim: Sim, lrn: Learner) -> None:
    """The step limit ended the episode: every robot's waiting transition is bootstrapped from
    the state it ended in (not terminal)."""
    w = sim.w
    s = sim.s
    place_sources(p.model, w.cells, w.offsets, w.sx, w.sy, w.sz)
    sense_all(p, w, s, sim.tr, s.pending)
    for i in range(s.pos.shape[0]):
        if not s.pending[i]:
            continue
        cell_d = treatment.nearest_target(
            w.cells, sim.tr.treated_at, s.pos[i, 0], s.pos[i, 1], s.pos[i, 2]
        )[1]  # fmt: skip
        state = read_state(p, rng, sim, i, p.max_steps, cell_d, bool(True))  # noqa: UP018
        if p.signal != NO_SIGNAL:
            state = state * p.signal_states + _heard(p, rng, sim, i)
        learn_last(p, lrn, s, i, state)
        s.pending[i] = False
