"""The compiled step, and the episode loop around it: each step the world moves, every active
robot senses, chooses, moves, collides or reaches, and learns (eq. 2.7).

The step composes the engine's rooms: ``dynamics.lattice`` (how cells, obstacles and robots
move), ``sensing`` (readings and the state), ``policies`` (the choice of an action),
``learning`` (the Q update), and the swarm's: ``contacts`` (robots that take up space),
``treatment`` (cells that take payloads) and ``communication`` (signals on the ``signals`` grid,
or broadcast). Everything here runs under numba; the loop over robots is compiled,
never a Python loop, and the rooms' small functions are inlined into it. Robots are processed in
index order within a step, so a shared Q-table written by many robots in one step receives every
update in a fixed order: the result is exact and reproducible.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from nanonav.engine import communication as radio_room
from nanonav.engine import treatment
from nanonav.engine.contacts import CellList, bumped_back, rebuild, relist
from nanonav.engine.dynamics import brownian
from nanonav.engine.dynamics.lattice import (
    _move_cells,
    _move_obstacles,
    _move_robot,
    _nearest,
    _nearest_obstacle,
    _redraw_emitters,
)
from nanonav.engine.fields import SAMPLED_GAUSSIAN, place_sources, place_treated
from nanonav.engine.learning import _learn, _learn_bootstrapped
from nanonav.engine.policies import (
    NO_BEHAVIOR,
    _baseline,
    _behavior_direction,
    _choose,
    _steer,
    _steering_baseline,
)
from nanonav.engine.qlearning import (
    AVOID_OBSTACLE,
    FOLLOW_SIGNAL,
    STEER_TO_CELL,
    STEER_TO_SIGNAL,
    STEER_UP_GRADIENT,
)
from nanonav.engine.sensing import (
    _read,
    _sense,
    _sense_all,
    _sensed_gradient,
    _state,
    _steering_state,
)
from nanonav.engine.state import (
    ACTIVE_BROWNIAN,
    BEHAVIORS,
    BROADCAST,
    CELL_LOAD,
    CELL_TREATED_AT,
    CURVE_COLLISIONS,
    CURVE_REACHED,
    CURVE_RETURN,
    CURVE_ROBOT_STEPS,
    CURVE_STEPS,
    CURVE_TREATED,
    EPISODE,
    EPISODE_START,
    EV_BUMPS,
    EV_CELL,
    EV_COLLISIONS,
    EV_FINAL_DISTANCE,
    EV_PATH_LENGTH,
    EV_REACHED,
    EV_RETURN,
    EV_STEPS,
    EV_STRAIGHT,
    EV_SUM_CONCENTRATION,
    EV_SUM_DISTANCE,
    EV_SWEPT,
    EXACT_GRADIENT,
    LAYOUT_STATUS,
    NO_SIGNAL,
    Q_LEARNING,
    ROBOT_STEPS,
    STEP,
    KernelParams,
    Learner,
    Recording,
    Social,
    Swarm,
    Treatment,
    World,
)
from nanonav.engine.world import draw_world


@njit(cache=True, error_model="numpy")
def observe(
    p: KernelParams, w: World, s: Swarm, so: Social, tr: Treatment, rec: Recording, t: int,
    final: bool, record: bool,
) -> None:  # fmt: skip
    """Measure the true field and distance at every robot after step ``t`` and add them to the
    per-robot sums of robots still moving at ``t``; if ``record``, store a history row every
    ``record_stride`` steps (and for the ``final`` step). Obstacles that do not move have one
    row, written at the start."""
    row = t // p.record_stride
    on_row = t % p.record_stride == 0
    if final and not on_row:
        row += 1
    keep = record and (on_row or final)
    _sense_all(p, w, s, tr, np.ones(s.pos.shape[0], dtype=np.bool_))
    for i in range(s.pos.shape[0]):
        c = s.reading[i]
        d = _nearest(w.cells, s.pos[i, 0], s.pos[i, 1], s.pos[i, 2])[1]
        if not final and s.steps[i] == t:
            s.sum_conc[i] += c
            s.sum_dist[i] += d
            s.last_dist[i] = d
        if keep:
            rec.conc[row, i] = c
            rec.dist[row, i] = d
            if rec.signal.shape[0]:
                rec.signal[row, i] = so.signal[i]
            if rec.sensed.shape[0]:
                rec.sensed[row, i] = s.sensed[i]
                rec.heading[row, i, 0] = s.heading[i, 0]
                rec.heading[row, i, 1] = s.heading[i, 1]
                rec.heading[row, i, 2] = s.heading[i, 2]
    if keep:
        rec.pos[row] = s.pos
        rec.cells[row] = w.cells
        rec.load[row] = tr.load
        if p.obstacle_std > 0.0:
            rec.obstacles[row] = w.obstacles
        elif t == 0:
            rec.obstacles[0] = w.obstacles
        rec.step[row] = t


@njit(cache=True, error_model="numpy")
def _begin_episode(
    p: KernelParams, world_rng: np.random.Generator, rng: np.random.Generator, w: World,
    s: Swarm, so: Social, tr: Treatment, rec: Recording, evaluating: bool, record: bool,
    near: CellList, radio: CellList,
    everyone: NDArray[np.bool_], sig: NDArray[np.float64],
) -> int:  # fmt: skip
    """Reset the swarm, the cells' loads and the signals, and draw a fresh world; returns
    ``draw_world``'s status."""
    s.active[:] = True
    s.swept[:] = False
    s.blocked[:] = False
    s.sensed[:] = 0.0
    s.steps[:] = 0
    s.prev_conc[:] = -1.0
    s.returns[:] = 0.0
    s.collisions[:] = 0
    s.path_length[:] = 0.0
    s.pending[:] = False
    s.sum_conc[:] = 0.0
    s.sum_dist[:] = 0.0
    s.last_dist[:] = 0.0
    so.bound_to[:] = -1
    so.bumps[:] = 0
    so.signal[:] = 0.0
    so.prev_signal[:] = 0.0
    so.has_message[:] = False
    tr.treated_sources[0] = 0
    tr.load[:] = 0
    tr.treated_at[:] = -1
    sig[:] = 0.0
    status = draw_world(p, world_rng, w, s, near, everyone)
    if status == 0 and p.signal == BROADCAST:
        rebuild(radio, s.pos, everyone)
    if status == 0:
        if p.model == SAMPLED_GAUSSIAN:
            _redraw_emitters(p, rng, w)
        place_sources(p.model, w.cells, w.offsets, w.sx, w.sy, w.sz)
        if record:
            rec.offsets[:] = w.offsets
        if evaluating:
            observe(p, w, s, so, tr, rec, 0, False, record)
    return status


