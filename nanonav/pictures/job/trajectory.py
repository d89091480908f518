"""The 3-D paths, the paper's Figure 3: the robots' paths and the cells' random walks in the
evaluation episode, with the obstacles to scale; for a swarm that delivers payloads, what each
robot did, the signal it read and which cells were treated."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from matplotlib.artist import Artist
from matplotlib.colors import Normalize, to_rgb
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from mpl_toolkits.mplot3d.art3d import Poly3DCollection
from numpy.typing import NDArray

from nanonav.engine import SimulationResult, Trajectory
from nanonav.engine.simulation import swarm_metrics
from nanonav.pictures.figure import png
from nanonav.pictures.job.common import (
    CELL_RED,
    ROBOT_BLUE,
    START_GREEN,
    beside_the_worlds,
    concentration_unit,
    counted,
    evaluation_trajectory,
    last_row,
    length_unit,
    reach_summary,
    recorded_world,
    sized_figure,
    thin,
    world_times,
)
from nanonav.pictures.job.treatment import delivers_payloads

# Beyond these counts the picture stays readable and fast by drawing fewer paths.
MAX_ROBOT_PATHS = 30
MAX_CELL_PATHS = 4
# Obstacles are meshes of 14 x 8 facets up to SMOOTH_SPHERES, 10 x 6 up to COARSE_SPHERES_FROM,
# 6 x 4 beyond (a thousand obstacles, the scenario's limit, draw in about a second); the more
# there are, the fainter, so that the paths drawn over them still read.
SMOOTH_SPHERES = 60
COARSE_SPHERES_FROM = 300
# A swarm's robots that still carry their payload: their paths, and their ends when they read no
# signal; with broadcast, those that hold a message; with a chemical signal, its colour map.
CARRYING_GREY = "0.55"
CARRYING_ORANGE = "tab:orange"
MESSAGE_PURPLE = "tab:purple"
SIGNAL_CMAP = "viridis"


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


@dataclass(frozen=True)
class SwarmView:
    """What a swarm's robots and cells did by the end of the evaluation episode."""

    ends: NDArray[np.float64]  # (robots, 3) where each robot stopped
    delivered: NDArray[np.bool_]  # (robots,) it carried its payload to a cell
    treated: NDArray[np.bool_] | None  # (cells,) treated at the end; None without a capacity
    signal: NDArray[np.float64] | None  # (robots,) the net chemical signal it read last
    message: NDArray[np.bool_] | None  # (robots,) broadcast: it held a message at its last step


def swarm_view(result: SimulationResult) -> SwarmView | None:
    """The swarm's state at the end, or None for a result without the swarm's numbers
    (``swarm_metrics``), whose robots deliver no payload (``delivers_payloads``: robots that
    only take up space are drawn as the paper's, reached or not) or whose episode did not
    record who delivered where (stored before it was recorded)."""
    trajectory = result.trajectory
    if (
        trajectory is None
        or trajectory.delivered_to is None
        or trajectory.cell_loads is None
        or not swarm_metrics(result.scenario)
        or not delivers_payloads(result.scenario)
    ):
        return None
    robots = trajectory.robots.shape[1]
    rows = np.minimum(
        np.searchsorted(trajectory.step, trajectory.robot_steps, side="left"),
        len(trajectory.step) - 1,
    )
    capacity = result.scenario.cells.capacity
    treated = None if capacity is None else trajectory.cell_loads[-1] >= capacity
    signal = message = None
    if trajectory.signals is not None:
        last = trajectory.signals[rows, np.arange(robots)]
        if result.scenario.communication.model == "broadcast":
            message = last > 0.5  # broadcast records 1 while a robot holds a message, else 0
        else:
            signal = last
    return SwarmView(
        ends=trajectory.robots[rows, np.arange(robots)],
        delivered=trajectory.delivered_to >= 0,
        treated=treated,
        signal=signal,
        message=message,
    )


