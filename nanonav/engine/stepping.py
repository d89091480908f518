"""A step whose actions come from outside the engine (an agent of an RL library), in two halves:
every robot perceives, then every robot acts on the action it was given.

``kernel`` interleaves the two robot by robot (robot i senses, chooses and moves before robot
i + 1 senses), which an agent outside cannot do: it sees every robot's observation before it
chooses any action. So here a step is ``act`` (each active robot, in index order, turns its
given action into a move, as the kernel turns its own choice), then the world's next step
begins (cells drift, sources and signals are placed, the field is read: ``_prelude``), then
``perceive`` (each robot, in index order, senses, receives, and is delivered if a cell drifted
within reach). With one robot the two orders are the same, random draw for random draw: an
agent that acts as the kernel's greedy choice would reproduces ``simulate``'s evaluation
exactly. With many they differ in what a robot can see of the others' moves within a step
(a cell treated, a message sent earlier in the same step) and in the order of the random draws.

The observation of robot i is ``FEATURES`` numbers (``OBS_*``): what the tabular state is built
from, before it is cut into levels. Everything here runs under numba; ``step_worlds`` steps many
worlds in one call.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple, TypeVar, cast

import numpy as np
from numba import njit
from numba.typed import List
from numpy.typing import NDArray

from nanonav.engine import communication as radio_room
from nanonav.engine import kernel, treatment
from nanonav.engine.contacts import CellList, bumped_back, relist
from nanonav.engine.dynamics import brownian
from nanonav.engine.dynamics.lattice import (
    _move_cells,
    _move_obstacles,
    _move_robot,
    _nearest_obstacle,
    _redraw_emitters,
)
from nanonav.engine.fields import SAMPLED_GAUSSIAN, place_sources, place_treated
from nanonav.engine.policies import NO_BEHAVIOR, _behavior_direction, _steer
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
    LATTICE,
    NO_SIGNAL,
    KernelParams,
    Recording,
    Social,
    Swarm,
    Treatment,
    World,
)

# The observation's columns.
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

# clock[] slots of a world
CLOCK_STEP = 0  # the step the world is at
CLOCK_OVER = 1  # 1 once its episode is over
CLOCK_SLOTS = 2

# worlds a call of _step_chunk steps: its arguments (the batch's every array, the parameters)
# are copied in at each call, thousands of words, so a call takes several (step_worlds hands
# it a tuple of exactly this many generators)
CHUNK = 8

_F = TypeVar("_F", bound=Callable[..., Any])


def _uncounted(function: _F) -> _F:
    """``njit`` without reference counting (numba's ``_nrt=False``, which its typed signature
    does not name): ``_step_chunk`` says why."""
    options: dict[str, Any] = {"cache": True, "error_model": "numpy", "_nrt": False}
    return cast(_F, njit(**options)(function))


class Percept(NamedTuple):
    """What every robot perceived at the start of the step, for the act that follows, and what
    it got since the agent's last decision."""

    obs: NDArray[np.float64]  # (N, FEATURES)
    state: NDArray[np.int64]  # (N,) the tabular state the engine's learner would see
    target: NDArray[np.int64]  # (N,) the nearest untreated cell (-1 if none)
    target_d: NDArray[np.float64]  # (N,) its distance
    way: NDArray[np.float64]  # (N, 3) where what it receives points
    reward: NDArray[np.float64]  # (N,) reward since the agent's last decision
    clock: NDArray[np.int64]  # (CLOCK_SLOTS,)


class Sim(NamedTuple):
    """One world's arrays, as ``simulate.episode_arrays`` makes them, and its percept."""

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
    rec: Recording  # an empty one: nothing is recorded
    pc: Percept


