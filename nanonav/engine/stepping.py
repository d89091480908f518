"""Worlds stepped from outside the engine (an agent of an RL library hands in the actions),
under the scenario's schedule, over the same phases (``phases``) ``simulate`` runs:

- ``simultaneous`` (PettingZoo's parallel order): a step is ``act`` (each active robot, in
  index order, on the action it was given), then the world's next step begins (``advance``),
  then ``perceive`` (each robot, in index order, senses and receives, or takes in a cell that
  drifted within reach). The agent sees every robot's observation before it chooses any action.
- ``sequential`` (PettingZoo's AEC order, the kernel's own): one robot acts at a time; the
  next active robot then perceives, and when the last robot of a step has acted the world's
  next step begins. ``clock[CLOCK_NEXT]`` names the robot whose turn it is.

Either way the random draws come in the order ``simulate`` draws them under the same schedule,
so an agent that acts as the engine's greedy choice would reproduces its evaluation exactly.
The observation of robot i is ``phases.FEATURES`` numbers (``phases.OBS_*``). ``step_worlds``
steps many worlds in one call.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numba.typed import List
from numpy.typing import NDArray

from nanonav.engine.compiled import episodic, inlined
from nanonav.engine.contacts import CellList
from nanonav.engine.generators import generator_at
from nanonav.engine.kernel import begin_episode, observe, over
from nanonav.engine.phases import (
    CLOCK_MEASURE,
    CLOCK_NEXT,
    CLOCK_OVER,
    CLOCK_STEP,
    RECORDED,
    Percept,
    Sim,
    act,
    advance,
    command,
    decides,
    keep,
    perceive,
)
from nanonav.engine.qlearning import TURN
from nanonav.engine.state import (
    SEQUENTIAL,
    KernelParams,
    Recording,
    Social,
    Swarm,
    Treatment,
    World,
)


@inlined
def _ended(p: KernelParams, sim: Sim, t: int) -> bool:
    """Step ``t`` has been reached: measure it if the world is measured (as ``simulate``'s
    evaluation does after each step, the last one recorded), and end the episode if it is
    over."""
    clock = sim.pc.clock
    measure = clock[CLOCK_MEASURE]
    if measure:
        observe(p, sim, t, bool(False), measure == RECORDED)  # noqa: UP018
    if not over(p, sim.tr, sim.s, t):
        return False
    if measure == RECORDED and t % p.record_stride:
        observe(p, sim, t, bool(True), bool(True))  # noqa: UP018
    clock[CLOCK_OVER] = 1
    return True


@episodic
def draw_fresh(
    p: KernelParams, world_rng: np.random.Generator, rng: np.random.Generator, sim: Sim
) -> int:
    """Draw a fresh world at step 0, not yet begun (``on_to_decision`` begins it); returns
    ``world.draw_world``'s status."""
    clock = sim.pc.clock
    clock[CLOCK_STEP] = 0
    clock[CLOCK_OVER] = 0
    clock[CLOCK_NEXT] = -1
    sim.pc.reward[:] = 0.0
    sim.pc.state[:] = 0
    sim.pc.obs[:] = 0.0
    sim.pc.held[:] = 0
    sim.pc.turn[:] = 0.0
    sim.pc.side[:] = 0.0  # a fresh body frame: an episode does not depend on the last one's
    measure = clock[CLOCK_MEASURE]
    status = begin_episode(p, world_rng, rng, sim, measure != 0, measure == RECORDED)
    if status != 0:
        clock[CLOCK_OVER] = 1
    return status


