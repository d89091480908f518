"""The 3-D paths, the paper's Figure 3: the robots' paths and the cells' random walks in the
evaluation episode, with the obstacles to scale."""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.artist import Artist
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from mpl_toolkits.mplot3d.art3d import Poly3DCollection
from numpy.typing import NDArray

from nanonav.engine import SimulationResult, Trajectory
from nanonav.pictures.figure import png
from nanonav.pictures.job.common import (
    CELL_RED,
    ROBOT_BLUE,
    START_GREEN,
    evaluation_trajectory,
    last_row,
    length_unit,
    sized_figure,
    thin,
)

# Beyond these counts the picture stays readable and fast by drawing fewer paths.
MAX_ROBOT_PATHS = 30
MAX_CELL_PATHS = 4
# Obstacles are meshes of 14 x 8 facets up to SMOOTH_SPHERES, 10 x 6 up to COARSE_SPHERES_FROM,
# 6 x 4 beyond (a thousand obstacles, the scenario's limit, draw in about a second); the more
# there are, the fainter, so that the paths drawn over them still read.
SMOOTH_SPHERES = 60
COARSE_SPHERES_FROM = 300


def sphere_facets(count: int) -> tuple[int, int]:
    """(around, pole to pole) facets of each obstacle's mesh: smooth up to ``SMOOTH_SPHERES``
    obstacles, coarser beyond so that a thousand still draw in about a second (and are then
    only a few pixels across)."""
    if count <= SMOOTH_SPHERES:
        return 14, 8
    if count <= COARSE_SPHERES_FROM:
        return 10, 6
    return 6, 4