def cell_radius(result: SimulationResult) -> float | None:
    """A cell's radius in the scenario's lengths where it has one (the active Brownian cell,
    ``physics.cell_radius_um``); None on the lattice, whose cells are points."""
    physics = result.scenario.physics
    return physics.cell_radius_um if physics.model == "active_brownian" else None


def _draw_cells_to_scale(ax: Any, result: SimulationResult, centres: NDArray[np.float64]) -> None:
    """Each cell where it ended as a translucent red sphere of its radius, to the scale of the
    obstacles and the cube (the star marks its centre over it); nothing for point cells."""
    radius = cell_radius(result)
    if radius is None or len(centres) == 0:
        return
    faces, grey = sphere_mesh(centres, radius)
    shade = 0.55 + 0.6 * grey  # the obstacles' light, on red
    colours = np.column_stack(
        [np.clip(shade * c, 0.0, 1.0) for c in to_rgb(CELL_RED)] + [np.full(len(grey), 0.45)]
    )
    ax.add_collection3d(
        Poly3DCollection(
            faces,
            facecolors=colours,
            edgecolors=colours,
            linewidths=0.2,
            zorder=1,
            label="cell to scale",
        )
    )


def _cell_patch(radius: float) -> Patch:
    return Patch(facecolor=CELL_RED, alpha=0.45, edgecolor=CELL_RED,
                 label=f"cell, {radius:g} µm radius to scale")  # fmt: skip


def _cube_axes(ax: Any, result: SimulationResult) -> None:
    """The space's cube, to scale, its axes labelled in the physics' length unit."""
    half = result.scenario.space.size / 2
    ax.set_xlim(-half, half)
    ax.set_ylim(-half, half)
    ax.set_zlim(-half, half)
    ax.set_box_aspect((1, 1, 1), zoom=0.92)
    length = length_unit(result.scenario)
    ax.set_xlabel(f"x ({length})")
    ax.set_ylabel(f"y ({length})")
    ax.set_zlabel(f"z ({length})")


def _paths_axes(fig: Figure, result: SimulationResult) -> Any:
    """The 3-D axes of the paths; with several evaluation worlds, a strip below them with each
    world's time to reach (``draw_worlds``), so that the world drawn is seen among them all."""
    times = world_times(result)
    if len(times) < 2:
        return fig.add_subplot(projection="3d", computed_zorder=False)
    grid = fig.add_gridspec(2, 1, height_ratios=(9, 1))
    ax = fig.add_subplot(grid[0], projection="3d", computed_zorder=False)
    draw_worlds(fig.add_subplot(grid[1]), result, times)
    return ax


def draw_worlds(ax: Any, result: SimulationResult, steps: list[float]) -> None:
    """Every evaluation world's time to reach a cell (Table 1's total steps) as a dot, the
    world the paths show (the first, the one recorded) as a blue ring, and their mean as a
    line: which world is drawn, among how many, and how typical it is."""
    ph = result.scenario.physics
    scale = ph.step_s if ph.model == "active_brownian" else 1.0
    unit = "s" if ph.model == "active_brownian" else "steps"
    times = np.array(steps) * scale
    rows = np.zeros_like(times)
    ax.scatter(times[1:], rows[1:], s=22, color="0.55", zorder=2, clip_on=False)
    ax.scatter(times[:1], rows[:1], s=70, facecolors="none", edgecolors=ROBOT_BLUE,
               linewidths=2.0, zorder=3, clip_on=False)  # fmt: skip
    ax.axvline(float(times.mean()), color="0.2", linestyle="--", linewidth=1.0, zorder=1)
    ax.set_yticks([])
    for side in ("left", "right", "top"):
        ax.spines[side].set_visible(False)
    ax.tick_params(labelsize="small")
    ax.set_xlabel(
        f"time to reach, each of the {len(times)} worlds ({unit}); ring: the one drawn; "
        "dashed: mean",
        fontsize="small",
    )