@njit(cache=True, error_model="numpy", inline="always")
def _over(p: KernelParams, tr: Treatment, s: Swarm, t: int) -> bool:
    """The episode is over at the step limit, when every robot has delivered, or when every
    cell is treated."""
    if t >= p.max_steps or not s.active.any():
        return True
    return p.capacity > 0 and treatment.untreated(tr.treated_at) == 0


@njit(cache=True, error_model="numpy")
def _evaluated(
    s: Swarm, so: Social, tr: Treatment, out: NDArray[np.float64], cells: NDArray[np.int64]
) -> None:
    """Every robot's tallies of an evaluation episode that has ended, into ``out[robot]``, and
    every cell's into ``cells[cell]``."""
    for j in range(tr.load.shape[0]):
        cells[j, CELL_LOAD] = tr.load[j]
        cells[j, CELL_TREATED_AT] = tr.treated_at[j]
    for i in range(s.pos.shape[0]):
        out[i, EV_CELL] = so.bound_to[i]
        out[i, EV_BUMPS] = so.bumps[i]
        out[i, EV_STEPS] = s.steps[i]
        out[i, EV_REACHED] = 0.0 if s.active[i] else 1.0
        out[i, EV_FINAL_DISTANCE] = s.last_dist[i]
        out[i, EV_SUM_DISTANCE] = s.sum_dist[i]
        out[i, EV_SUM_CONCENTRATION] = s.sum_conc[i]
        out[i, EV_COLLISIONS] = s.collisions[i]
        out[i, EV_PATH_LENGTH] = s.path_length[i]
        dx = s.pos[i, 0] - s.start[i, 0]
        dy = s.pos[i, 1] - s.start[i, 1]
        dz = s.pos[i, 2] - s.start[i, 2]
        out[i, EV_STRAIGHT] = math.sqrt(dx * dx + dy * dy + dz * dz)
        out[i, EV_RETURN] = s.returns[i]
        out[i, EV_SWEPT] = 1.0 if s.swept[i] else 0.0


