"""The compiled simulation step: cells drift, obstacles drift, every active robot senses, acts,
moves, collides or reaches, and learns (eq. 2.7).

Everything here runs under numba; the loop over robots is compiled, never a Python loop. Robots
are processed in index order within a step, so a shared Q-table written by many robots in one
step receives every update in a fixed order: the result is exact and reproducible.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from nanonav.engine.fields import SAMPLED_GAUSSIAN, place_sources, sample_many
from nanonav.engine.qlearning import (
    APPROACH_CELL,
    AVOID_OBSTACLE,
    EXPLORE,
    SIGN_THRESHOLD,
)
from nanonav.engine.state import (
    ALPHA_VISITS,
    BEHAVIORS,
    CURVE_COLLISIONS,
    CURVE_REACHED,
    CURVE_RETURN,
    CURVE_ROBOT_STEPS,
    CURVE_STEPS,
    EPISODE,
    EPISODE_START,
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
    GRADIENT,
    LAYOUT_STATUS,
    Q_LEARNING,
    ROBOT_STEPS,
    RULE,
    RUN_AND_TUMBLE,
    SIMPLE_RULE,
    STEP,
    KernelParams,
    Learner,
    Recording,
    Swarm,
    World,
)
from nanonav.engine.world import draw_world

# Proximity cut-offs, in robot steps: an obstacle surface within 2 steps is 'near', a cell within
# 3 steps is 'near'.
OBSTACLE_NEAR_STEPS = 2.0
CELL_NEAR_STEPS = 3.0


@njit(cache=True, error_model="numpy", inline="always")
def _random_unit(rng: np.random.Generator) -> tuple[float, float, float]:
    while True:
        x = rng.standard_normal()
        y = rng.standard_normal()
        z = rng.standard_normal()
        n = math.sqrt(x * x + y * y + z * z)
        if n > 1e-12:
            return x / n, y / n, z / n


@njit(cache=True, error_model="numpy", inline="always")
def _reflect(v: float, half: float) -> float:
    if v > half:
        return 2.0 * half - v
    if v < -half:
        return -2.0 * half - v
    return v


@njit(cache=True, error_model="numpy", inline="always")
def _nearest(points: NDArray[np.float64], x: float, y: float, z: float) -> tuple[int, float]:
    """Index of the point nearest to (x, y, z) and its distance (-1 and inf if none)."""
    best = -1
    best_d2 = np.inf
    for j in range(points.shape[0]):
        dx = points[j, 0] - x
        dy = points[j, 1] - y
        dz = points[j, 2] - z
        d2 = dx * dx + dy * dy + dz * dz
        if d2 < best_d2:
            best_d2 = d2
            best = j
    return best, math.sqrt(best_d2)


@njit(cache=True, error_model="numpy", inline="always")
def _nearest_obstacle(
    obstacles: NDArray[np.float64], radius: float, x: float, y: float, z: float
) -> tuple[int, float]:
    """Index of the nearest obstacle and the distance to its surface (inf if none)."""
    best, distance = _nearest(obstacles, x, y, z)
    return best, distance - radius


@njit(cache=True, error_model="numpy", inline="always")
def _inside_obstacle(
    obstacles: NDArray[np.float64], radius: float, x: float, y: float, z: float
) -> bool:
    r2 = radius * radius
    for j in range(obstacles.shape[0]):
        dx = obstacles[j, 0] - x
        dy = obstacles[j, 1] - y
        dz = obstacles[j, 2] - z
        if dx * dx + dy * dy + dz * dz < r2:
            return True
    return False


@njit(cache=True, error_model="numpy", inline="always")
def _segment_hit(
    obstacles: NDArray[np.float64], radius: float,
    px: float, py: float, pz: float, nx: float, ny: float, nz: float,
) -> int:  # fmt: skip
    """The first obstacle (by index) that the move from p to n passes through, or -1: the whole
    segment is checked, so a fast robot cannot tunnel through a small obstacle."""
    ux = nx - px
    uy = ny - py
    uz = nz - pz
    length2 = ux * ux + uy * uy + uz * uz
    r2 = radius * radius
    # an obstacle whose centre is farther than radius + the move's length cannot be touched
    reach = radius + math.sqrt(length2)
    reach2 = reach * reach
    for j in range(obstacles.shape[0]):
        cx = obstacles[j, 0] - px
        cy = obstacles[j, 1] - py
        cz = obstacles[j, 2] - pz
        if cx * cx + cy * cy + cz * cz >= reach2:
            continue
        # the segment's point nearest the centre: p + f u, f clamped to [0, 1]
        f = 0.0
        if length2 > 0.0:
            f = min(max((cx * ux + cy * uy + cz * uz) / length2, 0.0), 1.0)
        dx = cx - f * ux
        dy = cy - f * uy
        dz = cz - f * uz
        if dx * dx + dy * dy + dz * dz < r2:
            return j
    return -1


@njit(cache=True, error_model="numpy", inline="always")
def _slide(
    p: KernelParams, rng: np.random.Generator, w: World,
    px: float, py: float, pz: float, dx: float, dy: float, dz: float, step: float,
) -> tuple[float, float, float]:  # fmt: skip
    """The direction (dx, dy, dz), or, if a step along it would run into an obstacle, its part
    along that obstacle's surface: a robot that meets an obstacle goes round it rather than
    pushing against it."""
    j = _segment_hit(
        w.obstacles, p.obstacle_radius, px, py, pz, px + step * dx, py + step * dy, pz + step * dz
    )
    if j < 0:
        return dx, dy, dz
    nx, ny, nz = _unit_or_random(
        rng, px - w.obstacles[j, 0], py - w.obstacles[j, 1], pz - w.obstacles[j, 2]
    )
    inward = dx * nx + dy * ny + dz * nz
    if inward >= 0.0:
        return dx, dy, dz
    tx = dx - inward * nx
    ty = dy - inward * ny
    tz = dz - inward * nz
    if tx * tx + ty * ty + tz * tz < 1e-18:
        # head-on: any tangent will do
        tx, ty, tz = ny, -nx, 0.0
        if tx * tx + ty * ty < 1e-18:
            tx, ty, tz = 0.0, nz, -ny
    return _unit_or_random(rng, tx, ty, tz)


@njit(cache=True, error_model="numpy", inline="always")
def _climb(
    p: KernelParams, rng: np.random.Generator, w: World, s: Swarm, i: int,
    px: float, py: float, pz: float, gx: float, gy: float, gz: float,
) -> tuple[float, float, float]:  # fmt: skip
    """Up the sensed gradient, sliding round obstacles; straight on where nothing is sensed."""
    if gx * gx + gy * gy + gz * gz > 0.0:
        dx, dy, dz = _unit_or_random(rng, gx, gy, gz)
    else:
        dx = s.heading[i, 0]
        dy = s.heading[i, 1]
        dz = s.heading[i, 2]
    return _slide(p, rng, w, px, py, pz, dx, dy, dz, p.speed)


@njit(cache=True, error_model="numpy", inline="always")
def _sense_all(p: KernelParams, w: World, s: Swarm, wanted: NDArray[np.bool_]) -> None:
    """The true field and gradient at every ``wanted`` robot, in one pass over the swarm (the
    sources' loop vectorises there, unlike inside the robot loop)."""
    sample_many(
        p.model, w.sx, w.sy, w.sz, p.weight, p.length, p.softening, s.pos, wanted,
        s.reading, s.reading_grad,
    )  # fmt: skip


@njit(cache=True, error_model="numpy", inline="always")
def _sense(p: KernelParams, rng: np.random.Generator, s: Swarm, i: int) -> tuple[float, ...]:
    """Robot ``i``'s reading of the concentration and its gradient, with relative sensor noise."""
    c = s.reading[i]
    gx = s.reading_grad[i, 0]
    gy = s.reading_grad[i, 1]
    gz = s.reading_grad[i, 2]
    if p.noise > 0.0:
        c *= 1.0 + p.noise * rng.standard_normal()
        gx *= 1.0 + p.noise * rng.standard_normal()
        gy *= 1.0 + p.noise * rng.standard_normal()
        gz *= 1.0 + p.noise * rng.standard_normal()
    if p.noise_floor > 0.0:
        c += p.noise_floor * rng.standard_normal()
        gx += p.gradient_noise * rng.standard_normal()
        gy += p.gradient_noise * rng.standard_normal()
        gz += p.gradient_noise * rng.standard_normal()
    if p.detection_threshold > 0.0 and c < p.detection_threshold:
        return 0.0, 0.0, 0.0, 0.0  # below the threshold a robot senses nothing
    return c, gx, gy, gz


@njit(cache=True, error_model="numpy", inline="always")
def _state(
    p: KernelParams,
    c: float,
    prev_c: float,
    gx: float,
    gy: float,
    gz: float,
    obstacle_gap: float,
    cell_d: float,
) -> int:
    """Mixed-radix state index, in the order of ``qlearning.behavior_states`` or
    ``qlearning.direction_states``."""
    near_obstacle = obstacle_gap <= OBSTACLE_NEAR_STEPS * p.speed
    if p.action_set == BEHAVIORS:
        level = int(c > p.level_1) + int(c > p.level_2) + int(c > p.level_3)
        trend = 1 if c > prev_c else 0
        obstacle = 0
        if obstacle_gap <= p.sensing_radius:
            obstacle = 2 if near_obstacle else 1
        cell = 0
        if cell_d <= p.cell_sensing_radius:
            cell = 2 if cell_d <= CELL_NEAR_STEPS * p.speed else 1
        return ((level * 2 + trend) * 3 + obstacle) * 3 + cell
    g = math.sqrt(gx * gx + gy * gy + gz * gz)
    index = 0
    for v in (gx, gy, gz):
        sign = 1
        if g > 0.0:
            if v >= SIGN_THRESHOLD * g:
                sign = 2
            elif v <= -SIGN_THRESHOLD * g:
                sign = 0
        index = index * 3 + sign
    return index * 2 + (1 if near_obstacle else 0)


@njit(cache=True, error_model="numpy", inline="always")
def _choose(
    epsilon: float, rng: np.random.Generator, q: NDArray[np.float64], table: int, state: int
) -> int:
    """Epsilon-greedy over one row of the table; ties among the best are broken at random."""
    actions = q.shape[2]
    if epsilon > 0.0 and rng.random() < epsilon:
        return int(rng.integers(0, actions))
    best = q[table, state, 0]
    ties = 1
    for a in range(1, actions):
        v = q[table, state, a]
        if v > best:
            best = v
            ties = 1
        elif v == best:
            ties += 1
    pick = 0 if ties == 1 else int(rng.integers(0, ties))
    for a in range(actions):
        if q[table, state, a] == best:
            if pick == 0:
                return a
            pick -= 1
    return 0


@njit(cache=True, error_model="numpy", inline="always")
def _unit_or_random(
    rng: np.random.Generator, x: float, y: float, z: float
) -> tuple[float, float, float]:
    n = math.sqrt(x * x + y * y + z * z)
    if n > 1e-300:
        return x / n, y / n, z / n
    return _random_unit(rng)


@njit(cache=True, error_model="numpy", inline="always")
def _behavior_direction(
    p: KernelParams,
    rng: np.random.Generator,
    w: World,
    s: Swarm,
    robot: int,
    action: int,
    px: float,
    py: float,
    pz: float,
    gx: float,
    gy: float,
    gz: float,
    cell: int,
    cell_d: float,
) -> tuple[float, float, float, float]:
    """Unit direction and step length of one of the paper's behaviours. (Arrays are indexed
    element by element here: taking row views in this hot path costs reference counting.)"""
    if action == EXPLORE:
        dx, dy, dz = _random_unit(rng)
        return dx, dy, dz, p.speed
    if action == APPROACH_CELL:
        if cell_d <= p.cell_sensing_radius and cell_d > 0.0:
            return (
                (w.cells[cell, 0] - px) / cell_d,
                (w.cells[cell, 1] - py) / cell_d,
                (w.cells[cell, 2] - pz) / cell_d,
                min(p.speed, cell_d),
            )
        return s.heading[robot, 0], s.heading[robot, 1], s.heading[robot, 2], p.speed
    if action == AVOID_OBSTACLE:
        # up the gradient, and round an obstacle only if the step would run into it
        dx, dy, dz = _climb(p, rng, w, s, robot, px, py, pz, gx, gy, gz)
        return dx, dy, dz, p.speed
    if gx * gx + gy * gy + gz * gz > 0.0:
        dx, dy, dz = _unit_or_random(rng, gx, gy, gz)
        return dx, dy, dz, p.speed
    return s.heading[robot, 0], s.heading[robot, 1], s.heading[robot, 2], p.speed


@njit(cache=True, error_model="numpy", inline="always")
def _learn(
    p: KernelParams,
    q: NDArray[np.float64],
    visits: NDArray[np.int64],
    table: int,
    s: int,
    a: int,
    target: float,
) -> None:
    # eq. 2.7: Q(s,a) <- Q(s,a) + alpha [r + gamma max_a' Q(s',a') - Q(s,a)], alpha constant or
    # alpha / N(s,a)^omega over the visits N of (s, a)
    alpha = p.alpha
    if p.alpha_schedule == ALPHA_VISITS and visits[table, s, a] > 1:
        n = visits[table, s, a]
        alpha = p.alpha / n if p.alpha_exponent == 1.0 else p.alpha / n**p.alpha_exponent
    q[table, s, a] += alpha * (target - q[table, s, a])


@njit(cache=True, error_model="numpy", inline="always")
def _bootstrap(p: KernelParams, q: NDArray[np.float64], table: int, s: int, reward: float) -> float:
    best: float = q[table, s, 0]
    for a in range(1, q.shape[2]):
        best = max(best, q[table, s, a])
    return reward + p.gamma * best


@njit(cache=True, error_model="numpy")
def _move_cells(p: KernelParams, rng: np.random.Generator, w: World) -> None:
    """Random walk of the cells (paper 3.1); a move into an obstacle is refused. Without walls
    a cell may drift out of the cube."""
    for j in range(w.cells.shape[0]):
        x = w.cells[j, 0] + p.cell_std * rng.standard_normal()
        y = w.cells[j, 1] + p.cell_std * rng.standard_normal()
        z = w.cells[j, 2] + p.cell_std * rng.standard_normal()
        if p.walls:
            x = _reflect(x, p.half)
            y = _reflect(y, p.half)
            z = _reflect(z, p.half)
        if not _inside_obstacle(w.obstacles, p.obstacle_radius, x, y, z):
            w.cells[j, 0] = x
            w.cells[j, 1] = y
            w.cells[j, 2] = z


@njit(cache=True, error_model="numpy")
def _redraw_emitters(p: KernelParams, rng: np.random.Generator, w: World) -> None:
    """The sampled Gaussian's emitters, drawn anew around their cells: uniform within
    ``emitter_scatter`` on each axis (the authors' script redraws them every step)."""
    for k in range(w.offsets.shape[0]):
        for a in range(3):
            w.offsets[k, a] = p.emitter_scatter * (2.0 * rng.random() - 1.0)


@njit(cache=True, error_model="numpy")
def _move_obstacles(p: KernelParams, rng: np.random.Generator, w: World, s: Swarm) -> None:
    """Obstacle drift (paper 2.6); a move that would engulf a robot or a cell is refused."""
    r = p.obstacle_radius
    for j in range(w.obstacles.shape[0]):
        x = w.obstacles[j, 0] + p.obstacle_std * rng.standard_normal()
        y = w.obstacles[j, 1] + p.obstacle_std * rng.standard_normal()
        z = w.obstacles[j, 2] + p.obstacle_std * rng.standard_normal()
        if p.walls:
            x = _reflect(x, p.half)
            y = _reflect(y, p.half)
            z = _reflect(z, p.half)
        clear = True
        for i in range(s.pos.shape[0]):
            dx = s.pos[i, 0] - x
            dy = s.pos[i, 1] - y
            dz = s.pos[i, 2] - z
            if dx * dx + dy * dy + dz * dz < r * r:
                clear = False
                break
        if clear:
            margin = r + p.reach_distance
            for k in range(w.cells.shape[0]):
                dx = w.cells[k, 0] - x
                dy = w.cells[k, 1] - y
                dz = w.cells[k, 2] - z
                if dx * dx + dy * dy + dz * dz < margin * margin:
                    clear = False
                    break
        if clear:
            w.obstacles[j, 0] = x
            w.obstacles[j, 1] = y
            w.obstacles[j, 2] = z


@njit(cache=True, error_model="numpy")
def observe(
    p: KernelParams, w: World, s: Swarm, rec: Recording, t: int, final: bool, record: bool
) -> None:
    """Measure the true field and distance at every robot after step ``t`` and add them to the
    per-robot sums of robots still moving at ``t``; if ``record``, store a history row every
    ``record_stride`` steps (and for the ``final`` step). Obstacles that do not move have one
    row, written at the start."""
    row = t // p.record_stride
    on_row = t % p.record_stride == 0
    if final and not on_row:
        row += 1
    keep = record and (on_row or final)
    _sense_all(p, w, s, np.ones(s.pos.shape[0], dtype=np.bool_))
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
    if keep:
        rec.pos[row] = s.pos
        rec.cells[row] = w.cells
        if p.obstacle_std > 0.0:
            rec.obstacles[row] = w.obstacles
        elif t == 0:
            rec.obstacles[0] = w.obstacles
        rec.step[row] = t


@njit(cache=True, error_model="numpy")
def _begin_episode(
    p: KernelParams, world_rng: np.random.Generator, rng: np.random.Generator, w: World,
    s: Swarm, rec: Recording, evaluating: bool, record: bool,
) -> int:  # fmt: skip
    """Reset the swarm and draw a fresh world; returns ``draw_world``'s status."""
    s.active[:] = True
    s.swept[:] = False
    s.steps[:] = 0
    s.prev_conc[:] = -1.0
    s.returns[:] = 0.0
    s.collisions[:] = 0
    s.path_length[:] = 0.0
    s.pending[:] = False
    s.sum_conc[:] = 0.0
    s.sum_dist[:] = 0.0
    s.last_dist[:] = 0.0
    status = draw_world(p, world_rng, w, s)
    if status == 0:
        if p.model == SAMPLED_GAUSSIAN:
            _redraw_emitters(p, rng, w)
        place_sources(p.model, w.cells, w.offsets, w.sx, w.sy, w.sz)
        if record:
            rec.offsets[:] = w.offsets
        if evaluating:
            observe(p, w, s, rec, 0, False, record)
    return status


@njit(cache=True, error_model="numpy", inline="always")
def _over(p: KernelParams, s: Swarm, t: int) -> bool:
    return t >= p.max_steps or not s.active.any()


@njit(cache=True, error_model="numpy")
def _evaluated(s: Swarm, out: NDArray[np.float64]) -> None:
    """Every robot's tallies of an evaluation episode that has ended, into ``out[robot]``."""
    for i in range(s.pos.shape[0]):
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


@njit(cache=True, error_model="numpy")
def run(
    p: KernelParams,
    epsilons: NDArray[np.float64],
    world_rng: np.random.Generator,
    evaluation_rng: np.random.Generator,
    rng: np.random.Generator,
    w: World,
    s: Swarm,
    lrn: Learner,
    rec: Recording,
    counters: NDArray[np.int64],
    curve: NDArray[np.float64],
    evaluation: NDArray[np.float64],
    budget: int,
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
                status = _begin_episode(p, evaluation_rng, rng, w, s, rec, True, record)
            else:
                status = _begin_episode(p, world_rng, rng, w, s, rec, False, False)
            if status != 0:
                counters[LAYOUT_STATUS] = status
                break
        spent = counters[ROBOT_STEPS]
        t = _run_steps(
            p, eps, learn, evaluating, record, rng, w, s, lrn, rec, t, budget, counters
        )  # fmt: skip
        budget -= counters[ROBOT_STEPS] - spent
        if not _over(p, s, t):
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
        counters[EPISODE_START] = counters[ROBOT_STEPS]
        if evaluating:
            _evaluated(s, evaluation[episode - training])
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
    lrn: Learner,
    rec: Recording,
    t: int,
    budget: int,
    counters: NDArray[np.int64],
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
        if p.cell_std > 0.0:
            _move_cells(p, rng, w)
        if p.obstacle_std > 0.0 and w.obstacles.shape[0] > 0:
            _move_obstacles(p, rng, w, s)
        if p.model == SAMPLED_GAUSSIAN:
            _redraw_emitters(p, rng, w)
        place_sources(p.model, w.cells, w.offsets, w.sx, w.sy, w.sz)
        _sense_all(p, w, s, s.active)
        for i in range(n):
            if not s.active[i]:
                continue
            table = 0 if p.shared else i
            px = s.pos[i, 0]
            py = s.pos[i, 1]
            pz = s.pos[i, 2]
            cell, cell_d = _nearest(w.cells, px, py, pz)
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
                continue
            c, gx, gy, gz = _sense(p, rng, s, i)

            # one call site for the behaviours, whoever chooses them: the compiled loop stays small
            behavior = -1
            if p.policy == Q_LEARNING:
                gap = _nearest_obstacle(w.obstacles, p.obstacle_radius, px, py, pz)[1]
                state = _state(p, c, s.prev_conc[i], gx, gy, gz, gap, cell_d)
                if learn and s.pending[i]:
                    target = _bootstrap(p, lrn.q, table, state, s.last_reward[i])
                    _learn(p, lrn.q, lrn.visits, table, s.last_state[i], s.last_action[i], target)
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
                if p.policy == GRADIENT:
                    behavior = AVOID_OBSTACLE  # up the gradient, round obstacles
                elif p.policy == SIMPLE_RULE:
                    sensed = cell_d <= p.cell_sensing_radius and cell_d > 0.0
                    behavior = APPROACH_CELL if sensed else AVOID_OBSTACLE
                elif p.policy == RULE:
                    # advance on a sensed cell; on a reading above the 'mid' level, run and
                    # tumble (a gradient is flat and noisy there, between cells and round a
                    # field's maximum); below it, climb the gradient
                    behavior = AVOID_OBSTACLE
                    if cell_d <= p.cell_sensing_radius and cell_d > 0.0:
                        behavior = APPROACH_CELL
                    elif c > p.level_2:
                        if c > s.prev_conc[i]:
                            gx = 0.0  # no gradient to climb: straight on, round obstacles
                            gy = 0.0
                            gz = 0.0
                        else:
                            behavior = EXPLORE
                elif p.policy == RUN_AND_TUMBLE and c > s.prev_conc[i]:
                    dx = s.heading[i, 0]
                    dy = s.heading[i, 1]
                    dz = s.heading[i, 2]
                else:
                    dx, dy, dz = _random_unit(rng)
            if behavior >= 0:
                dx, dy, dz, step = _behavior_direction(
                    p, rng, w, s, i, behavior, px, py, pz, gx, gy, gz, cell, cell_d
                )
            s.prev_conc[i] = c

            nx = px + step * dx
            ny = py + step * dy
            nz = pz + step * dz
            if p.walls and abs(nx) > p.half:
                nx = _reflect(nx, p.half)
                dx = -dx
            if p.walls and abs(ny) > p.half:
                ny = _reflect(ny, p.half)
                dy = -dy
            if p.walls and abs(nz) > p.half:
                nz = _reflect(nz, p.half)
                dz = -dz
            reward = p.reward_step
            if _segment_hit(w.obstacles, p.obstacle_radius, px, py, pz, nx, ny, nz) >= 0:
                s.collisions[i] += 1
                reward += p.reward_collision
                nx = px
                ny = py
                nz = pz
            else:
                s.path_length[i] += step
                s.heading[i, 0] = dx
                s.heading[i, 1] = dy
                s.heading[i, 2] = dz
            s.pos[i, 0] = nx
            s.pos[i, 1] = ny
            s.pos[i, 2] = nz
            s.steps[i] += 1
            new_d = _nearest(w.cells, nx, ny, nz)[1]
            # paper 2.7: +approach per unit moved toward the source, +reach on arrival
            reward += p.reward_approach * (cell_d - new_d)
            reached = new_d <= p.reach_distance
            if reached:
                reward += p.reward_reach
                s.active[i] = False
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
            observe(p, w, s, rec, t, False, record)
    if _over(p, s, t):
        if learn:
            _finish_episode(p, rng, w, s, lrn)
        if record and t % p.record_stride:
            observe(p, w, s, rec, t, True, record)
    return t


@njit(cache=True, error_model="numpy")
def _finish_episode(
    p: KernelParams, rng: np.random.Generator, w: World, s: Swarm, lrn: Learner
) -> None:
    """Bootstrap the last transition of every robot the step limit stopped (not terminal)."""
    place_sources(p.model, w.cells, w.offsets, w.sx, w.sy, w.sz)
    _sense_all(p, w, s, s.pending)
    for i in range(s.pos.shape[0]):
        if not s.pending[i]:
            continue
        table = 0 if p.shared else i
        px = s.pos[i, 0]
        py = s.pos[i, 1]
        pz = s.pos[i, 2]
        c, gx, gy, gz = _sense(p, rng, s, i)
        gap = _nearest_obstacle(w.obstacles, p.obstacle_radius, px, py, pz)[1]
        cell_d = _nearest(w.cells, px, py, pz)[1]
        state = _state(p, c, s.prev_conc[i], gx, gy, gz, gap, cell_d)
        target = _bootstrap(p, lrn.q, table, state, s.last_reward[i])
        _learn(p, lrn.q, lrn.visits, table, s.last_state[i], s.last_action[i], target)
        s.pending[i] = False