def trajectory_figure(result: SimulationResult) -> Figure:
    """Figure 3: the robots' paths (blue, each up to the step it stopped) and the cells' random
    walks (red) in the evaluation episode, with the obstacles to scale (spheres of their radius)
    where they were at the end. Robot ends are drawn over everything: a ring for a robot that
    reached a cell (the cell shows through), a cross for one that did not. Beyond
    ``MAX_ROBOT_PATHS`` robots only the first ones' paths are drawn, beyond ``MAX_CELL_PATHS``
    cells only the paths of the cells most reached (every cell is marked where it ended), and
    the title says so.

    A swarm whose episode recorded its deliveries (``swarm_view``) is drawn by what it did: the
    paths and ring ends of the robots that delivered their payload blue, those still carrying
    grey with a cross at the end, coloured by the net signal they read last (a colour bar) with
    a chemical signal, purple or orange by whether they held a message with broadcast; every
    robot's end is marked, and a treated cell is a hollow star, a cell still to treat a filled
    one."""
    trajectory = evaluation_trajectory(result)
    view = swarm_view(result)
    if view is not None:
        return _swarm_figure(result, trajectory, view)
    robots_total = trajectory.robots.shape[1]
    cells_total = trajectory.cells.shape[1]
    shown = min(robots_total, MAX_ROBOT_PATHS)
    fig = sized_figure("trajectory")
    # Explicit draw order (spheres, then paths, then markers) reads better than matplotlib's
    # depth sorting, which hides markers and whole paths behind spheres.
    ax = _paths_axes(fig, result)
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
    _draw_cells_to_scale(ax, result, trajectory.cells[-1])
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
    _cube_axes(ax, result)
    who = "robot" if robots_total == 1 else f"{robots_total} robots"
    cells = "cancer cell" if cells_total == 1 else f"{cells_total} cancer cells"
    notes = []
    if shown < robots_total:
        notes.append(f"paths of the first {shown} robots")
    if len(drawn) < cells_total:
        notes.append(f"paths of the {len(drawn)} cells most reached")
    title = (
        f"Paths of the {who} and the {cells}, {recorded_world(result)}\n"
        f"{reach_summary(result.scenario, trajectory)}"
    )
    if notes:
        title += f"; {' and '.join(notes)} drawn"
    if beside := beside_the_worlds(result):
        title += f"\n{beside}"
    ax.set_title(title)
    fig.legend(
        handles=_trajectory_handles(
            bool(reached.any()), bool((~reached).any()), len(trajectory.obstacles_at(-1)) > 0,
            trajectory.obstacles_move, cell_radius(result),
        ),
        loc="outside lower center", ncols=4, frameon=False, fontsize="small",
    )  # fmt: skip
    return fig


def _trajectory_handles(
    reached: bool, failed: bool, obstacles: bool, moving: bool, radius: float | None
) -> list[Artist]:
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
    if radius is not None:
        handles.append(_cell_patch(radius))
    if obstacles:
        handles.append(Patch(facecolor="0.45", edgecolor="0.3",
                             label="obstacle at the end" if moving else "obstacle"))  # fmt: skip
    return handles