# nogil: while a run computes, the worker's other threads (the lease's heartbeat) go on, and a
# transaction one of them opened is never held open by the run.
@njit(cache=True, error_model="numpy", nogil=True)
def run(
    p: KernelParams,
    epsilons: NDArray[np.float64],
    world_rng: np.random.Generator,
    evaluation_rng: np.random.Generator,
    rng: np.random.Generator,
    w: World,
    s: Swarm,
    so: Social,
    tr: Treatment,
    lrn: Learner,
    rec: Recording,
    counters: NDArray[np.int64],
    curve: NDArray[np.float64],
    evaluation: NDArray[np.float64],
    budget: int,
    near: CellList,
    radio: CellList,
    everyone: NDArray[np.bool_],
    found: NDArray[np.int64],
    sig: NDArray[np.float64],
    sig_scratch: NDArray[np.float64],
    cell_tallies: NDArray[np.int64],
) -> None:
    """Run episodes from where ``counters`` says (episode, step) until about ``budget``
    robot-steps are spent, the training episodes are over, or the evaluation is.

    ``epsilons`` holds one rate per training episode; the evaluation episodes follow them, one
    per row of ``evaluation`` (greedy, not learning, in worlds drawn from ``evaluation_rng``,
    the first recorded); each writes its robots' tallies into its row. ``curve[e]`` receives
    episode ``e``'s steps, robots that reached, summed return, collisions and robot-steps. A
    world with no room stops the run with ``counters[LAYOUT_STATUS]`` set.
    """
    training = epsilons.shape[0]
    episodes = training + evaluation.shape[0]
    episode = counters[EPISODE]
    t = counters[STEP]
    while budget > 0 and episode < episodes:
        evaluating = episode >= training
        record = episode == training
        eps = 0.0 if evaluating else epsilons[episode]
        learn = p.learn and not evaluating
        if t == 0:
            if evaluating:
                status = _begin_episode(
                    p, evaluation_rng, rng, w, s, so, tr, rec, True, record, near, radio, everyone,
                    sig,
                )  # fmt: skip
            else:
                status = _begin_episode(
                    p, world_rng, rng, w, s, so, tr, rec, False, False, near, radio, everyone, sig
                )  # fmt: skip
            if status != 0:
                counters[LAYOUT_STATUS] = status
                break
        spent = counters[ROBOT_STEPS]
        if p.physics == ACTIVE_BROWNIAN:
            t = _swim_steps(
                p, eps, learn, evaluating, record, rng, w, s, so, tr, lrn, rec, t, budget, counters,
                near, radio, everyone, found, sig, sig_scratch,
            )  # fmt: skip
        else:
            t = _run_steps(
                p, eps, learn, evaluating, record, rng, w, s, so, tr, lrn, rec, t, budget, counters,
                near, radio, everyone, found, sig, sig_scratch,
            )  # fmt: skip
        budget -= counters[ROBOT_STEPS] - spent
        if not _over(p, tr, s, t):
            continue
        reached = 0
        for i in range(s.pos.shape[0]):
            if not s.active[i]:
                reached += 1
        curve[episode, CURVE_STEPS] = t
        curve[episode, CURVE_REACHED] = reached
        curve[episode, CURVE_RETURN] = s.returns.sum()
        curve[episode, CURVE_COLLISIONS] = s.collisions.sum()
        curve[episode, CURVE_ROBOT_STEPS] = counters[ROBOT_STEPS] - counters[EPISODE_START]
        curve[episode, CURVE_TREATED] = tr.treated_at.shape[0] - treatment.untreated(tr.treated_at)
        counters[EPISODE_START] = counters[ROBOT_STEPS]
        if evaluating:
            _evaluated(s, so, tr, evaluation[episode - training], cell_tallies[episode - training])
        episode += 1
        t = 0
        if episode == training:
            break  # the evaluation starts in a call of its own, so that it is timed alone
    counters[EPISODE] = episode
    counters[STEP] = t