@njit(cache=True, error_model="numpy", inline="always")
def _prelude(p: KernelParams, rng: np.random.Generator, sim: Sim, t: int) -> None:
    """The start of step ``t``: the world moves, its sources and the signal are placed, and the
    true field is read at every active robot (as at the top of the kernel's step)."""
    w = sim.w
    tr = sim.tr
    if p.cell_std > 0.0:
        _move_cells(p, rng, w)
    if p.physics == LATTICE:
        if p.obstacle_std > 0.0 and w.obstacles.shape[0] > 0:
            _move_obstacles(p, rng, w, sim.s)
        if p.model == SAMPLED_GAUSSIAN:
            _redraw_emitters(p, rng, w)
    place_sources(p.model, w.cells, w.offsets, w.sx, w.sy, w.sz)
    if p.capacity > 0:
        tr.treated_sources[0] = place_treated(
            p.model, w.cells, w.offsets, tr.treated_at, tr.tx, tr.ty, tr.tz
        )  # fmt: skip
    if p.signal != NO_SIGNAL and p.signal != BROADCAST and t % p.signal_every == 0:
        radio_room.update_field(p, sim.s.pos, sim.so.bound_to, tr.treated_at, sim.sig,
                                sim.sig_scratch)  # fmt: skip
    _sense_all(p, w, sim.s, tr, sim.s.active)


@njit(cache=True, error_model="numpy")
def _delivered(p: KernelParams, sim: Sim, i: int, cell: int, t: int) -> None:
    """Robot ``i`` reached ``cell`` at step ``t``: it delivers, is done, and broadcasts."""
    s = sim.s
    s.active[i] = False
    treatment.deliver(p, sim.tr, sim.so, i, cell, t + 1)
    if p.signal == BROADCAST:
        radio_room.broadcast(p, s.pos, s.active, sim.so, sim.radio, sim.found, i)


@njit(cache=True, error_model="numpy", inline="always")
def _perceive(p: KernelParams, rng: np.random.Generator, sim: Sim, t: int) -> None:
    """Every active robot, in index order, at the start of step ``t``: a cell that drifted
    within reach is received (the robot's step is spent so, as in the kernel); otherwise it
    senses and receives, and its observation and tabular state are written."""
    s = sim.s
    so = sim.so
    pc = sim.pc
    brownian_robots = p.physics == ACTIVE_BROWNIAN
    arrived = max(p.cell_sensing_radius, p.speed)
    if brownian_robots:
        arrived = max(p.cell_sensing_radius + p.reach_distance, p.speed)
    for i in range(s.pos.shape[0]):
        if not s.active[i]:
            continue
        px = s.pos[i, 0]
        py = s.pos[i, 1]
        pz = s.pos[i, 2]
        cell, cell_d = treatment.nearest_target(sim.w.cells, sim.tr.treated_at, px, py, pz)
        if cell_d <= p.reach_distance:
            toward = (
                s.heading[i, 0] * (sim.w.cells[cell, 0] - px)
                + s.heading[i, 1] * (sim.w.cells[cell, 1] - py)
                + s.heading[i, 2] * (sim.w.cells[cell, 2] - pz)
            )
            s.swept[i] = toward <= 0.0
            s.steps[i] += 1
            s.returns[i] += p.reward_reach + p.reward_step
            pc.reward[i] += p.reward_reach + p.reward_step
            _delivered(p, sim, i, cell, t)
            continue
        row = pc.obs[i]
        if brownian_robots:
            c = _read(p, rng, s.reading[i])
            s.sensed[i] = c
            if s.prev_conc[i] < 0.0:
                s.prev_conc[i] = c  # the first reading starts the memory
            row[OBS_READING] = c
            row[OBS_CHANGE] = c - s.prev_conc[i]
            row[OBS_GRADIENT] = 0.0
            row[OBS_GRADIENT + 1] = 0.0
            row[OBS_GRADIENT + 2] = 0.0
            row[OBS_OBSTACLE] = 1.0 if s.blocked[i] else 0.0
            gap = cell_d - p.reach_distance
            row[OBS_CELL] = min(gap, p.cell_sensing_radius)
            state = _steering_state(
                p, c, c > s.prev_conc[i], s.blocked[i], gap <= p.cell_sensing_radius
            )
        else:
            c, gx, gy, gz = _sense(p, rng, s, i)
            row[OBS_READING] = c
            row[OBS_CHANGE] = c - s.prev_conc[i] if s.prev_conc[i] >= 0.0 else 0.0
            row[OBS_GRADIENT] = gx
            row[OBS_GRADIENT + 1] = gy
            row[OBS_GRADIENT + 2] = gz
            gap = _nearest_obstacle(sim.w.obstacles, p.obstacle_radius, px, py, pz)[1]
            row[OBS_OBSTACLE] = min(max(gap, 0.0), p.sensing_radius)
            row[OBS_CELL] = min(cell_d, p.cell_sensing_radius)
            state = _state(p, c, s.prev_conc[i], gx, gy, gz, gap, cell_d)
        row[OBS_SIGNAL] = 0.0
        row[OBS_SIGNAL_CHANGE] = 0.0
        ux = 0.0
        uy = 0.0
        uz = 0.0
        if p.signal != NO_SIGNAL:
            before = so.prev_signal[i]
            heard, ux, uy, uz = radio_room.listen(p, rng, sim.sig, s.pos, so, i, arrived)
            state = state * p.signal_states + heard
            row[OBS_SIGNAL] = so.signal[i]
            if p.signal != BROADCAST:
                row[OBS_SIGNAL_CHANGE] = so.signal[i] - before
        pc.state[i] = state
        pc.target[i] = cell
        pc.target_d[i] = cell_d
        pc.way[i, 0] = ux
        pc.way[i, 1] = uy
        pc.way[i, 2] = uz