@inlined
def _act_on(
    p: KernelParams, rng: np.random.Generator, sim: Sim, i: int, t: int, action: int,
    turns: NDArray[np.float64], directions: NDArray[np.float64],
) -> None:  # fmt: skip
    """Robot ``i`` acts on its action number, or where robots turn (``KernelParams.turning``)
    on its continuous turn ``turns[i]`` (side, up), each within -1 .. 1."""
    if p.turning:
        pc = sim.pc
        pc.turn[i, 0] = min(1.0, max(-1.0, turns[i, 0]))
        pc.turn[i, 1] = min(1.0, max(-1.0, turns[i, 1]))
        code, dx, dy, dz, gx, gy, gz = TURN, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    else:
        code, dx, dy, dz, gx, gy, gz = command(p, sim, i, action, directions)
    act(p, rng, sim, i, t, code, dx, dy, dz, gx, gy, gz)


# ``step_worlds`` calls each half once, for fresh worlds and moves alike: each phase is then
# compiled into it once (a fresh world and a move with halves of their own held four copies
# of perceive and advance and two of act, and the compiler optimised them all at the
# environments' first start), and all of it inlined (a call per world that passes the world's
# arrays one by one halved the vector env's speed).


@inlined
def act_on_actions(
    p: KernelParams, rng: np.random.Generator, sim: Sim, actions: NDArray[np.int64],
    turns: NDArray[np.float64], directions: NDArray[np.float64],
) -> int:  # fmt: skip
    """The acting half of a move: the robot whose turn it is (sequential) or every active
    robot (simultaneous) acts on its action, each robot's reward of the move starting at 0;
    returns the robot the perceiving goes on from (``on_to_decision``'s ``first``)."""
    pc = sim.pc
    s = sim.s
    clock = pc.clock
    t = clock[CLOCK_STEP]
    for i in range(s.pos.shape[0]):
        pc.reward[i] = 0.0
    sequential = p.schedule == SEQUENTIAL
    first = clock[CLOCK_NEXT] if sequential else 0
    last = first + 1 if sequential else s.pos.shape[0]
    for i in range(first, last):
        if s.active[i]:
            _act_on(p, rng, sim, i, t, actions[i], turns, directions)
    return last


@inlined
def on_to_decision(
    p: KernelParams, rng: np.random.Generator, sim: Sim, first: int, fresh: bool
) -> None:
    """The perceiving half of a move, or of a fresh world (``fresh``: its step begins first):
    on to the next decision or the episode's end. Sequential: robots from ``first`` on
    perceive (one a drifting cell reaches spends its turn so) until one gets the turn
    (``clock[CLOCK_NEXT]``); when a step's robots have all had theirs the next step begins.
    Simultaneous: the next step begins and every robot perceives. With a decision interval
    (``KernelParams.hold``) the robots keep to their actions through the steps between."""
    s = sim.s
    clock = sim.pc.clock
    n = s.pos.shape[0]
    t = clock[CLOCK_STEP]
    sequential = p.schedule == SEQUENTIAL
    start = first
    begins = fresh
    while True:
        if begins:
            advance(p, rng, sim, t)
            start = 0
        if begins or sequential:
            # sequential, one pass: each robot perceives and, unless it gets the turn, keeps
            # to its action; simultaneous, two: every robot perceives, then, unless the step
            # decides, every robot keeps to its action. One place perceives and one keeps.
            for second in range(1 if sequential else 2):
                if second == 1:
                    if not s.active.any():
                        # the robots spent step t receiving cells that drifted onto them
                        clock[CLOCK_STEP] = t + 1
                        _ended(p, sim, t + 1)
                        return
                    if decides(p, t):
                        return
                for i in range(start, n):
                    if not s.active[i]:
                        continue
                    if second == 0:
                        perceived = perceive(p, rng, sim, i, t, bool(True))  # noqa: UP018
                        if not (sequential and perceived):
                            continue
                        if decides(p, t):
                            clock[CLOCK_NEXT] = i
                            return
                    keep(p, rng, sim, i, t)
        begins = True
        t += 1
        clock[CLOCK_STEP] = t
        if _ended(p, sim, t):
            clock[CLOCK_NEXT] = -1
            return