@njit(cache=True, error_model="numpy")
def _run_steps(
    p: KernelParams,
    epsilon: float,
    learn: bool,
    evaluating: bool,
    record: bool,
    rng: np.random.Generator,
    w: World,
    s: Swarm,
    so: Social,
    tr: Treatment,
    lrn: Learner,
    rec: Recording,
    t: int,
    budget: int,
    counters: NDArray[np.int64],
    near: CellList,
    radio: CellList,
    everyone: NDArray[np.bool_],
    found: NDArray[np.int64],
    sig: NDArray[np.float64],
    sig_scratch: NDArray[np.float64],
) -> int:
    """Advance the episode from step ``t`` until it ends or about ``budget`` robot-steps are
    spent; return the new step. When the episode ends (every robot reached a cell, or
    ``max_steps``) the last transitions are learned and, in the evaluation, the final step
    measured (and recorded)."""
    n = s.pos.shape[0]
    stop_at = counters[ROBOT_STEPS] + budget
    while t < p.max_steps and counters[ROBOT_STEPS] < stop_at:
        n_active = 0
        for i in range(n):
            if s.active[i]:
                n_active += 1
        if n_active == 0:
            break
        counters[ROBOT_STEPS] += n_active
        # the world's motion and (below) the pending slots are written out in this loop: moved
        # into functions handed the world and the swarm, they cost up to a quarter of the
        # robot-steps per second (reference counts of the swarm's arrays, or the call's arguments)
        if p.cell_std > 0.0:
            _move_cells(p, rng, w)
        if p.obstacle_std > 0.0 and w.obstacles.shape[0] > 0:
            _move_obstacles(p, rng, w, s)
        if p.model == SAMPLED_GAUSSIAN:
            _redraw_emitters(p, rng, w)
        place_sources(p.model, w.cells, w.offsets, w.sx, w.sy, w.sz)
        if p.capacity > 0:
            tr.treated_sources[0] = place_treated(
                p.model, w.cells, w.offsets, tr.treated_at, tr.tx, tr.ty, tr.tz
            )  # fmt: skip
        if p.signal != NO_SIGNAL and p.signal != BROADCAST and t % p.signal_every == 0:
            radio_room.update_field(p, s.pos, so.bound_to, tr.treated_at, sig, sig_scratch)
        _sense_all(p, w, s, tr, s.active)
        for i in range(n):
            if not s.active[i]:
                continue
            table = 0 if p.shared else i
            px = s.pos[i, 0]
            py = s.pos[i, 1]
            pz = s.pos[i, 2]
            cell, cell_d = treatment.nearest_target(w.cells, tr.treated_at, px, py, pz)
            if cell_d <= p.reach_distance:
                # a drifting cell came within reach: the robot spends this step receiving it.
                # Unless its last heading pointed at the cell, the cell found the robot (a
                # robot parked at a field maximum, say), not the robot the cell.
                toward = (
                    s.heading[i, 0] * (w.cells[cell, 0] - px)
                    + s.heading[i, 1] * (w.cells[cell, 1] - py)
                    + s.heading[i, 2] * (w.cells[cell, 2] - pz)
                )
                s.swept[i] = toward <= 0.0
                s.steps[i] += 1
                s.returns[i] += p.reward_reach + p.reward_step
                if learn and s.pending[i]:
                    _learn(
                        p, lrn.q, lrn.visits, table, s.last_state[i], s.last_action[i],
                        s.last_reward[i] + p.reward_reach + p.reward_step,
                    )  # fmt: skip
                s.pending[i] = False
                s.active[i] = False
                treatment.deliver(p, tr, so, i, cell, t + 1)
                if p.signal == BROADCAST:
                    radio_room.broadcast(p, s.pos, s.active, so, radio, found, i)
                continue
            c, gx, gy, gz = _sense(p, rng, s, i)
            # what the robot receives: the net signal and its gradient, or a message's way
            heard = 0
            ux = 0.0
            uy = 0.0
            uz = 0.0
            if p.signal != NO_SIGNAL:
                heard, ux, uy, uz = radio_room.listen(
                    p, rng, sig, s.pos, so, i, max(p.cell_sensing_radius, p.speed)
                )  # fmt: skip

            # one call site for the behaviours, whoever chooses them: the compiled loop stays small
            behavior = NO_BEHAVIOR
            if p.policy == Q_LEARNING:
                gap = _nearest_obstacle(w.obstacles, p.obstacle_radius, px, py, pz)[1]
                state = _state(p, c, s.prev_conc[i], gx, gy, gz, gap, cell_d)
                if p.signal != NO_SIGNAL:
                    state = state * p.signal_states + heard
                if learn and s.pending[i]:
                    _learn_bootstrapped(
                        p, lrn.q, lrn.visits, table, s.last_state[i], s.last_action[i],
                        s.last_reward[i], state,
                    )  # fmt: skip
                action = _choose(epsilon, rng, lrn.q, table, state)
                lrn.visits[table, state, action] += 1
                if p.action_set == BEHAVIORS:
                    behavior = action
                else:
                    dx = lrn.directions[action, 0]
                    dy = lrn.directions[action, 1]
                    dz = lrn.directions[action, 2]
                    step = p.speed
            else:
                state = 0
                action = 0
                step = p.speed
                behavior, dx, dy, dz, gx, gy, gz = _baseline(
                    p, rng, s.heading, i, c, s.prev_conc[i], gx, gy, gz, cell_d, heard
                )
            if behavior == FOLLOW_SIGNAL:
                # up what it receives, round obstacles (straight on where it receives nothing)
                behavior = AVOID_OBSTACLE
                gx = ux
                gy = uy
                gz = uz
            if behavior >= 0:
                dx, dy, dz, step = _behavior_direction(
                    p, rng, w, s, i, behavior, px, py, pz, gx, gy, gz, cell, cell_d
                )
            s.prev_conc[i] = c

            hx = s.heading[i, 0]
            hy = s.heading[i, 1]
            hz = s.heading[i, 2]
            path = s.path_length[i]
            nx, ny, nz, blocked = _move_robot(p, w, s, i, px, py, pz, dx, dy, dz, step)
            if (
                p.exclusion
                and not blocked
                and bumped_back(near, s.pos, everyone, i, px, py, pz, p.contact)
            ):
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
            if p.signal == BROADCAST and not blocked:
                relist(radio, i, nx, ny, nz)
            reward = p.reward_step
            if blocked:
                reward += p.reward_collision
            s.steps[i] += 1
            target, new_d = treatment.nearest_target(w.cells, tr.treated_at, nx, ny, nz)
            # paper 2.7: +approach per unit moved toward the source, +reach on arrival (no
            # approach once every cell is treated: the episode ends with this step)
            if cell >= 0 and target >= 0:
                reward += p.reward_approach * (cell_d - new_d)
            reached = new_d <= p.reach_distance
            if reached:
                reward += p.reward_reach
                s.active[i] = False
                treatment.deliver(p, tr, so, i, target, t + 1)
                if p.signal == BROADCAST:
                    radio_room.broadcast(p, s.pos, s.active, so, radio, found, i)
            s.returns[i] += reward
            if learn:
                if reached:
                    _learn(p, lrn.q, lrn.visits, table, state, action, reward)
                    s.pending[i] = False
                else:
                    # eq. 2.7 needs the next state: the transition waits for it
                    s.pending[i] = True
                    s.last_state[i] = state
                    s.last_action[i] = action
                    s.last_reward[i] = reward
        t += 1
        if evaluating:
            observe(p, w, s, so, tr, rec, t, False, record)
        if p.capacity > 0 and treatment.untreated(tr.treated_at) == 0:
            break  # every cell is treated: the episode is over
    if _over(p, tr, s, t):
        if learn:
            _finish_episode(p, rng, w, s, so, tr, lrn, sig)
        if record and t % p.record_stride:
            observe(p, w, s, so, tr, rec, t, True, record)
    return t