@njit(cache=True, error_model="numpy", inline="always")
def _act(
    p: KernelParams, rng: np.random.Generator, sim: Sim, actions: NDArray[np.int64], t: int,
    directions: NDArray[np.float64],
) -> None:  # fmt: skip
    """Every active robot, in index order, carries out its action of step ``t``: the move it
    makes, a bump into another robot, the reward (paper 2.7), and a delivery on arrival."""
    s = sim.s
    so = sim.so
    pc = sim.pc
    w = sim.w
    for i in range(s.pos.shape[0]):
        if not s.active[i]:
            continue
        pc.reward[i] = 0.0
        px = s.pos[i, 0]
        py = s.pos[i, 1]
        pz = s.pos[i, 2]
        action = actions[i]
        c = pc.obs[i, OBS_READING]
        cell = pc.target[i]
        cell_d = pc.target_d[i]
        hx = s.heading[i, 0]
        hy = s.heading[i, 1]
        hz = s.heading[i, 2]
        path = s.path_length[i]
        if p.physics == ACTIVE_BROWNIAN:
            gx = 0.0
            gy = 0.0
            gz = 0.0
            if action == STEER_UP_GRADIENT:
                gx, gy, gz = _sensed_gradient(p, rng, s, i)
            tx = 0.0
            ty = 0.0
            tz = 0.0
            if action == STEER_TO_CELL and cell_d - p.reach_distance <= p.cell_sensing_radius:
                tx = w.cells[cell, 0] - px
                ty = w.cells[cell, 1] - py
                tz = w.cells[cell, 2] - pz
            elif action == STEER_TO_SIGNAL:
                action = STEER_TO_CELL
                tx = pc.way[i, 0]
                ty = pc.way[i, 1]
                tz = pc.way[i, 2]
            _steer(p, rng, s, i, action, gx, gy, gz, tx, ty, tz)
            s.prev_conc[i] += p.memory_weight * (c - s.prev_conc[i])
            nx, ny, nz, blocked = brownian.move_robot(p, rng, w, s, i, px, py, pz)
        else:
            behavior = NO_BEHAVIOR
            dx = 0.0
            dy = 0.0
            dz = 0.0
            step = p.speed
            if p.action_set == BEHAVIORS:
                behavior = action
            else:
                dx = directions[action, 0]
                dy = directions[action, 1]
                dz = directions[action, 2]
            gx = pc.obs[i, OBS_GRADIENT]
            gy = pc.obs[i, OBS_GRADIENT + 1]
            gz = pc.obs[i, OBS_GRADIENT + 2]
            if behavior == FOLLOW_SIGNAL:
                behavior = AVOID_OBSTACLE
                gx = pc.way[i, 0]
                gy = pc.way[i, 1]
                gz = pc.way[i, 2]
            if behavior >= 0:
                dx, dy, dz, step = _behavior_direction(
                    p, rng, w, s, i, behavior, px, py, pz, gx, gy, gz, cell, cell_d
                )
            s.prev_conc[i] = c
            nx, ny, nz, blocked = _move_robot(p, w, s, i, px, py, pz, dx, dy, dz, step)
        if (
            p.exclusion
            and not blocked
            and bumped_back(sim.near, s.pos, sim.everyone, i, px, py, pz, p.contact)
        ):
            so.bumps[i] += 1
            blocked = True
            s.path_length[i] = path
            if p.physics == LATTICE:
                s.heading[i, 0] = hx
                s.heading[i, 1] = hy
                s.heading[i, 2] = hz
            nx = px
            ny = py
            nz = pz
        if p.signal == BROADCAST and not blocked:
            relist(sim.radio, i, nx, ny, nz)
        if p.physics == ACTIVE_BROWNIAN:
            s.blocked[i] = blocked
        reward = p.reward_step
        if blocked:
            reward += p.reward_collision
        s.steps[i] += 1
        target, new_d = treatment.nearest_target(w.cells, sim.tr.treated_at, nx, ny, nz)
        if cell >= 0 and target >= 0:
            reward += p.reward_approach * (cell_d - new_d)
        if new_d <= p.reach_distance:
            reward += p.reward_reach
            _delivered(p, sim, i, target, t)
        s.returns[i] += reward
        pc.reward[i] = reward