@episodic
def reset_world(
    p: KernelParams, world_rng: np.random.Generator, rng: np.random.Generator, sim: Sim
) -> int:
    """Draw a fresh world and perceive its step 0 (under the sequential schedule, up to the
    first robot's turn); returns ``world.draw_world``'s status."""
    status = draw_fresh(p, world_rng, rng, sim)
    if status == 0:
        on_to_decision(p, rng, sim, int(0), bool(True))  # noqa: UP018, RUF046
    return status


@inlined
def step_world(
    p: KernelParams, rng: np.random.Generator, sim: Sim, actions: NDArray[np.int64],
    turns: NDArray[np.float64], directions: NDArray[np.float64],
) -> None:  # fmt: skip
    """One move of a world whose episode is not over, each robot's reward of it in
    ``pc.reward`` (0 for a robot that did nothing). Simultaneous: every active robot acts on
    its action, and the next step is perceived. Sequential: the robot whose turn it is acts on
    its action (the others' are unused), and the next turn is perceived. Where robots turn
    (``KernelParams.turning``), ``turns`` (robots x 2) are their actions instead. With a decision
    interval (``KernelParams.hold``) a move runs on to the next decision, the robots keeping to
    their actions, and the reward is summed over it."""
    first = act_on_actions(p, rng, sim, actions, turns, directions)
    on_to_decision(p, rng, sim, first, bool(False))  # noqa: UP018


@inlined
def _world_at(b: World, k: int) -> World:
    return World(b.cells[k], b.obstacles[k], b.offsets[k], b.sx[k], b.sy[k], b.sz[k])


@inlined
def _swarm_at(b: Swarm, k: int) -> Swarm:
    return Swarm(
        b.pos[k], b.heading[k], b.active[k], b.steps[k], b.prev_conc[k], b.returns[k],
        b.collisions[k], b.path_length[k], b.pending[k], b.last_state[k], b.last_action[k],
        b.last_reward[k], b.start[k], b.sum_conc[k], b.sum_dist[k], b.last_dist[k],
        b.reading[k], b.reading_grad[k], b.swept[k], b.blocked[k], b.sensed[k],
        b.sensed_grad[k], b.recent[k], b.window_flux[k],
    )  # fmt: skip


@inlined
def _social_at(b: Social, k: int) -> Social:
    return Social(
        b.bound_to[k], b.bumps[k], b.signal[k], b.prev_signal[k], b.signal_grad[k],
        b.signal_flux[k], b.message[k], b.has_message[k],
    )  # fmt: skip


@inlined
def _treatment_at(b: Treatment, k: int) -> Treatment:
    return Treatment(b.load[k], b.treated_at[k], b.tx[k], b.ty[k], b.tz[k], b.treated_sources[k])


@inlined
def _cells_at(b: CellList, k: int) -> CellList:
    return CellList(b.heads[k], b.next[k], b.cell[k], b.origin, b.width, b.dims, b.slack)


@inlined
def _recording_at(b: Recording, k: int) -> Recording:
    return Recording(
        b.pos[k], b.cells[k], b.obstacles[k], b.conc[k], b.dist[k], b.step[k], b.offsets[k],
        b.heading[k], b.sensed[k], b.load[k], b.signal[k],
    )  # fmt: skip


@inlined
def _percept_at(b: Percept, k: int) -> Percept:
    return Percept(
        b.obs[k], b.state[k], b.heard[k], b.target[k], b.target_d[k], b.way[k], b.reward[k],
        b.clock[k], b.held[k], b.turn[k], b.side[k],
    )  # fmt: skip


@inlined
def sim_at(b: Sim, k: int) -> Sim:
    """World ``k`` of a batch whose every array has a leading axis of worlds, as views: the
    worlds' arrays lie side by side in memory, so stepping them one after another streams
    through it (separate arrays per world cost each step a cache miss per array)."""
    return Sim(
        _world_at(b.w, k), _swarm_at(b.s, k), _social_at(b.so, k), _treatment_at(b.tr, k),
        _cells_at(b.near, k), _cells_at(b.radio, k), b.everyone[k], b.found[k], b.sig[k],
        b.sig_scratch[k], _recording_at(b.rec, k), _percept_at(b.pc, k),
    )  # fmt: skip