def sphere_mesh(
    centres: NDArray[np.float64], radius: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Quadrilaterals ``(faces, 4, 3)`` covering a sphere of ``radius`` round each centre, to
    scale, and each face's grey ``(faces,)`` lit from the upper left (a Lambert term computed
    here: matplotlib's own shading needs edge colours)."""
    around, poles = sphere_facets(len(centres))
    theta = np.linspace(0.0, 2 * np.pi, around + 1)
    phi = np.linspace(0.0, np.pi, poles + 1)
    t0, p0 = np.meshgrid(theta[:-1], phi[:-1])
    t1, p1 = np.meshgrid(theta[1:], phi[1:])

    def unit(t: NDArray[np.float64], p: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.stack([np.cos(t) * np.sin(p), np.sin(t) * np.sin(p), np.cos(p)], axis=-1)

    quad = np.stack([unit(t0, p0), unit(t1, p0), unit(t1, p1), unit(t0, p1)], axis=2)
    quad = quad.reshape(-1, 4, 3)
    normal = unit((t0 + t1) / 2, (p0 + p1) / 2).reshape(-1, 3)
    light = np.array([-1.0, -1.0, 1.5]) / np.linalg.norm([-1.0, -1.0, 1.5])
    grey = 0.2 + 0.5 * np.clip(normal @ light, 0.0, 1.0)
    faces = (centres[:, None, None, :] + radius * quad[None]).reshape(-1, 4, 3)
    return faces, np.tile(grey, len(centres))


def _draw_obstacles(ax: Any, centres: NDArray[np.float64], radius: float) -> None:
    if len(centres) == 0:
        return
    faces, grey = sphere_mesh(centres, radius)
    alpha = (
        0.9
        if len(centres) <= SMOOTH_SPHERES
        else 0.6
        if len(centres) <= COARSE_SPHERES_FROM
        else 0.35
    )
    colours = np.column_stack([grey, grey, grey, np.full(len(grey), alpha)])
    ax.add_collection3d(
        Poly3DCollection(faces, facecolors=colours, edgecolors=colours, linewidths=0.2, zorder=1)
    )


def reached_cells(trajectory: Trajectory) -> NDArray[np.int64]:
    """How many robots reached each cell: the cell nearest to a robot when it stopped."""
    counts = np.zeros(trajectory.cells.shape[1], dtype=np.int64)
    for i in np.flatnonzero(trajectory.reached):
        row = last_row(trajectory, int(i))
        gaps = np.linalg.norm(trajectory.cells[row] - trajectory.robots[row, i], axis=1)
        counts[int(np.argmin(gaps))] += 1
    return counts


def cells_with_paths(trajectory: Trajectory) -> NDArray[np.int64]:
    """The cells whose paths the 3-D picture draws: all of them up to ``MAX_CELL_PATHS``, else
    the ones most robots reached (then the first ones), so many cells do not bury the robots."""
    cells = trajectory.cells.shape[1]
    if cells <= MAX_CELL_PATHS:
        return np.arange(cells)
    order = np.lexsort((np.arange(cells), -reached_cells(trajectory)))
    return np.sort(order[:MAX_CELL_PATHS])


def trajectory_figure(result: SimulationResult) -> Figure:
    """Figure 3: the robots' paths (blue, each up to the step it stopped) and the cells' random
    walks (red) in the evaluation episode, with the obstacles to scale (spheres of their radius)
    where they were at the end. Robot ends are drawn over everything: a ring for a robot that
    reached a cell (the cell shows through), a cross for one that did not. Beyond
    ``MAX_ROBOT_PATHS`` robots only the first ones' paths are drawn, beyond ``MAX_CELL_PATHS``
    cells only the paths of the cells most reached (every cell is marked where it ended), and
    the title says so."""
    trajectory = evaluation_trajectory(result)
    half = result.scenario.space.size / 2
    robots_total = trajectory.robots.shape[1]
    cells_total = trajectory.cells.shape[1]
    shown = min(robots_total, MAX_ROBOT_PATHS)
    fig = sized_figure("trajectory")
    # Explicit draw order (spheres, then paths, then markers) reads better than matplotlib's
    # depth sorting, which hides markers and whole paths behind spheres.
    ax: Any = fig.add_subplot(projection="3d", computed_zorder=False)
    _draw_obstacles(ax, trajectory.obstacles_at(-1), trajectory.obstacle_radius)
    width, alpha = (1.6, 0.9) if shown == 1 else (1.0, 0.85) if shown <= 10 else (0.8, 0.7)
    ends = np.empty((shown, 3))
    for i in range(shown):
        path = thin(trajectory.robots[: last_row(trajectory, i) + 1, i])
        ax.plot(*path.T, color=ROBOT_BLUE, linewidth=width, alpha=alpha, zorder=3)
        ends[i] = path[-1]
    starts = trajectory.robots[0, :shown]
    ax.scatter(*starts.T, color=START_GREEN, marker="o", s=22, edgecolors="white",
               linewidths=0.6, depthshade=False, zorder=4)  # fmt: skip
    drawn = cells_with_paths(trajectory)
    for j in drawn:
        ax.plot(*thin(trajectory.cells[:, j]).T, color=CELL_RED, linewidth=1.1, alpha=0.8,
                zorder=2)  # fmt: skip
    star = 170 if cells_total <= MAX_CELL_PATHS else 110 if cells_total <= 20 else 60
    ax.scatter(*trajectory.cells[-1].T, color=CELL_RED, marker="*", s=star, edgecolors="black",
               linewidths=0.7, depthshade=False, zorder=5, label="cell at the end")  # fmt: skip
    reached = trajectory.reached[:shown]
    # Rings, so that the cell a robot reached still shows through; a cross where it failed.
    if reached.any():
        for colour, line in (("white", 3.2), (ROBOT_BLUE, 1.6)):
            ax.scatter(*ends[reached].T, marker="o", s=44, facecolors="none", edgecolors=colour,
                       linewidths=line, depthshade=False, zorder=6,
                       label="robot end, reached")  # fmt: skip
    if not reached.all():
        ax.scatter(*ends[~reached].T, color=ROBOT_BLUE, marker="X", s=60, edgecolors="white",
                   linewidths=0.8, depthshade=False, zorder=6,
                   label="robot end, not reached")  # fmt: skip
    ax.set_xlim(-half, half)
    ax.set_ylim(-half, half)
    ax.set_zlim(-half, half)
    ax.set_box_aspect((1, 1, 1), zoom=0.92)
    length = length_unit(result.scenario)
    ax.set_xlabel(f"x ({length})")
    ax.set_ylabel(f"y ({length})")
    ax.set_zlabel(f"z ({length})")
    who = "robot" if robots_total == 1 else f"{robots_total} robots"
    cells = "cancer cell" if cells_total == 1 else f"{cells_total} cancer cells"
    notes = []
    if shown < robots_total:
        notes.append(f"paths of the first {shown} robots")
    if len(drawn) < cells_total:
        notes.append(f"paths of the {len(drawn)} cells most reached")
    reached_total = int(np.count_nonzero(trajectory.reached))
    title = (
        f"Paths of the {who} and the {cells}, evaluation episode\n"
        f"{reached_total} of {robots_total} reached a cell in {trajectory.length} steps"
    )
    if notes:
        title += f"; {' and '.join(notes)} drawn"
    ax.set_title(title)
    fig.legend(
        handles=_trajectory_handles(
            bool(reached.any()), bool((~reached).any()), len(trajectory.obstacles_at(-1)) > 0,
            trajectory.obstacles_move,
        ),
        loc="outside lower center", ncols=4, frameon=False, fontsize="small",
    )  # fmt: skip
    return fig


def _trajectory_handles(reached: bool, failed: bool, obstacles: bool, moving: bool) -> list[Artist]:
    handles: list[Artist] = [
        Line2D([], [], color=ROBOT_BLUE, label="robot path"),
        Line2D([], [], color=START_GREEN, marker="o", markeredgecolor="white", linestyle="",
               label="robot start"),
        Line2D([], [], color=CELL_RED, linewidth=1.1, label="cell path"),
        Line2D([], [], color=CELL_RED, marker="*", markersize=12, markeredgecolor="black",
               linestyle="", label="cell at the end"),
    ]  # fmt: skip
    if reached:
        handles.append(Line2D([], [], marker="o", markerfacecolor="none",
                              markeredgecolor=ROBOT_BLUE, markeredgewidth=1.6, linestyle="",
                              label="robot end, reached"))  # fmt: skip
    if failed:
        handles.append(Line2D([], [], color=ROBOT_BLUE, marker="X", markersize=8,
                              markeredgecolor="white", linestyle="",
                              label="robot end, not reached"))  # fmt: skip
    if obstacles:
        handles.append(Patch(facecolor="0.45", edgecolor="0.3",
                             label="obstacle at the end" if moving else "obstacle"))  # fmt: skip
    return handles


def trajectory_png(result: SimulationResult) -> bytes:
    """The 3-D paths (``trajectory_figure``) as PNG bytes."""
    return png(trajectory_figure(result))