def _swarm_figure(result: SimulationResult, trajectory: Trajectory, view: SwarmView) -> Figure:
    robots_total = trajectory.robots.shape[1]
    cells_total = trajectory.cells.shape[1]
    shown = min(robots_total, MAX_ROBOT_PATHS)
    fig = sized_figure("trajectory")
    ax = _paths_axes(fig, result)
    _draw_obstacles(ax, trajectory.obstacles_at(-1), trajectory.obstacle_radius)
    width, alpha = (1.6, 0.9) if shown == 1 else (1.0, 0.85) if shown <= 10 else (0.8, 0.7)
    for i in range(shown):
        path = thin(trajectory.robots[: last_row(trajectory, i) + 1, i])
        colour = ROBOT_BLUE if view.delivered[i] else CARRYING_GREY
        ax.plot(*path.T, color=colour, linewidth=width, alpha=alpha, zorder=3)
    ax.scatter(*trajectory.robots[0, :shown].T, color=START_GREEN, marker="o", s=22,
               edgecolors="white", linewidths=0.6, depthshade=False, zorder=4)  # fmt: skip
    drawn = cells_with_paths(trajectory)
    for j in drawn:
        ax.plot(*thin(trajectory.cells[:, j]).T, color=CELL_RED, linewidth=1.1, alpha=0.8,
                zorder=2)  # fmt: skip
    star = 170 if cells_total <= MAX_CELL_PATHS else 110 if cells_total <= 20 else 60
    treated = np.zeros(cells_total, dtype=np.bool_) if view.treated is None else view.treated
    ends = trajectory.cells[-1]
    _draw_cells_to_scale(ax, result, ends)
    untreated = "cell at the end" if view.treated is None else "cell to treat"
    if (~treated).any():
        ax.scatter(*ends[~treated].T, color=CELL_RED, marker="*", s=star, edgecolors="black",
                   linewidths=0.7, depthshade=False, zorder=5, label=untreated)  # fmt: skip
    delivered = view.delivered
    if delivered.any():
        for colour, line in (("white", 3.2), (ROBOT_BLUE, 1.6)):
            ax.scatter(*view.ends[delivered].T, marker="o", s=44, facecolors="none",
                       edgecolors=colour, linewidths=line, depthshade=False, zorder=6,
                       label="robot end, delivered")  # fmt: skip
    carrying = ~delivered
    if carrying.any():
        _draw_carrying(fig, ax, result, view, carrying)
    # A treated cell is a hollow star over the rings of the robots bound to it, so both show.
    if treated.any():
        for colour, line in (("white", 3.0), (CELL_RED, 1.5)):
            ax.scatter(*ends[treated].T, marker="*", s=star * 1.8, facecolors="none",
                       edgecolors=colour, linewidths=line, depthshade=False, zorder=7,
                       label="treated cell")  # fmt: skip
    _cube_axes(ax, result)
    notes = []
    if shown < robots_total:
        notes.append(f"paths of the first {shown} robots")
    if len(drawn) < cells_total:
        notes.append(f"paths of the {len(drawn)} cells most reached")
    treated_text = (
        "" if view.treated is None else f"; {int(treated.sum())} of {cells_total} treated"
    )
    who = "robot" if robots_total == 1 else f"{robots_total} robots"
    cells = "cancer cell" if cells_total == 1 else f"{cells_total} cancer cells"
    title = (
        f"Paths of the {who} and the {cells}, {recorded_world(result)}\n"
        f"{int(delivered.sum())} of {robots_total} delivered "
        f"{'its payload' if robots_total == 1 else 'their payloads'} in "
        f"{counted(trajectory.length, 'step')}{treated_text}"
    )
    if notes:
        title += f"\n{' and '.join(notes)} drawn; every robot's end marked"
    fig.suptitle(title, fontsize="medium")
    fig.legend(
        handles=_swarm_handles(view, shown, len(trajectory.obstacles_at(-1)) > 0,
                               trajectory.obstacles_move, cell_radius(result)),
        loc="outside lower center", ncols=4, frameon=False, fontsize="small",
    )  # fmt: skip
    return fig