@njit(cache=True, error_model="numpy")
def _heard(
    p: KernelParams, rng: np.random.Generator, s: Swarm, so: Social, sig: NDArray[np.float64],
    i: int,
) -> int:  # fmt: skip
    """What robot ``i`` receives where it ended (the state's 'signal'), for the last bootstrap."""
    if p.signal == BROADCAST:
        return 1 if so.has_message[i] else 0
    net = radio_room.receive(p, rng, sig, s.pos[i, 0], s.pos[i, 1], s.pos[i, 2])[0]
    return radio_room.received(p, net, so.prev_signal[i])


@njit(cache=True, error_model="numpy")
def _finish_episode(
    p: KernelParams, rng: np.random.Generator, w: World, s: Swarm, so: Social, tr: Treatment,
    lrn: Learner, sig: NDArray[np.float64],
) -> None:  # fmt: skip
    """Bootstrap the last transition of every robot the step limit stopped (not terminal)."""
    place_sources(p.model, w.cells, w.offsets, w.sx, w.sy, w.sz)
    _sense_all(p, w, s, tr, s.pending)
    for i in range(s.pos.shape[0]):
        if not s.pending[i]:
            continue
        table = 0 if p.shared else i
        px = s.pos[i, 0]
        py = s.pos[i, 1]
        pz = s.pos[i, 2]
        c, gx, gy, gz = _sense(p, rng, s, i)
        gap = _nearest_obstacle(w.obstacles, p.obstacle_radius, px, py, pz)[1]
        cell_d = treatment.nearest_target(w.cells, tr.treated_at, px, py, pz)[1]
        state = _state(p, c, s.prev_conc[i], gx, gy, gz, gap, cell_d)
        if p.signal != NO_SIGNAL:
            state = state * p.signal_states + _heard(p, rng, s, so, sig, i)
        _learn_bootstrapped(
            p, lrn.q, lrn.visits, table, s.last_state[i], s.last_action[i], s.last_reward[i],
            state,
        )  # fmt: skip
        s.pending[i] = False