@njit(cache=True, error_model="numpy")
def reset_world(
    p: KernelParams, world_rng: np.random.Generator, rng: np.random.Generator, sim: Sim
) -> int:
    """Draw a fresh world and perceive its step 0; returns ``world.draw_world``'s status."""
    clock = sim.pc.clock
    clock[CLOCK_STEP] = 0
    clock[CLOCK_OVER] = 0
    sim.pc.reward[:] = 0.0
    sim.pc.state[:] = 0
    sim.pc.obs[:] = 0.0
    status = kernel._begin_episode(
        p, world_rng, rng, sim.w, sim.s, sim.so, sim.tr, sim.rec, False, False, sim.near,
        sim.radio, sim.everyone, sim.sig,
    )  # fmt: skip
    if status != 0:
        clock[CLOCK_OVER] = 1
        return status
    _prelude(p, rng, sim, 0)
    _perceive(p, rng, sim, 0)
    if not sim.s.active.any():
        clock[CLOCK_STEP] = 1
        clock[CLOCK_OVER] = 1
    return 0


@njit(cache=True, error_model="numpy", inline="always")
def step_world(
    p: KernelParams, rng: np.random.Generator, sim: Sim, actions: NDArray[np.int64],
    directions: NDArray[np.float64],
) -> None:  # fmt: skip
    """One step of a world whose episode is not over: act, then perceive the next step."""
    clock = sim.pc.clock
    t = clock[CLOCK_STEP]
    _act(p, rng, sim, actions, t, directions)
    t += 1
    clock[CLOCK_STEP] = t
    if kernel._over(p, sim.tr, sim.s, t):
        clock[CLOCK_OVER] = 1
        return
    _prelude(p, rng, sim, t)
    _perceive(p, rng, sim, t)
    if not sim.s.active.any():
        # the last robots spent step t receiving cells that drifted onto them: it counts
        clock[CLOCK_STEP] = t + 1
        clock[CLOCK_OVER] = 1


@njit(cache=True, error_model="numpy", inline="always")
def _world_at(b: World, k: int) -> World:
    return World(b.cells[k], b.obstacles[k], b.offsets[k], b.sx[k], b.sy[k], b.sz[k])


@njit(cache=True, error_model="numpy", inline="always")
def _swarm_at(b: Swarm, k: int) -> Swarm:
    return Swarm(
        b.pos[k], b.heading[k], b.active[k], b.steps[k], b.prev_conc[k], b.returns[k],
        b.collisions[k], b.path_length[k], b.pending[k], b.last_state[k], b.last_action[k],
        b.last_reward[k], b.start[k], b.sum_conc[k], b.sum_dist[k], b.last_dist[k],
        b.reading[k], b.reading_grad[k], b.swept[k], b.blocked[k], b.sensed[k],
    )  # fmt: skip


@njit(cache=True, error_model="numpy", inline="always")
def _social_at(b: Social, k: int) -> Social:
    return Social(
        b.bound_to[k], b.bumps[k], b.signal[k], b.prev_signal[k], b.message[k], b.has_message[k]
    )


@njit(cache=True, error_model="numpy", inline="always")
def _treatment_at(b: Treatment, k: int) -> Treatment:
    return Treatment(b.load[k], b.treated_at[k], b.tx[k], b.ty[k], b.tz[k], b.treated_sources[k])


