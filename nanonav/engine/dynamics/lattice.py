"""The paper's motion, in lattice steps: cells and obstacles drift as random walks, the sampled
Gaussian's emitters are redrawn, and a robot moves one step along a unit direction, reflected by
the walls and stopped by obstacles (the whole segment is checked).

It is a room of its own so that another physics can replace how things move while sensing,
policies and learning stay as they are. Everything here runs under numba; the small functions
are inlined into the compiled step.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from nanonav.engine.compiled import inlined
from nanonav.engine.state import KernelParams, Swarm, World


@inlined
def random_unit(rng: np.random.Generator) -> tuple[float, float, float]:
    """A direction drawn uniformly on the sphere (a normalised Gaussian vector)."""
    while True:
        x = rng.standard_normal()
        y = rng.standard_normal()
        z = rng.standard_normal()
        n = math.sqrt(x * x + y * y + z * z)
        if n > 1e-12:
            return x / n, y / n, z / n


@inlined
def unit_or_random(
    rng: np.random.Generator, x: float, y: float, z: float
) -> tuple[float, float, float]:
    """(x, y, z) made a unit vector, or a random direction where it has no length (a robot
    told to move along a gradient of zero moves somewhere)."""
    n = math.sqrt(x * x + y * y + z * z)
    if n > 1e-300:
        return x / n, y / n, z / n
    return random_unit(rng)


@inlined
def reflect(v: float, half: float) -> float:
    """A coordinate that left the cube of half-width ``half`` mirrored back in off its wall."""
    if v > half:
        return 2.0 * half - v
    if v < -half:
        return -2.0 * half - v
    return v


@inlined
def nearest(points: NDArray[np.float64], x: float, y: float, z: float) -> tuple[int, float]:
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


@inlined
def nearest_obstacle(
    obstacles: NDArray[np.float64], radius: float, x: float, y: float, z: float
) -> tuple[int, float]:
    """Index of the nearest obstacle and the distance to its surface (inf if none)."""
    best, distance = nearest(obstacles, x, y, z)
    return best, distance - radius


@inlined
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


@inlined
def segment_hit(
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


@inlined
def slide(
    p: KernelParams, rng: np.random.Generator, w: World,
    px: float, py: float, pz: float, dx: float, dy: float, dz: float, step: float,
) -> tuple[float, float, float]:  # fmt: skip
    """The direction (dx, dy, dz), or, if a step along it would run into an obstacle, its part
    along that obstacle's surface: a robot that meets an obstacle goes round it rather than
    pushing against it."""
    j = segment_hit(
        w.obstacles, p.obstacle_radius, px, py, pz, px + step * dx, py + step * dy, pz + step * dz
    )
    if j < 0:
        return dx, dy, dz
    nx, ny, nz = unit_or_random(
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
    return unit_or_random(rng, tx, ty, tz)


@njit(cache=True, error_model="numpy")
def move_cells(p: KernelParams, rng: np.random.Generator, w: World) -> None:
    """Random walk of the cells (paper 3.1; in the active Brownian physics, their diffusion); a
    move that brings a cell's centre within ``cell_margin`` of an obstacle's is refused. Without
    walls a cell may drift out of the cube."""
    for j in range(w.cells.shape[0]):
        x = w.cells[j, 0] + p.cell_std * rng.standard_normal()
        y = w.cells[j, 1] + p.cell_std * rng.standard_normal()
        z = w.cells[j, 2] + p.cell_std * rng.standard_normal()
        if p.walls:
            x = reflect(x, p.half)
            y = reflect(y, p.half)
            z = reflect(z, p.half)
        if not _inside_obstacle(w.obstacles, p.cell_margin, x, y, z):
            w.cells[j, 0] = x
            w.cells[j, 1] = y
            w.cells[j, 2] = z


@njit(cache=True, error_model="numpy")
def redraw_emitters(p: KernelParams, rng: np.random.Generator, w: World) -> None:
    """The sampled Gaussian's emitters, drawn anew around their cells: uniform within
    ``emitter_scatter`` on each axis (the authors' script redraws them every step)."""
    for k in range(w.offsets.shape[0]):
        for a in range(3):
            w.offsets[k, a] = p.emitter_scatter * (2.0 * rng.random() - 1.0)


@njit(cache=True, error_model="numpy")
def move_obstacles(p: KernelParams, rng: np.random.Generator, w: World, s: Swarm) -> None:
    """Obstacle drift (paper 2.6); a move that would engulf a robot or a cell is refused."""
    r = p.obstacle_radius
    for j in range(w.obstacles.shape[0]):
        x = w.obstacles[j, 0] + p.obstacle_std * rng.standard_normal()
        y = w.obstacles[j, 1] + p.obstacle_std * rng.standard_normal()
        z = w.obstacles[j, 2] + p.obstacle_std * rng.standard_normal()
        if p.walls:
            x = reflect(x, p.half)
            y = reflect(y, p.half)
            z = reflect(z, p.half)
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


@inlined
def move_robot(
    p: KernelParams, w: World, s: Swarm, i: int,
    px: float, py: float, pz: float, dx: float, dy: float, dz: float, step: float,
) -> tuple[float, float, float, bool]:  # fmt: skip
    """Robot ``i`` at p moves ``step`` along the unit direction d, reflected by the walls (its
    heading with it). A move whose segment passes through an obstacle is blocked: the robot
    stays and a collision is counted; otherwise its path length and heading are updated.
    Returns where it ends and whether it was blocked."""
    nx = px + step * dx
    ny = py + step * dy
    nz = pz + step * dz
    if p.walls and abs(nx) > p.half:
        nx = reflect(nx, p.half)
        dx = -dx
    if p.walls and abs(ny) > p.half:
        ny = reflect(ny, p.half)
        dy = -dy
    if p.walls and abs(nz) > p.half:
        nz = reflect(nz, p.half)
        dz = -dz
    blocked = segment_hit(w.obstacles, p.obstacle_radius, px, py, pz, nx, ny, nz) >= 0
    if blocked:
        s.collisions[i] += 1
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
    return nx, ny, nz, blocked