@njit(cache=True, error_model="numpy")
def _swim_steps(
    p: KernelParams,
    epsilon: float,
    learn: bool,
    evaluating: bool,
    record: bool,
    rng: np.random.Generator,
    w: World,
    s: Swarm,
    so: Social,
    tr: Treatment,
    lrn: Learner,
    rec: Recording,
    t: int,
    budget: int,
    counters: NDArray[np.int64],
    near: CellList,
    radio: CellList,
    everyone: NDArray[np.bool_],
    found: NDArray[np.int64],
    sig: NDArray[np.float64],
    sig_scratch: NDArray[np.float64],
) -> int:
    """``_run_steps`` in the active Brownian physics (um, s, nM; a step is dt_s): cells diffuse,
    every robot reads the field at the Berg-Purcell limit, its policy steers its heading (all a
    policy can do), then it swims, jiggles, and its heading diffuses (``dynamics.brownian``)."""
    n = s.pos.shape[0]
    stop_at = counters[ROBOT_STEPS] + budget
    while t < p.max_steps and counters[ROBOT_STEPS] < stop_at:
        n_active = 0
        for i in range(n):
            if s.active[i]:
                n_active += 1
        if n_active == 0:
            break
        counters[ROBOT_STEPS] += n_active
        if p.cell_std > 0.0:
            _move_cells(p, rng, w)
        place_sources(p.model, w.cells, w.offsets, w.sx, w.sy, w.sz)
        if p.capacity > 0:
            tr.treated_sources[0] = place_treated(
                p.model, w.cells, w.offsets, tr.treated_at, tr.tx, tr.ty, tr.tz
            )  # fmt: skip
        if p.signal != NO_SIGNAL and p.signal != BROADCAST and t % p.signal_every == 0:
            radio_room.update_field(p, s.pos, so.bound_to, tr.treated_at, sig, sig_scratch)
        _sense_all(p, w, s, tr, s.active)
        for i in range(n):
            if not s.active[i]:
                continue
            table = 0 if p.shared else i
            px = s.pos[i, 0]
            py = s.pos[i, 1]
            pz = s.pos[i, 2]
            cell, cell_d = treatment.nearest_target(w.cells, tr.treated_at, px, py, pz)
            if cell_d <= p.reach_distance:
                # a diffusing cell touched the robot: as in _run_steps (written out there too:
                # a shared function taking the swarm would cost every step its reference counts)
                toward = (
                    s.heading[i, 0] * (w.cells[cell, 0] - px)
                    + s.heading[i, 1] * (w.cells[cell, 1] - py)
                    + s.heading[i, 2] * (w.cells[cell, 2] - pz)
                )
                s.swept[i] = toward <= 0.0
                s.steps[i] += 1
                s.returns[i] += p.reward_reach + p.reward_step
                if learn and s.pending[i]:
                    _learn(
                        p, lrn.q, lrn.visits, table, s.last_state[i], s.last_action[i],
                        s.last_reward[i] + p.reward_reach + p.reward_step,
                    )  # fmt: skip
                s.pending[i] = False
                s.active[i] = False
                treatment.deliver(p, tr, so, i, cell, t + 1)
                if p.signal == BROADCAST:
                    radio_room.broadcast(p, s.pos, s.active, so, radio, found, i)
                continue
            c = _read(p, rng, s.reading[i])
            s.sensed[i] = c
            if s.prev_conc[i] < 0.0:
                s.prev_conc[i] = c  # the first reading starts the memory
            # temporal sensing: above the memory of past readings
            rising = c > s.prev_conc[i]
            # a cell within the receptor range of the robot's surface
            sensed = cell_d - p.reach_distance <= p.cell_sensing_radius
            heard = 0
            ux = 0.0
            uy = 0.0
            uz = 0.0
            if p.signal != NO_SIGNAL:
                heard, ux, uy, uz = radio_room.listen(
                    p, rng, sig, s.pos, so, i,
                    max(p.cell_sensing_radius + p.reach_distance, p.speed),
                )  # fmt: skip
            if p.policy == Q_LEARNING:
                state = _steering_state(p, c, rising, s.blocked[i], sensed)
                if p.signal != NO_SIGNAL:
                    state = state * p.signal_states + heard
                if learn and s.pending[i]:
                    _learn_bootstrapped(
                        p, lrn.q, lrn.visits, table, s.last_state[i], s.last_action[i],
                        s.last_reward[i], state,
                    )  # fmt: skip
                action = _choose(epsilon, rng, lrn.q, table, state)
                lrn.visits[table, state, action] += 1
            else:
                state = 0
                action = _steering_baseline(p, rng, rising)
                if action == STEER_UP_GRADIENT and heard > 0 and c <= p.level_1:
                    # the written rule: where the biomarker is at trace level, follow the signal
                    action = STEER_TO_SIGNAL
            gx = 0.0
            gy = 0.0
            gz = 0.0
            if action == STEER_UP_GRADIENT:
                if p.policy == EXACT_GRADIENT:
                    gx = s.reading_grad[i, 0]
                    gy = s.reading_grad[i, 1]
                    gz = s.reading_grad[i, 2]
                else:
                    gx, gy, gz = _sensed_gradient(p, rng, s, i)
            tx = 0.0
            ty = 0.0
            tz = 0.0
            if action == STEER_TO_CELL and sensed:
                tx = w.cells[cell, 0] - px
                ty = w.cells[cell, 1] - py
                tz = w.cells[cell, 2] - pz
            elif action == STEER_TO_SIGNAL:
                # toward what it receives: as steering toward a cell, along the signal's way
                action = STEER_TO_CELL
                tx = ux
                ty = uy
                tz = uz
            _steer(p, rng, s, i, action, gx, gy, gz, tx, ty, tz)
            s.prev_conc[i] += p.memory_weight * (c - s.prev_conc[i])

            path = s.path_length[i]
            nx, ny, nz, blocked = brownian.move_robot(p, rng, w, s, i, px, py, pz)
            if (
                p.exclusion
                and not blocked
                and bumped_back(near, s.pos, everyone, i, px, py, pz, p.contact)
            ):
                # hard spheres: a step into another robot is refused, a bump (the heading
                # has diffused all the same, as when an obstacle refuses it)
                so.bumps[i] += 1
                blocked = True
                s.path_length[i] = path
                nx = px
                ny = py
                nz = pz
            if p.signal == BROADCAST and not blocked:
                relist(radio, i, nx, ny, nz)
            s.blocked[i] = blocked
            reward = p.reward_step
            if blocked:
                reward += p.reward_collision
            s.steps[i] += 1
            target, new_d = treatment.nearest_target(w.cells, tr.treated_at, nx, ny, nz)
            if cell >= 0 and target >= 0:
                reward += p.reward_approach * (cell_d - new_d)  # per um closed
            reached = new_d <= p.reach_distance
            if reached:
                reward += p.reward_reach
                s.active[i] = False
                treatment.deliver(p, tr, so, i, target, t + 1)
                if p.signal == BROADCAST:
                    radio_room.broadcast(p, s.pos, s.active, so, radio, found, i)
            s.returns[i] += reward
            if learn:
                if reached:
                    _learn(p, lrn.q, lrn.visits, table, state, action, reward)
                    s.pending[i] = False
                else:
                    s.pending[i] = True
                    s.last_state[i] = state
                    s.last_action[i] = action
                    s.last_reward[i] = reward
        t += 1
        if evaluating:
            observe(p, w, s, so, tr, rec, t, False, record)
        if p.capacity > 0 and treatment.untreated(tr.treated_at) == 0:
            break  # every cell is treated: the episode is over
    if _over(p, tr, s, t):
        if learn:
            _finish_swim_episode(p, rng, w, s, so, tr, lrn, sig)
        if record and t % p.record_stride:
            observe(p, w, s, so, tr, rec, t, True, record)
    return t


