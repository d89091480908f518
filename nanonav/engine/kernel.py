"""The episode loop of ``simulate``: episodes of training, then the evaluation, each a run of
steps whose phases (``phases``: advance, perceive, decide, act, learn) the engine's own policies
drive under the scenario's schedule, with the episode's bookkeeping around them (a fresh world,
the measurements and the history of the evaluation, the tallies when it ends).

Everything here runs under numba; the loop over robots is compiled, never a Python loop. Robots
are processed in index order within a step, so a shared Q-table written by many robots in one
step receives every update in a fixed order: the result is exact and reproducible.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from nanonav.engine import treatment
from nanonav.engine.compiled import episodic, episodic_counted, inlined
from nanonav.engine.contacts import rebuild
from nanonav.engine.dynamics.lattice import nearest, redraw_emitters
from nanonav.engine.fields import SAMPLED_GAUSSIAN, place_sources
from nanonav.engine.phases import Sim, advance, learn_at_limit, respond, sense
from nanonav.engine.sensing import sense_all
from nanonav.engine.state import (
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
    LAYOUT_STATUS,
    ROBOT_STEPS,
    SEQUENTIAL,
    STEP,
    KernelParams,
    Learner,
    Social,
    Swarm,
    Treatment,
)
from nanonav.engine.world import draw_world


@episodic_counted
def observe(p: KernelParams, sim: Sim, t: int, final: bool, record: bool) -> None:
    """Measure the true field and distance at every robot after step ``t`` and add them to the
    per-robot sums of robots still moving at ``t``; if ``record``, store a history row every
    ``record_stride`` steps (and for the ``final`` step). Obstacles that do not move have one
    row, written at the start. (Element by element: this runs inside the uncounted step.)"""
    w = sim.w
    s = sim.s
    rec = sim.rec
    row = t // p.record_stride
    on_row = t % p.record_stride == 0
    if final and not on_row:
        row += 1
    keep = record and (on_row or final)
    sense_all(p, w, s, sim.tr, sim.everyone)
    for i in range(s.pos.shape[0]):
        c = s.reading[i]
        d = nearest(w.cells, s.pos[i, 0], s.pos[i, 1], s.pos[i, 2])[1]
        if not final and s.steps[i] == t:
            s.sum_conc[i] += c
            s.sum_dist[i] += d
            s.last_dist[i] = d
        if keep:
            rec.conc[row, i] = c
            rec.dist[row, i] = d
            for axis in range(3):
                rec.pos[row, i, axis] = s.pos[i, axis]
            if rec.signal.shape[0]:
                rec.signal[row, i] = sim.so.signal[i]
            if rec.sensed.shape[0]:
                rec.sensed[row, i] = s.sensed[i]
                for axis in range(3):
                    rec.heading[row, i, axis] = s.heading[i, axis]
    if keep:
        for j in range(w.cells.shape[0]):
            for axis in range(3):
                rec.cells[row, j, axis] = w.cells[j, axis]
            rec.load[row, j] = sim.tr.load[j]
        if p.obstacle_std > 0.0 or t == 0:
            at = row if p.obstacle_std > 0.0 else 0
            for j in range(w.obstacles.shape[0]):
                for axis in range(3):
                    rec.obstacles[at, j, axis] = w.obstacles[j, axis]
        rec.step[row] = t


@episodic
def begin_episode(
    p: KernelParams, world_rng: np.random.Generator, rng: np.random.Generator, sim: Sim,
    evaluating: bool, record: bool,
) -> int:  # fmt: skip
    """Reset the swarm, the cells' loads and the signals, and draw a fresh world; returns
    ``draw_world``'s status."""
    s = sim.s
    so = sim.so
    tr = sim.tr
    w = sim.w
    s.active[:] = True
    s.swept[:] = False
    s.blocked[:] = False
    s.sensed[:] = 0.0
    s.window_flux[:] = 0.0
    s.sensed_grad[:] = 0.0
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
    so.signal_grad[:] = 0.0
    so.signal_flux[:] = 0.0
    so.has_message[:] = False
    tr.treated_sources[0] = 0
    tr.load[:] = 0
    tr.treated_at[:] = -1
    sim.sig[:] = 0.0
    status = draw_world(p, world_rng, w, s, sim.near, sim.everyone)
    if status == 0 and p.signal == BROADCAST:
        rebuild(sim.radio, s.pos, sim.everyone)
    if status == 0:
        if p.model == SAMPLED_GAUSSIAN:
            redraw_emitters(p, rng, w)
        place_sources(p.model, w.cells, w.offsets, w.sx, w.sy, w.sz)
        if record:
            for k in range(w.offsets.shape[0]):
                for axis in range(3):
                    sim.rec.offsets[k, axis] = w.offsets[k, axis]
        if evaluating:
            # step 0 as a number, not a constant: a constant would compile observe once more
            observe(p, sim, int(0), bool(False), record)  # noqa: UP018, RUF046
    return status