def _draw_carrying(
    fig: Figure, ax: Any, result: SimulationResult, view: SwarmView, carrying: NDArray[np.bool_]
) -> None:
    """The ends of the robots still carrying their payload: crosses coloured by the signal they
    read last (with a colour bar), by the message they held, or plain orange."""
    ends = view.ends[carrying]
    style: dict[str, Any] = {"marker": "X", "s": 60 if len(ends) <= 30 else 40,
                             "linewidths": 0.6, "depthshade": False, "zorder": 6,
                             "label": "robot end, still carrying"}  # fmt: skip
    if view.signal is not None:
        values = view.signal[carrying]
        low, high = min(0.0, float(values.min())), max(0.0, float(values.max()))
        norm = Normalize(low, high if high > low else low + 1.0)
        points = ax.scatter(*ends.T, c=values, cmap=SIGNAL_CMAP, norm=norm, edgecolors="black",
                            **style)  # fmt: skip
        colourbar = fig.colorbar(points, ax=ax, shrink=0.5, aspect=25, pad=0.12)
        repellent = result.scenario.communication.model == "attractant_repellent"
        colourbar.set_label(
            f"net signal{': attractant - repellent' if repellent else ''} "
            f"({concentration_unit(result.scenario)})"
        )
    elif view.message is not None:
        held = view.message[carrying]
        for mask, colour in ((held, MESSAGE_PURPLE), (~held, CARRYING_ORANGE)):
            if mask.any():
                ax.scatter(*ends[mask].T, color=colour, edgecolors="white", **style)
    else:
        ax.scatter(*ends.T, color=CARRYING_ORANGE, edgecolors="white", **style)


def _swarm_handles(
    view: SwarmView, shown: int, obstacles: bool, moving: bool, radius: float | None
) -> list[Artist]:
    """The legend of what the swarm's picture shows, and only that (``shown``: paths drawn)."""
    delivered = view.delivered
    carrying = ~delivered
    treated = view.treated
    handles: list[Artist] = []
    if delivered[:shown].any():
        handles.append(Line2D([], [], color=ROBOT_BLUE, label="path, delivered"))
    if carrying[:shown].any():
        handles.append(Line2D([], [], color=CARRYING_GREY, label="path, still carrying"))
    handles += [
        Line2D([], [], color=START_GREEN, marker="o", markeredgecolor="white", linestyle="",
               label="robot start"),
        Line2D([], [], color=CELL_RED, linewidth=1.1, label="cell path"),
    ]  # fmt: skip
    if treated is None or not treated.all():
        handles.append(Line2D([], [], color=CELL_RED, marker="*", markersize=12,
                              markeredgecolor="black", linestyle="",
                              label="cell at the end" if treated is None
                              else "cell to treat"))  # fmt: skip
    if treated is not None and treated.any():
        handles.append(Line2D([], [], marker="*", markersize=14, markerfacecolor="none",
                              markeredgecolor=CELL_RED, markeredgewidth=1.5, linestyle="",
                              label="treated cell"))  # fmt: skip
    if delivered.any():
        handles.append(Line2D([], [], marker="o", markerfacecolor="none",
                              markeredgecolor=ROBOT_BLUE, markeredgewidth=1.6, linestyle="",
                              label="delivered its payload"))  # fmt: skip
    cross: dict[str, Any] = {"marker": "X", "markersize": 8, "linestyle": ""}
    if not carrying.any():
        pass
    elif view.message is not None:
        held = view.message[carrying]
        if held.any():
            handles.append(Line2D([], [], color=MESSAGE_PURPLE, markeredgecolor="white",
                                  label="carrying, holds a message", **cross))  # fmt: skip
        if not held.all():
            handles.append(Line2D([], [], color=CARRYING_ORANGE, markeredgecolor="white",
                                  label="carrying, no message", **cross))  # fmt: skip
    elif view.signal is not None:
        handles.append(Line2D([], [], color="0.75", markeredgecolor="black",
                              label="still carrying (colour: last signal read)",
                              **cross))  # fmt: skip
    else:
        handles.append(Line2D([], [], color=CARRYING_ORANGE, markeredgecolor="white",
                              label="still carrying", **cross))  # fmt: skip
    if radius is not None:
        handles.append(_cell_patch(radius))
    if obstacles:
        handles.append(Patch(facecolor="0.45", edgecolor="0.3",
                             label="obstacle at the end" if moving else "obstacle"))  # fmt: skip
    return handles


def trajectory_png(result: SimulationResult) -> bytes:
    """The 3-D paths (``trajectory_figure``) as PNG bytes."""
    return png(trajectory_figure(result))