@njit(cache=True)
def held(
    p: KernelParams,
    batch: Sim,
    world_handles: NDArray[np.uint64],
    handles: NDArray[np.uint64],
    due: NDArray[np.int64],
) -> List[tuple[KernelParams, Sim, NDArray[np.uint64], NDArray[np.uint64], NDArray[np.int64]]]:
    """The one-item list ``step_worlds`` takes, made in compiled code: numba compiles a typed
    list's methods called from Python anew in every process (5 s of each process's first
    environment), where this is kept compiled with the engine."""
    out = List()
    out.append((p, batch, world_handles, handles, due))
    return out


@njit(cache=True, error_model="numpy")
def step_worlds(
    held: List[tuple[KernelParams, Sim, NDArray[np.uint64], NDArray[np.uint64], NDArray[np.int64]]],
    actions: NDArray[np.int64],
    turns: NDArray[np.float64],
    fresh: NDArray[np.bool_],
    directions: NDArray[np.float64],
    advance: bool,
) -> int:
    """Every world k of the batch (its arrays shaped worlds x ...) one move
    (``step_world``) on ``actions[k]`` (one per robot; ``turns[k]``, robots x 2, where robots
    turn), or, where ``fresh[k]``, into a fresh world (its actions unused); a world whose
    episode is over and is not fresh stays as it is, and so does every world not fresh unless
    ``advance`` (a reset of some worlds alone, as Stable-Baselines3 resets a finished world
    within the step that ended it). What each world's robots perceived and got is then in its
    ``pc``. The fresh worlds are drawn first, in world order (a generator of fresh worlds may
    serve many). Returns the first non-zero ``draw_world`` status, or 0.

    ``held[0]`` is (the parameters, the batch, the handles (``generators``) of each world's
    generator of fresh worlds and of its dynamics' generator, room for a number per world):
    one list crosses into compiled code at once, where a tuple of many arrays is checked array
    by array each call (and each list more costs about 0.7 us a call)."""
    p, batch, world_handles, handles, due = held[0]
    return _step_all(p, batch, world_handles, handles, due, actions, turns, fresh, directions,
                     advance)  # fmt: skip


@episodic
def _step_all(
    p: KernelParams, batch: Sim, world_handles: NDArray[np.uint64], handles: NDArray[np.uint64],
    due: NDArray[np.int64], actions: NDArray[np.int64], turns: NDArray[np.float64],
    fresh: NDArray[np.bool_], directions: NDArray[np.float64], advance: bool,
) -> int:  # fmt: skip
    """``step_worlds``' work in one loop without reference counting (``compiled.uncounted``):
    each world's views of the batch and its generators are made as it is reached (the caller
    holds the batch and the generators for the whole call).

    The worlds to draw, then those to step, are listed in ``due`` first and taken from the
    list: a loop whose world is a plain counter let the compiler turn each of a world's views
    of the batch (about 70) into a pointer carried from world to world, held on the stack and
    moved for every world, drawn or stepped or not (measured: 34 ns a world in a call that
    stepped none)."""
    worlds = batch.pc.clock.shape[0]
    drawn = 0
    for k in range(worlds):
        if fresh[k]:
            due[drawn] = k
            drawn += 1
    count = drawn
    if advance:
        clock = batch.pc.clock
        for k in range(worlds):
            if not fresh[k] and clock[k, CLOCK_OVER] == 0:
                due[count] = k
                count += 1
    for j in range(count):
        k = due[j]
        rng = generator_at(handles, k)
        sim = sim_at(batch, k)
        if j < drawn:
            status = draw_fresh(p, generator_at(world_handles, k), rng, sim)
            if status != 0:
                return status
            first = 0
        else:
            first = act_on_actions(p, rng, sim, actions[k], turns[k], directions)
        on_to_decision(p, rng, sim, first, j < drawn)
    return 0