@inlined
def over(p: KernelParams, tr: Treatment, s: Swarm, t: int) -> bool:
    """The episode is over at the step limit, when every robot has delivered, or when every
    cell is treated."""
    if t >= p.max_steps or not s.active.any():
        return True
    return p.capacity > 0 and treatment.untreated(tr.treated_at) == 0


@episodic_counted
def tally_evaluation(
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
    sim: Sim,
    lrn: Learner,
    counters: NDArray[np.int64],
    curve: NDArray[np.float64],
    evaluation: NDArray[np.float64],
    budget: int,
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
    s = sim.s
    tr = sim.tr
    training = epsilons.shape[0]
    episodes = training + evaluation.shape[0]
    episode = counters[EPISODE]
    t = counters[STEP]
    while budget > 0 and episode < episodes:
        evaluating = episode >= training
        record = episode == training
        eps = 0.0 if evaluating else epsilons[episode]
        learning = p.learn and not evaluating
        if t == 0:
            status = begin_episode(
                p, evaluation_rng if evaluating else world_rng, rng, sim, evaluating, record
            )  # fmt: skip
            if status != 0:
                counters[LAYOUT_STATUS] = status
                break
        spent = counters[ROBOT_STEPS]
        t = _steps(p, eps, learning, evaluating, record, rng, sim, lrn, t, budget, counters)
        budget -= counters[ROBOT_STEPS] - spent
        if not over(p, tr, s, t):
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
            tally_evaluation(s, sim.so, tr, evaluation[episode - training],
                       cell_tallies[episode - training])  # fmt: skip
        episode += 1
        t = 0
        if episode == training:
            break  # the evaluation starts in a call of its own, so that it is timed alone
    counters[EPISODE] = episode
    counters[STEP] = t


@episodic
def _steps(
    p: KernelParams, epsilon: float, learning: bool, evaluating: bool, record: bool,
    rng: np.random.Generator, sim: Sim, lrn: Learner, t: int, budget: int,
    counters: NDArray[np.int64],
) -> int:  # fmt: skip
    """Advance the episode from step ``t`` until it ends or about ``budget`` robot-steps are
    spent, the engine deciding for every robot under the scenario's schedule; return the new
    step. When the episode ends (every robot reached a cell, every cell is treated, or
    ``max_steps``) the last transitions are learned and, in the evaluation, the final step
    measured (and recorded). Compiled without reference counting (``compiled.uncounted``)."""
    s = sim.s
    n = s.pos.shape[0]
    sequential = p.schedule == SEQUENTIAL
    stop_at = counters[ROBOT_STEPS] + budget
    while t < p.max_steps and counters[ROBOT_STEPS] < stop_at:
        n_active = 0
        for i in range(n):
            if s.active[i]:
                n_active += 1
        if n_active == 0:
            break
        counters[ROBOT_STEPS] += n_active
        advance(p, rng, sim, t)
        # sequential, one pass: each robot senses and, if it did, responds before the next;
        # simultaneous, two: every robot senses, then every robot still active responds. One
        # place senses and one responds, so that each is compiled into the step once.
        for second in range(1 if sequential else 2):
            for i in range(n):
                if not s.active[i]:
                    continue
                if second == 0:
                    sensed = sense(p, rng, sim, lrn, i, t, learning)
                    if not (sequential and sensed):
                        continue
                respond(p, rng, sim, lrn, i, t, epsilon, learning)
        t += 1
        if evaluating:
            observe(p, sim, t, bool(False), record)  # noqa: UP018
        if p.capacity > 0 and treatment.untreated(sim.tr.treated_at) == 0:
            break  # every cell is treated: the episode is over
    if over(p, sim.tr, s, t):
        if learning:
            learn_at_limit(p, rng, sim, lrn)
        if record and t % p.record_stride:
            observe(p, sim, t, bool(True), record)  # noqa: UP018
    return t