@njit(cache=True, error_model="numpy")
def _finish_swim_episode(
    p: KernelParams, rng: np.random.Generator, w: World, s: Swarm, so: Social, tr: Treatment,
    lrn: Learner, sig: NDArray[np.float64],
) -> None:  # fmt: skip
    """``_finish_episode`` in the active Brownian physics: bootstrap the last transition of
    every robot the step limit stopped from the steering state it ended in."""
    place_sources(p.model, w.cells, w.offsets, w.sx, w.sy, w.sz)
    _sense_all(p, w, s, tr, s.pending)
    for i in range(s.pos.shape[0]):
        if not s.pending[i]:
            continue
        table = 0 if p.shared else i
        c = _read(p, rng, s.reading[i])
        cell_d = treatment.nearest_target(
            w.cells, tr.treated_at, s.pos[i, 0], s.pos[i, 1], s.pos[i, 2]
        )[1]  # fmt: skip
        sensed = cell_d - p.reach_distance <= p.cell_sensing_radius
        state = _steering_state(p, c, c > s.prev_conc[i], s.blocked[i], sensed)
        if p.signal != NO_SIGNAL:
            state = state * p.signal_states + _heard(p, rng, s, so, sig, i)
        _learn_bootstrapped(
            p, lrn.q, lrn.visits, table, s.last_state[i], s.last_action[i], s.last_reward[i],
            state,
        )  # fmt: skip
        s.pending[i] = False