@njit(cache=True, error_model="numpy", inline="always")
def _cells_at(b: CellList, k: int) -> CellList:
    return CellList(b.heads[k], b.next[k], b.cell[k], b.origin, b.width, b.dims, b.slack)


@njit(cache=True, error_model="numpy", inline="always")
def _recording_at(b: Recording, k: int) -> Recording:
    return Recording(
        b.pos[k], b.cells[k], b.obstacles[k], b.conc[k], b.dist[k], b.step[k], b.offsets[k],
        b.heading[k], b.sensed[k], b.load[k], b.signal[k],
    )  # fmt: skip


@njit(cache=True, error_model="numpy", inline="always")
def _percept_at(b: Percept, k: int) -> Percept:
    return Percept(
        b.obs[k], b.state[k], b.target[k], b.target_d[k], b.way[k], b.reward[k], b.clock[k]
    )


@njit(cache=True, error_model="numpy", inline="always")
def _sim_at(b: Sim, k: int) -> Sim:
    """World ``k`` of a batch whose every array has a leading axis of worlds, as views: the
    worlds' arrays lie side by side in memory, so stepping them one after another streams
    through it (separate arrays per world cost each step a cache miss per array)."""
    return Sim(
        _world_at(b.w, k), _swarm_at(b.s, k), _social_at(b.so, k), _treatment_at(b.tr, k),
        _cells_at(b.near, k), _cells_at(b.radio, k), b.everyone[k], b.found[k], b.sig[k],
        b.sig_scratch[k], _recording_at(b.rec, k), _percept_at(b.pc, k),
    )  # fmt: skip


@njit(cache=True, error_model="numpy")
def step_worlds(
    params: List[KernelParams],
    world_rngs: List[np.random.Generator],
    rngs: List[np.random.Generator],
    batches: List[Sim],
    actions: NDArray[np.int64],
    fresh: NDArray[np.bool_],
    directions: NDArray[np.float64],
) -> int:
    """Every world k of ``batches[0]`` (its arrays shaped worlds x ...) one step on
    ``actions[k]`` (robots x 1), or, where ``fresh[k]``, into a fresh world (its actions
    unused); a world whose episode is over and is not fresh stays as it is. What each world's
    robots perceived and got is then in its ``pc``. Returns the first non-zero ``draw_world``
    status, or 0. (The parameters and the batch come in lists of one: a list crosses into
    compiled code at once, where a tuple of many arrays is checked array by array each call.)"""
    p = params[0]
    batch = batches[0]
    worlds = batch.pc.clock.shape[0]
    for k in range(worlds):
        if fresh[k]:
            status = reset_world(p, world_rngs[k], rngs[k], _sim_at(batch, k))
            if status != 0:
                return status
    last = worlds - 1
    for start in range(0, worlds, CHUNK):
        # CHUNK worlds' generators (the last world's again where the batch runs out)
        generators = (
            rngs[min(start, last)], rngs[min(start + 1, last)], rngs[min(start + 2, last)],
            rngs[min(start + 3, last)], rngs[min(start + 4, last)], rngs[min(start + 5, last)],
            rngs[min(start + 6, last)], rngs[min(start + 7, last)],
        )  # fmt: skip
        _step_chunk(p, generators, batch, start, min(CHUNK, worlds - start), actions, fresh,
                    directions)  # fmt: skip
    return 0


@_uncounted
def _step_chunk(
    p: KernelParams, generators: tuple[np.random.Generator, ...], batch: Sim, start: int,
    count: int, actions: NDArray[np.int64], fresh: NDArray[np.bool_],
    directions: NDArray[np.float64],
) -> None:  # fmt: skip
    """``step_world`` of worlds ``start`` ... ``start + count - 1`` of the batch (world
    ``start + j`` with ``generators[j]``; one fresh or over is left as it is), compiled without
    reference counting (``_nrt=False``). Every view of a world and every member taken from its
    NamedTuples would otherwise be counted in and out, an atomic call each: measured, those
    calls were two thirds of a step's time. Nothing here allocates (numba refuses to compile it
    if anything did), and the batch it views is held by the caller for the whole call."""
    clock = batch.pc.clock
    for j in range(count):
        k = start + j
        if not fresh[k] and clock[k, CLOCK_OVER] == 0:
            step_world(p, generators[j], _sim_at(batch, k), actions[k], directions)
