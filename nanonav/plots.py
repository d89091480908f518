"""Pictures of a simulation result, as PNG bytes (the paper's Figures 3, 4 and 5, the
learning curve and the learned Q-table).

The view is kept apart from the model: the engine never imports this module, and this module
only reads a finished ``SimulationResult``. Every figure is drawn on its own
``matplotlib.figure.Figure`` with the Agg canvas and saved to a ``BytesIO``; pyplot and its
global state are never used, so a server process keeps no figure alive between requests.
Each PNG is exactly ``PICTURE_PIXELS`` in size (no tight bounding box), which clients can rely
on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import matplotlib
import numpy as np
from matplotlib import patheffects
from matplotlib.artist import Artist
from matplotlib.axes import Axes
from matplotlib.colors import CenteredNorm, LogNorm, Normalize
from matplotlib.figure import Figure
from matplotlib.image import AxesImage
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch
from matplotlib.ticker import MaxNLocator
from mpl_toolkits.mplot3d.art3d import Poly3DCollection
from numpy.typing import NDArray

from nanonav.engine import SimulationResult, Trajectory, field_and_gradient
from nanonav.figures import DPI, new_figure, png
from nanonav.policy import greedy_table, swarm_table

Plane = Literal["xy", "xz", "yz", "all"]
ColourScale = Literal["auto", "linear", "log"]

PICTURE_NAMES: tuple[str, ...] = (
    "heatmap_xy",
    "heatmap_xz",
    "heatmap_yz",
    "heatmap_all",
    "trajectory",
    "concentration",
    "learning",
)
"""The keys of ``render_all``: also the file names (``<name>.png``) the command line writes."""

PICTURE_PIXELS: dict[str, tuple[int, int]] = {
    "heatmap_xy": (640, 620),
    "heatmap_xz": (640, 620),
    "heatmap_yz": (640, 620),
    "heatmap_all": (1520, 540),
    "trajectory": (750, 720),
    "concentration": (800, 600),
    "learning": (900, 600),
}
"""(width, height) in pixels of each picture, whatever it shows (one robot or ten thousand, a
learner or a baseline, any heatmap resolution); the Q-table's grows with the table."""

# Heatmap grids are HEATMAP_RESOLUTION pixels per side unless asked otherwise, within these.
HEATMAP_RESOLUTION = 120
MIN_HEATMAP_RESOLUTION = 20
MAX_HEATMAP_RESOLUTION = 400
# A log colour scale shows this many decades below the maximum, at most: the inverse-square and
# diffusion fields diverge (softened) at their sources and would otherwise squash everything else.
LOG_DECADES = 5.0
# Beyond these counts the 3-D picture and the heatmaps stay readable and fast by drawing less.
MAX_ROBOT_PATHS = 30
MAX_HEATMAP_PATHS = 10
MAX_CELL_PATHS = 4
MAX_LINE_POINTS = 2000
# Obstacles are meshes of 14 x 8 facets up to SMOOTH_SPHERES, 10 x 6 up to COARSE_SPHERES_FROM,
# 6 x 4 beyond (a thousand obstacles, the scenario's limit, draw in about a second); the more
# there are, the fainter, so that the paths drawn over them still read.
SMOOTH_SPHERES = 60
COARSE_SPHERES_FROM = 300

_PLANE_AXES: dict[str, tuple[int, int, int]] = {"xy": (0, 1, 2), "xz": (0, 2, 1), "yz": (1, 2, 0)}
_AXIS_NAMES = "xyz"
_LENGTH = "length units"
_ROBOT_BLUE = "tab:blue"
_CELL_RED = "tab:red"
_START_GREEN = "tab:green"
_HEATMAP_CMAP = "viridis"
_FIELD_NAMES = {
    "gaussian": "Gaussian",
    "inverse_square": "inverse-square",
    "diffusion": "diffusion",
    "sampled_gaussian": "sampled Gaussian",
}


def _new_figure(name: str) -> Figure:
    width, height = PICTURE_PIXELS[name]
    return new_figure(width / DPI, height / DPI)


def _trajectory(result: SimulationResult) -> Trajectory:
    if result.trajectory is None:
        raise ValueError(
            "this result has no evaluation episode to draw (the run was stopped before it "
            "finished); only the learning curve can be drawn"
        )
    return result.trajectory


def _last_row(trajectory: Trajectory, robot: int) -> int:
    """The history row that shows ``robot`` where it stopped: the first row at or after its last
    step (rows may be ``stride`` steps apart, and a stopped robot stays put)."""
    row = int(np.searchsorted(trajectory.step, trajectory.robot_steps[robot], side="left"))
    return min(row, len(trajectory.step) - 1)


def _target_cell(trajectory: Trajectory) -> int:
    """The cell nearest to robot 0 at the last step: the one the heatmap slices through."""
    cells = trajectory.cells[-1]
    robot = trajectory.robots[-1, 0]
    return int(np.argmin(np.linalg.norm(cells - robot, axis=1)))


def _resolve_scale(result: SimulationResult, scale: ColourScale) -> Literal["linear", "log"]:
    if scale != "auto":
        return scale
    return "linear" if result.scenario.biomarker.model == "gaussian" else "log"


# ---------------------------------------------------------------- heatmap (Figure 5)


@dataclass(frozen=True)
class Slice:
    """The true concentration in one plane: ``grid[row, column]`` at the centre of the pixel
    ``(u, v) = (axis[column], axis[row])``, where the plane cuts its normal axis at ``level``;
    ``peak`` is the largest concentration at the cells themselves, which tops the colour
    scale, so that a slice away from the cells reads darker than one through them."""

    plane: str
    level: float
    axis: NDArray[np.float64]
    grid: NDArray[np.float64]
    peak: float


def check_heatmap(size: float, at: float | None, resolution: int) -> None:
    """Refuse a slice outside the cube (``at`` beyond ``[-size/2, size/2]``) or a resolution
    outside ``[MIN_HEATMAP_RESOLUTION, MAX_HEATMAP_RESOLUTION]`` with ``ValueError``."""
    half = size / 2
    if at is not None and not (math.isfinite(at) and -half <= at <= half):
        raise ValueError(f"at must be within [{-half:g}, {half:g}], the cube; it is {at!r}")
    if not MIN_HEATMAP_RESOLUTION <= resolution <= MAX_HEATMAP_RESOLUTION:
        raise ValueError(
            f"resolution must be within [{MIN_HEATMAP_RESOLUTION}, {MAX_HEATMAP_RESOLUTION}] "
            f"pixels per side; it is {resolution}"
        )


def heatmap_slices(
    result: SimulationResult,
    planes: tuple[str, ...],
    resolution: int = HEATMAP_RESOLUTION,
    at: float | None = None,
) -> dict[str, Slice]:
    """The true concentration at the centres of a ``resolution`` square grid over the whole
    cube, in each plane at ``at`` along its normal axis, or through the target cell when
    ``at`` is None; one field evaluation for all planes."""
    check_heatmap(result.scenario.space.size, at, resolution)
    trajectory = _trajectory(result)
    half = result.scenario.space.size / 2
    target = trajectory.cells[-1, _target_cell(trajectory)]
    axis = np.linspace(-half, half, resolution, endpoint=False) + half / resolution
    u, v = np.meshgrid(axis, axis, indexing="xy")
    blocks = []
    levels = []
    for plane in planes:
        a, b, fixed = _PLANE_AXES[plane]
        level = float(target[fixed]) if at is None else at
        block = np.empty((resolution * resolution, 3))
        block[:, a] = u.ravel()
        block[:, b] = v.ravel()
        block[:, fixed] = level
        blocks.append(block)
        levels.append(level)
    cells = trajectory.cells[-1]
    points = np.concatenate([*blocks, cells])
    concentration, _ = field_and_gradient(
        result.scenario.biomarker, cells, trajectory.emitter_offsets, points
    )
    peak = float(concentration[-len(cells) :].max())
    grids = concentration[: -len(cells)].reshape(len(planes), resolution, resolution)
    return {plane: Slice(plane, levels[i], axis, grids[i], peak) for i, plane in enumerate(planes)}


def _norm(slices: list[Slice], scale: Literal["linear", "log"]) -> Normalize:
    """One colour scale for the slices, topped by the concentration at the cells (or the
    slices' own maximum, were it larger); a log scale spans at most ``LOG_DECADES``."""
    values = [s.grid for s in slices]
    top = max(max(float(v.max()) for v in values), slices[0].peak)
    if scale == "linear":
        return Normalize(vmin=0.0, vmax=top if top > 0 else 1.0)
    positive = [v[v > 0] for v in values]
    low = min((float(p.min()) for p in positive if p.size), default=top)
    top = top if top > 0 else 1.0
    low = max(low, top * 10.0**-LOG_DECADES)
    return LogNorm(vmin=low if low < top else top / 10.0, vmax=top)


@dataclass(frozen=True)
class _Drawn:
    """What a slice showed, for the legend."""

    image: AxesImage
    obstacles_cut: bool
    cells_in: bool
    cells_off: bool
    reached: bool
    failed: bool


_HALO = [patheffects.withStroke(linewidth=2.2, foreground="white", alpha=0.7)]


def _draw_paths(ax: Axes, trajectory: Trajectory, a: int, b: int) -> tuple[bool, bool]:
    """The paths of the first ``MAX_HEATMAP_PATHS`` robots projected on the plane (thin blue
    lines on a white halo, so that they read on any colour, fewer than in 3-D so that they do
    not hide the field), their starts and their ends, drawn over the cells; whether any end
    reached, any failed."""
    shown = min(trajectory.robots.shape[1], MAX_HEATMAP_PATHS)
    ends = np.empty((shown, 2))
    for i in range(shown):
        path = _thin(trajectory.robots[: _last_row(trajectory, i) + 1, i])
        ax.plot(path[:, a], path[:, b], color=_ROBOT_BLUE, linewidth=1.2,
                path_effects=_HALO, zorder=2)  # fmt: skip
        ends[i] = path[-1, [a, b]]
    starts = trajectory.robots[0, :shown]
    ax.scatter(starts[:, a], starts[:, b], s=18, color=_START_GREEN, edgecolors="white",
               linewidths=0.7, zorder=4)  # fmt: skip
    reached = trajectory.reached[:shown]
    if reached.any():
        for colour, line in (("white", 3.0), (_ROBOT_BLUE, 1.5)):
            ax.scatter(ends[reached, 0], ends[reached, 1], s=34, facecolors="none",
                       edgecolors=colour, linewidths=line, zorder=7)  # fmt: skip
    if not reached.all():
        ax.scatter(ends[~reached, 0], ends[~reached, 1], s=50, marker="X", color=_ROBOT_BLUE,
                   edgecolors="white", linewidths=0.7, zorder=7)  # fmt: skip
    return bool(reached.any()), bool((~reached).any())


def _draw_slice(ax: Axes, result: SimulationResult, cut: Slice, norm: Normalize) -> _Drawn:
    trajectory = _trajectory(result)
    half = result.scenario.space.size / 2
    a, b, fixed = _PLANE_AXES[cut.plane]
    grid = np.clip(cut.grid, norm.vmin, None) if isinstance(norm, LogNorm) else cut.grid
    # Nearest: every computed value is one square pixel, so the resolution asked for shows.
    image = ax.imshow(grid, origin="lower", extent=(-half, half, -half, half),
                      cmap=_HEATMAP_CMAP, norm=norm, interpolation="nearest")  # fmt: skip
    radius = trajectory.obstacle_radius
    obstacles_cut = False
    for centre in trajectory.obstacles_at(-1):
        depth = abs(float(centre[fixed]) - cut.level)
        if depth < radius:
            obstacles_cut = True
            ax.add_patch(
                Circle((float(centre[a]), float(centre[b])), float(np.sqrt(radius**2 - depth**2)),
                       facecolor="black", edgecolor="white", linewidth=0.8, alpha=0.85, zorder=1)
            )  # fmt: skip
    reached, failed = _draw_paths(ax, trajectory, a, b)
    cells = trajectory.cells[-1]
    pixel = 2 * half / len(cut.axis)
    near = np.abs(cells[:, fixed] - cut.level) <= max(result.scenario.reach_distance, pixel)
    if (~near).any():
        ax.scatter(cells[~near, a], cells[~near, b], s=60, facecolors="none",
                   edgecolors=_CELL_RED, linewidths=2, zorder=6)  # fmt: skip
    if near.any():
        ax.scatter(cells[near, a], cells[near, b], s=80, color=_CELL_RED, edgecolors="white",
                   linewidths=1.2, zorder=6)  # fmt: skip
    ax.set_xlim(-half, half)
    ax.set_ylim(-half, half)
    ax.set_aspect("equal")
    ax.set_xlabel(f"{_AXIS_NAMES[a]} ({_LENGTH})")
    ax.set_ylabel(f"{_AXIS_NAMES[b]} ({_LENGTH})")
    ax.set_title(f"{cut.plane.upper()} plane at {_AXIS_NAMES[fixed]} = {cut.level:.1f}")
    return _Drawn(image, obstacles_cut, bool(near.any()), bool((~near).any()), reached, failed)


def _heatmap_legend_handles(drawn: list[_Drawn], robots: int) -> list[Artist]:
    paths = "robot path (projected)"
    if robots > MAX_HEATMAP_PATHS:
        paths = f"paths of the first {MAX_HEATMAP_PATHS} of {robots} robots (projected)"
    handles: list[Artist] = [
        Line2D([], [], color=_ROBOT_BLUE, linewidth=1.2, path_effects=_HALO, label=paths),
        Line2D([], [], marker="o", linestyle="", color=_START_GREEN, markeredgecolor="white",
               label="robot start"),
    ]  # fmt: skip
    if any(d.reached for d in drawn):
        handles.append(Line2D([], [], marker="o", linestyle="", markerfacecolor="none",
                              markeredgecolor=_ROBOT_BLUE, markeredgewidth=1.5,
                              label="robot end, reached"))  # fmt: skip
    if any(d.failed for d in drawn):
        handles.append(Line2D([], [], marker="X", linestyle="", color=_ROBOT_BLUE,
                              markeredgecolor="white", markersize=8,
                              label="robot end, not reached"))  # fmt: skip
    if any(d.cells_in for d in drawn):
        handles.append(Line2D([], [], marker="o", linestyle="", color=_CELL_RED,
                              markeredgecolor="white", markersize=9,
                              label="cell in the slice"))  # fmt: skip
    if any(d.cells_off for d in drawn):
        handles.append(Line2D([], [], marker="o", linestyle="", markerfacecolor="none",
                              markeredgecolor=_CELL_RED, markeredgewidth=2, markersize=8,
                              label="cell off the slice (projected)"))  # fmt: skip
    if any(d.obstacles_cut for d in drawn):
        handles.append(
            Patch(facecolor="black", edgecolor="grey", label="obstacle cut by the slice")
        )
    return handles


def heatmap_figure(
    result: SimulationResult,
    slices: dict[str, Slice],
    scale: Literal["linear", "log"],
    *,
    through_target: bool = True,
) -> Figure:
    """The slices side by side on one colour scale, each with the robots' paths projected on
    it, the cells and the obstacles it cuts; one or three planes."""
    trajectory = _trajectory(result)
    planes = tuple(slices)
    single = len(planes) == 1
    fig = _new_figure("heatmap_xy" if single else "heatmap_all")
    axes = fig.subplots(1, len(planes), squeeze=False)[0]
    norm = _norm(list(slices.values()), scale)
    drawn = [_draw_slice(ax, result, slices[p], norm) for ax, p in zip(axes, planes, strict=True)]
    colourbar = fig.colorbar(drawn[0].image, ax=list(axes), shrink=0.9)
    colourbar.set_label(f"biomarker concentration (a.u.{', log scale' if scale == 'log' else ''})")
    model = _FIELD_NAMES[result.scenario.biomarker.model]
    where = "through the cell nearest to robot 0" if through_target else "at the chosen level"
    fig.suptitle(
        f"Biomarker concentration, {model} field, at the last step ({trajectory.length})\n"
        f"of the evaluation episode; slice{'' if single else 's'} {where}"
    )
    handles = _heatmap_legend_handles(drawn, trajectory.robots.shape[1])
    fig.legend(
        handles=handles,
        loc="outside lower center",
        ncols=min(len(handles), 2 if single else 4),
        frameon=False,
        fontsize="small",
    )
    return fig


def heatmap_png(
    result: SimulationResult,
    plane: Plane = "all",
    *,
    at: float | None = None,
    resolution: int = HEATMAP_RESOLUTION,
    scale: ColourScale = "auto",
) -> bytes:
    """Figure 5: the true concentration at the end of the evaluation episode in a plane over
    the whole cube, with the robots' paths projected on it, the cells and the obstacles the
    slice cuts. ``at`` is where the slice cuts the plane's normal axis (z for ``xy``), within
    the cube; by default the slice goes through the target cell (the cell nearest to robot 0
    at the end). ``plane="all"`` draws XY, XZ and YZ side by side on one colour scale (with
    ``at``: at x, y and z = ``at``). ``resolution`` is the grid's pixels per side
    (``MIN_HEATMAP_RESOLUTION`` to ``MAX_HEATMAP_RESOLUTION``); the PNG's size does not change
    with it. ``scale="auto"`` is linear for the Gaussian fields and logarithmic for the
    inverse-square and diffusion fields, which span decades."""
    planes = ("xy", "xz", "yz") if plane == "all" else (plane,)
    slices = heatmap_slices(result, planes, resolution, at)
    figure = heatmap_figure(
        result, slices, _resolve_scale(result, scale), through_target=at is None
    )
    return png(figure)


# ---------------------------------------------------------------- trajectory (Figure 3)


def _thin(path: NDArray[np.float64]) -> NDArray[np.float64]:
    """At most ``MAX_LINE_POINTS`` rows of a path, always keeping its last point."""
    if len(path) <= MAX_LINE_POINTS:
        return path
    stride = int(np.ceil(len(path) / MAX_LINE_POINTS))
    return np.concatenate([path[::stride], path[-1:]])


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
        row = _last_row(trajectory, int(i))
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
    trajectory = _trajectory(result)
    half = result.scenario.space.size / 2
    robots_total = trajectory.robots.shape[1]
    cells_total = trajectory.cells.shape[1]
    shown = min(robots_total, MAX_ROBOT_PATHS)
    fig = _new_figure("trajectory")
    # Explicit draw order (spheres, then paths, then markers) reads better than matplotlib's
    # depth sorting, which hides markers and whole paths behind spheres.
    ax: Any = fig.add_subplot(projection="3d", computed_zorder=False)
    _draw_obstacles(ax, trajectory.obstacles_at(-1), trajectory.obstacle_radius)
    width, alpha = (1.6, 0.9) if shown == 1 else (1.0, 0.85) if shown <= 10 else (0.8, 0.7)
    ends = np.empty((shown, 3))
    for i in range(shown):
        path = _thin(trajectory.robots[: _last_row(trajectory, i) + 1, i])
        ax.plot(*path.T, color=_ROBOT_BLUE, linewidth=width, alpha=alpha, zorder=3)
        ends[i] = path[-1]
    starts = trajectory.robots[0, :shown]
    ax.scatter(*starts.T, color=_START_GREEN, marker="o", s=22, edgecolors="white",
               linewidths=0.6, depthshade=False, zorder=4)  # fmt: skip
    drawn = cells_with_paths(trajectory)
    for j in drawn:
        ax.plot(*_thin(trajectory.cells[:, j]).T, color=_CELL_RED, linewidth=1.1, alpha=0.8,
                zorder=2)  # fmt: skip
    star = 170 if cells_total <= MAX_CELL_PATHS else 110 if cells_total <= 20 else 60
    ax.scatter(*trajectory.cells[-1].T, color=_CELL_RED, marker="*", s=star, edgecolors="black",
               linewidths=0.7, depthshade=False, zorder=5, label="cell at the end")  # fmt: skip
    reached = trajectory.reached[:shown]
    # Rings, so that the cell a robot reached still shows through; a cross where it failed.
    if reached.any():
        for colour, line in (("white", 3.2), (_ROBOT_BLUE, 1.6)):
            ax.scatter(*ends[reached].T, marker="o", s=44, facecolors="none", edgecolors=colour,
                       linewidths=line, depthshade=False, zorder=6,
                       label="robot end, reached")  # fmt: skip
    if not reached.all():
        ax.scatter(*ends[~reached].T, color=_ROBOT_BLUE, marker="X", s=60, edgecolors="white",
                   linewidths=0.8, depthshade=False, zorder=6,
                   label="robot end, not reached")  # fmt: skip
    ax.set_xlim(-half, half)
    ax.set_ylim(-half, half)
    ax.set_zlim(-half, half)
    ax.set_box_aspect((1, 1, 1), zoom=0.92)
    ax.set_xlabel(f"x ({_LENGTH})")
    ax.set_ylabel(f"y ({_LENGTH})")
    ax.set_zlabel(f"z ({_LENGTH})")
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
        Line2D([], [], color=_ROBOT_BLUE, label="robot path"),
        Line2D([], [], color=_START_GREEN, marker="o", markeredgecolor="white", linestyle="",
               label="robot start"),
        Line2D([], [], color=_CELL_RED, linewidth=1.1, label="cell path"),
        Line2D([], [], color=_CELL_RED, marker="*", markersize=12, markeredgecolor="black",
               linestyle="", label="cell at the end"),
    ]  # fmt: skip
    if reached:
        handles.append(Line2D([], [], marker="o", markerfacecolor="none",
                              markeredgecolor=_ROBOT_BLUE, markeredgewidth=1.6, linestyle="",
                              label="robot end, reached"))  # fmt: skip
    if failed:
        handles.append(Line2D([], [], color=_ROBOT_BLUE, marker="X", markersize=8,
                              markeredgecolor="white", linestyle="",
                              label="robot end, not reached"))  # fmt: skip
    if obstacles:
        handles.append(Patch(facecolor="0.45", edgecolor="0.3",
                             label="obstacle at the end" if moving else "obstacle"))  # fmt: skip
    return handles


def trajectory_png(result: SimulationResult) -> bytes:
    """The 3-D paths (``trajectory_figure``) as PNG bytes."""
    return png(trajectory_figure(result))


# ---------------------------------------------------------------- concentration (Figure 4)


@dataclass(frozen=True)
class SearchingStats:
    """Per history row, over the robots still searching then: how many, and the median and
    quartiles of their distance to the nearest cell and of the concentration they sense
    (NaN where none searches)."""

    step: NDArray[np.int64]
    searching: NDArray[np.int64]
    distance: NDArray[np.float64]  # (rows, 3): 25th, 50th and 75th percentiles
    concentration: NDArray[np.float64]  # (rows, 3)


def searching_mask(trajectory: Trajectory) -> NDArray[np.bool_]:
    """``(rows, robots)``: whether each robot is still searching at each row's step. A robot
    searches up to the step it reached a cell, excluded (it stops there while the cell drifts
    on), or to the end of the episode when it never reached one."""
    step = trajectory.step[:, None]
    own = trajectory.robot_steps[None, :]
    mask: NDArray[np.bool_] = (step < own) | ((step == own) & ~trajectory.reached[None, :])
    return mask


def searching_stats(trajectory: Trajectory) -> SearchingStats:
    """What a swarm's concentration picture draws: the robots still searching, row by row."""
    mask = searching_mask(trajectory)
    count = mask.sum(axis=1)
    quartiles = []
    for values in (trajectory.distance, trajectory.concentration):
        out = np.full((len(count), 3), np.nan)
        rows = count > 0
        masked = np.where(mask[rows], values[rows], np.nan)
        out[rows] = np.nanpercentile(masked, [25, 50, 75], axis=1).T
        quartiles.append(out)
    return SearchingStats(trajectory.step, count, quartiles[0], quartiles[1])


def _reach_summary(trajectory: Trajectory) -> str:
    n = len(trajectory.reached)
    reached = int(np.count_nonzero(trajectory.reached))
    if n == 1:
        if reached:
            return f"reached a cell at step {int(trajectory.robot_steps[0])}"
        return f"did not reach a cell in {trajectory.length} steps"
    return f"{reached} of {n} reached a cell within {trajectory.length} steps"


def _concentration_label(log_scale: bool) -> str:
    return f"biomarker concentration (a.u.{', log scale' if log_scale else ''})"


def concentration_figure(result: SimulationResult) -> Figure:
    """Figure 4: the biomarker concentration at the robots and their distance to the nearest
    cell over the steps of the evaluation episode, each robot only while it searches (a robot
    that reached a cell stops, while the cell drifts on).

    One robot, as in the paper: concentration (red, left axis) and distance (blue, right axis)
    up to the step it stopped. A swarm: three panels over the robots still searching at each
    step, the median and the interquartile band of their distance, of their concentration, and
    how many still search, so that thousands of robots read as easily as two.
    """
    trajectory = _trajectory(result)
    log_scale = _resolve_scale(result, "auto") == "log"
    fig = _new_figure("concentration")
    if trajectory.robots.shape[1] == 1:
        _draw_one_robot(fig, trajectory, log_scale)
    else:
        _draw_searching_swarm(fig, trajectory, log_scale)
    fig.suptitle(
        "Biomarker concentration and distance to the nearest cell, evaluation episode\n"
        + _reach_summary(trajectory)
    )
    return fig


def _draw_one_robot(fig: Figure, trajectory: Trajectory, log_scale: bool) -> None:
    left = fig.add_subplot()
    right = left.twinx()
    end = _last_row(trajectory, 0) + 1
    steps = trajectory.step[:end]
    left.plot(steps, trajectory.concentration[:end, 0], color=_CELL_RED, linewidth=1.8)
    right.plot(steps, trajectory.distance[:end, 0], color=_ROBOT_BLUE, linewidth=1.8)
    if log_scale:
        left.set_yscale("log")
    left.set_xlabel("step")
    left.set_ylabel(_concentration_label(log_scale), color=_CELL_RED)
    right.set_ylabel(f"distance to the nearest cell ({_LENGTH})", color=_ROBOT_BLUE)
    left.tick_params(axis="y", colors=_CELL_RED)
    right.tick_params(axis="y", colors=_ROBOT_BLUE)
    right.set_ylim(bottom=0)
    left.set_xlim(0, max(int(steps[-1]), 1))
    left.grid(alpha=0.3)
    fig.legend(
        handles=[
            Line2D([], [], color=_CELL_RED, linewidth=1.8, label="concentration at the robot"),
            Line2D([], [], color=_ROBOT_BLUE, linewidth=1.8, label="distance to the nearest cell"),
        ],
        loc="outside lower center",
        ncols=2,
        frameon=False,
    )


def _draw_searching_swarm(fig: Figure, trajectory: Trajectory, log_scale: bool) -> None:
    stats = searching_stats(trajectory)
    n = trajectory.robots.shape[1]
    distance_ax, concentration_ax, count_ax = fig.subplots(
        3, 1, sharex=True, height_ratios=(3, 3, 1.7)
    )
    for ax, quartiles, colour in (
        (distance_ax, stats.distance, _ROBOT_BLUE),
        (concentration_ax, stats.concentration, _CELL_RED),
    ):
        ax.fill_between(stats.step, quartiles[:, 0], quartiles[:, 2], color=colour, alpha=0.2,
                        linewidth=0)  # fmt: skip
        ax.plot(stats.step, quartiles[:, 1], color=colour, linewidth=1.8)
        ax.grid(alpha=0.3)
    distance_ax.set_ylabel(f"distance\n({_LENGTH})")
    distance_ax.set_ylim(bottom=0)
    distance_ax.set_title("distance to the nearest cell", fontsize="medium")
    if log_scale:
        concentration_ax.set_yscale("log")
    concentration_ax.set_ylabel(f"concentration\n(a.u.{', log' if log_scale else ''})")
    concentration_ax.set_title("biomarker concentration at the robot", fontsize="medium")
    count_ax.fill_between(stats.step, stats.searching, step="post", color=_ROBOT_BLUE, alpha=0.2,
                          linewidth=0)  # fmt: skip
    count_ax.step(stats.step, stats.searching, where="post", color=_ROBOT_BLUE, linewidth=1.5)
    count_ax.set_ylim(0, n * 1.05)
    count_ax.set_ylabel("robots")
    count_ax.set_title(f"robots still searching (of {n})", fontsize="medium")
    count_ax.yaxis.set_major_locator(MaxNLocator(nbins=3, integer=True))
    count_ax.grid(alpha=0.3)
    count_ax.set_xlabel("step")
    count_ax.set_xlim(0, max(int(stats.step[-1]), 1))
    fig.legend(
        handles=[
            Line2D([], [], color="0.25", linewidth=1.8,
                   label="median over the robots still searching"),
            Patch(facecolor="0.25", alpha=0.2, label="interquartile range"),
        ],
        loc="outside lower center",
        ncols=2,
        frameon=False,
    )  # fmt: skip


def concentration_png(result: SimulationResult) -> bytes:
    """The concentration picture (``concentration_figure``) as PNG bytes."""
    return png(concentration_figure(result))


# ---------------------------------------------------------------- learning curve

_POLICY_NAMES = {
    "q_learning": "Q-learning",
    "gradient": "gradient climbing",
    "run_and_tumble": "run and tumble",
    "rule": "the fixed rule",
    "random": "the random walk",
}
# Policies that learn nothing: their episodes are independent trials of the same behaviour.
BASELINES = frozenset({"gradient", "run_and_tumble", "rule", "random"})
# The moving mean spans about an eighth of the episodes, within these bounds; runs shorter than
# SMOOTH_FROM episodes show the raw values only.
SMOOTH_FROM = 4
MAX_SMOOTHING_WINDOW = 100
# The raw values behind the moving mean are drawn with points up to this many episodes.
POINTS_UP_TO = 60
_EVALUATION_ORANGE = "tab:orange"


@dataclass(frozen=True)
class _Panel:
    """One panel of the learning curve: an episode field and the summary field it matches."""

    key: str
    summary_key: str | None
    title: str
    ylabel: str
    factor: float = 1.0


_LEARNING_PANELS = (
    _Panel("steps", "episode_steps", "steps per episode", "steps"),
    _Panel("success_rate", "success_rate", "robots that reached a cell", "success rate (%)", 100.0),
    _Panel("mean_return", "mean_return", "mean return per robot", "return (reward units)"),
    _Panel("epsilon", None, "exploration rate", "epsilon"),
)


def smoothing_window(episodes: int) -> int:
    """Episodes in the learning curve's moving mean: about an eighth of the run (at least 2, at
    most ``MAX_SMOOTHING_WINDOW``), so a short run is smoothed a little and a long one enough;
    1 (no mean) below ``SMOOTH_FROM`` episodes."""
    if episodes < SMOOTH_FROM:
        return 1
    return min(max(2, math.ceil(episodes / 8)), MAX_SMOOTHING_WINDOW)


def moving_mean(values: NDArray[np.float64], window: int) -> NDArray[np.float64]:
    """The trailing mean over ``window`` values; the first ``window - 1`` average those before
    them, so the curve starts with the first episode."""
    sums = np.concatenate([[0.0], np.cumsum(values)])
    end = np.arange(1, len(values) + 1)
    start = np.maximum(end - window, 0)
    mean: NDArray[np.float64] = (sums[end] - sums[start]) / (end - start)
    return mean


def _evaluation_worlds(result: SimulationResult) -> int | None:
    worlds = result.summary.get("worlds")
    if worlds is not None:
        return int(worlds)
    return len(result.worlds) or None


def _evaluation_point(
    result: SimulationResult, key: str, factor: float
) -> tuple[float, tuple[float, float] | None] | None:
    """The evaluation's mean of ``key`` and its 95% interval over the worlds (None when there is
    no spread to show), both times ``factor``."""
    value = result.summary.get(key)
    if value is None or not math.isfinite(float(value)):
        return None
    spread = result.uncertainty.get(key) or {}
    low, high = spread.get("ci_low"), spread.get("ci_high")
    interval = None
    if low is not None and high is not None:
        interval = (float(low) * factor, float(high) * factor)
    return float(value) * factor, interval


def _trials(result: SimulationResult, evaluated: bool) -> tuple[str, list[dict[str, Any]]]:
    """What the learning curve draws along x: the training episodes, or, for a baseline that
    trained none, its evaluation worlds (trials of the same fixed behaviour all the same)."""
    if result.scenario.robots.policy in BASELINES and not result.episodes and evaluated:
        worlds = [
            {**w, "episode": i, "steps": w["episode_steps"]} for i, w in enumerate(result.worlds)
        ]
        return "evaluation world", worlds
    return "episode", result.episodes


def learning_figure(result: SimulationResult) -> Figure:
    """The learning curve, one point per training episode, with its moving mean
    (``smoothing_window``) over the raw values drawn faint.

    A learner (Q-learning) gets four panels: steps, success rate, mean return and the
    exploration rate, and the greedy evaluation after them, its mean over the evaluation worlds
    with the 95% interval. A baseline learns nothing: three panels of its trials, with neither
    exploration rate nor evaluation (which would only be more trials); with no training
    episodes its evaluation worlds are drawn as the trials. A run stopped early shows the
    episodes it finished.
    """
    baseline = result.scenario.robots.policy in BASELINES
    evaluated = result.completed and result.trajectory is not None and bool(result.summary)
    trial_name, trials = _trials(result, evaluated)
    if not trials and not evaluated:
        raise ValueError("this result has no finished episode to draw a learning curve from")
    panels = _LEARNING_PANELS if trials and not baseline else _LEARNING_PANELS[:3]
    show_evaluation = evaluated and not baseline
    planned = result.scenario.learning.episodes if trial_name == "episode" else len(trials)
    index = np.array([float(e["episode"]) for e in trials])
    last = max(len(trials), planned) - 1.0  # the last episode planned or finished
    gap = max(1.0, 0.06 * max(last, 1.0))  # between the last episode and the evaluation
    x_eval = last + gap if trials else 0.0
    window = smoothing_window(len(trials))
    fig = _new_figure("learning")
    grid = fig.subplots(2, 2, sharex=True) if len(panels) == 4 else fig.subplots(3, 1, sharex=True)
    axes: list[Axes] = list(grid.ravel())
    for ax, panel in zip(axes, panels, strict=True):
        if trials:
            values = np.array([float(e[panel.key]) * panel.factor for e in trials])
            smooth = window if panel.key != "epsilon" else 1
            _draw_trials(ax, index, values, smooth, points=len(trials) <= POINTS_UP_TO)
        if show_evaluation and panel.summary_key is not None:
            _draw_evaluation(ax, result, panel, x_eval)
            if trials:
                ax.axvline(last + gap / 2, color="0.6", linewidth=0.8, linestyle=":")
        ax.set_title(panel.title, fontsize="medium")
        ax.set_ylabel(panel.ylabel)
        ax.grid(alpha=0.3)
        if panel.key == "success_rate":
            ax.set_ylim(-5, 105)
        if panel.key == "epsilon":
            ax.set_ylim(-0.05, 1.05)
    right = x_eval if show_evaluation else last
    axes[0].set_xlim(-max(0.5, 0.03 * right), right + max(0.5, 0.03 * right))
    ticks, labels = _episode_ticks(last, x_eval if show_evaluation else None, bool(trials))
    for ax in axes[-2:] if len(axes) == 4 else axes[-1:]:
        ax.set_xticks(ticks, labels)
        if trials:
            ax.set_xlabel(trial_name)
    handles = _learning_handles(
        trial_name if trials else None,
        window,
        len(trials) <= POINTS_UP_TO,
        show_evaluation,
        _evaluation_worlds(result),
    )
    fig.legend(handles=handles, loc="outside lower center", ncols=3, frameon=False)
    fig.suptitle(_learning_title(result, len(trials), planned, trial_name))
    return fig


def _draw_trials(
    ax: Axes, index: NDArray[np.float64], values: NDArray[np.float64], window: int, points: bool
) -> None:
    """Every trial's value, faint behind its moving mean when there is one."""
    style: dict[str, Any] = {"color": _ROBOT_BLUE, "linewidth": 0.8}
    if points:
        style.update(marker="o", markersize=2.5)
    if window > 1:
        ax.plot(index, values, alpha=0.3, **style)
        ax.plot(index, moving_mean(values, window), color=_ROBOT_BLUE, linewidth=2.0)
    else:
        ax.plot(index, values, **style)


def _draw_evaluation(ax: Axes, result: SimulationResult, panel: _Panel, x: float) -> None:
    """The evaluation's mean over its worlds, with the 95% interval as a bar."""
    assert panel.summary_key is not None
    point = _evaluation_point(result, panel.summary_key, panel.factor)
    if point is None:
        return
    value, interval = point
    yerr = None
    if interval is not None:
        yerr = [[max(value - interval[0], 0.0)], [max(interval[1] - value, 0.0)]]
    ax.errorbar(
        [x], [value], yerr=yerr, fmt="D", color=_EVALUATION_ORANGE, markeredgecolor="black",
        markersize=7, ecolor="black", elinewidth=1.2, capsize=4, zorder=3,
    )  # fmt: skip


def _episode_ticks(
    last: float, x_eval: float | None, trials: bool
) -> tuple[list[float], list[str]]:
    """Whole episode numbers up to ``last``, clear of the evaluation's own labelled tick."""
    ticks = [
        float(t)
        for t in MaxNLocator(nbins=6, integer=True).tick_values(0, max(last, 1.0))
        if trials and 0 <= t <= last and (x_eval is None or x_eval - t >= 0.08 * (x_eval + 1))
    ]
    labels = [f"{t:.0f}" for t in ticks]
    if x_eval is not None:
        ticks.append(x_eval)
        labels.append("greedy\nevaluation" if trials else "greedy evaluation")
    return ticks, labels


def _learning_handles(
    trial_name: str | None, window: int, points: bool, evaluation: bool, worlds: int | None
) -> list[Artist]:
    handles: list[Artist] = []
    if trial_name is not None:
        handles.append(
            Line2D([], [], color=_ROBOT_BLUE, linewidth=0.8, alpha=0.3 if window > 1 else 1.0,
                   marker="o" if points else None, markersize=2.5, label=f"each {trial_name}")
        )  # fmt: skip
    if trial_name is not None and window > 1:
        handles.append(
            Line2D([], [], color=_ROBOT_BLUE, linewidth=2.0, label=f"moving mean of {window}")
        )
    if evaluation:
        over = f", {worlds} worlds" if worlds else ""
        handles.append(
            Line2D([], [], color=_EVALUATION_ORANGE, marker="D", markeredgecolor="black",
                   linestyle="", label=f"greedy evaluation{over} (mean, 95% CI)")
        )  # fmt: skip
    return handles


def _learning_title(result: SimulationResult, trials: int, planned: int, trial_name: str) -> str:
    policy = result.scenario.robots.policy
    name = _POLICY_NAMES[policy]
    done = f"{trials}" if result.completed else f"{trials} of {planned}"
    stopped = "" if result.completed else " (stopped early)"
    if policy in BASELINES:
        name = name[0].upper() + name[1:]
        if trial_name != "episode":
            return f"{name} does not learn: its {trials} evaluation worlds as trials"
        return f"{name} does not learn: {done} training episodes, all trials alike{stopped}"
    actions = result.scenario.learning.actions
    if trials == 0:
        source = result.scenario.policy_from
        table = f"the table of job {source}" if source is not None else "an untrained table"
        return f"Q-learning ({actions}): {table}, evaluated without training"
    return f"Learning curve: Q-learning ({actions}), {done} training episodes{stopped}"


def learning_png(result: SimulationResult) -> bytes:
    """The learning curve (``learning_figure``) as PNG bytes."""
    return png(learning_figure(result))


# ---------------------------------------------------------------- Q-table

# Inches per table row and per column (narrow columns when there are many actions), and per
# character of a state label at QTABLE_FONT points: the figure grows with the table, so that
# 72 states x 4 actions and 54 states x 26 actions both stay legible.
QTABLE_ROW_IN = 0.17
QTABLE_WIDE_COLUMN_IN = 0.95
QTABLE_NARROW_COLUMN_IN = 0.3
QTABLE_WIDE_UP_TO = 8
QTABLE_CHAR_IN = 0.052
QTABLE_FONT = 6.5
_QTABLE_CMAP = "RdBu_r"
_UNVISITED_GREY = "0.82"


def qtable_figsize(states: list[str], actions: list[str]) -> tuple[float, float]:
    """(width, height) in inches of the Q-table picture: a row per state, a column per action,
    room for the longest labels, the colour bar above and the legend below."""
    wide = len(actions) <= QTABLE_WIDE_UP_TO
    column = QTABLE_WIDE_COLUMN_IN if wide else QTABLE_NARROW_COLUMN_IN
    state_labels = QTABLE_CHAR_IN * max((len(s) for s in states), default=1)
    action_labels = 0.35 if wide else QTABLE_CHAR_IN * max((len(a) for a in actions), default=1)
    width = state_labels + column * len(actions) + 1.3
    height = QTABLE_ROW_IN * len(states) + action_labels + 2.4
    return round(max(width, 6.0), 1), round(height, 1)


def qtable_figure(
    states: list[str],
    actions: list[str],
    values: NDArray[np.float64],
    visits: NDArray[np.int64],
) -> Figure:
    """The Q-values as a heatmap, a row per state and a column per action, on a diverging
    colour scale centred on 0. A dot marks each state's greedy action and squares the actions
    tied for best (a greedy robot picks among them at random); states never visited, with
    nothing learned, are grey; the right axis gives each state's visits. Per-robot tables are
    shown as their visit-weighted mean (``nanonav.policy.swarm_table``)."""
    table, counts = swarm_table(values, visits)
    greedy = greedy_table(states, actions, values, visits)
    learned = np.array([g.learned for g in greedy], dtype=bool)
    fig = new_figure(*qtable_figsize(states, actions))
    ax = fig.add_subplot()
    shown = np.ma.masked_array(table, mask=np.repeat(~learned[:, None], len(actions), axis=1))
    reach = float(np.abs(table[learned]).max()) if learned.any() else 0.0
    cmap = matplotlib.colormaps[_QTABLE_CMAP].with_extremes(bad=_UNVISITED_GREY)
    image = ax.imshow(
        shown,
        cmap=cmap,
        norm=CenteredNorm(vcenter=0.0, halfrange=reach if reach > 0 else 1.0),
        aspect="auto",
        interpolation="nearest",
    )
    rows = np.arange(len(states))
    ax.set_yticks(rows, states, fontsize=QTABLE_FONT)
    wide = len(actions) <= QTABLE_WIDE_UP_TO
    ax.set_xticks(
        np.arange(len(actions)),
        actions,
        fontsize=QTABLE_FONT + 1 if wide else QTABLE_FONT,
        rotation=0 if wide else 90,
    )
    ax.tick_params(length=0)
    for label, state in zip(ax.get_yticklabels(), greedy, strict=True):
        if not state.learned:
            label.set_color("0.5")
    ax.set_xticks(np.arange(len(actions) + 1) - 0.5, minor=True)
    ax.set_yticks(np.arange(len(states) + 1) - 0.5, minor=True)
    ax.grid(which="minor", color="white", linewidth=0.6)
    ax.tick_params(which="minor", length=0)
    column = {a: i for i, a in enumerate(actions)}
    best = np.array([(column[g.action], i) for i, g in enumerate(greedy) if g.learned], float)
    tied = np.array([(column[a], i) for i, g in enumerate(greedy) for a in g.ties], float)
    if len(best):
        ax.scatter(
            best[:, 0], best[:, 1], s=16, color="black", edgecolors="white", linewidths=0.6,
            label="greedy action", zorder=3,
        )  # fmt: skip
    if len(tied):
        ax.scatter(
            tied[:, 0], tied[:, 1], s=60, marker="s", facecolors="none", edgecolors="black",
            linewidths=0.9, label="tied for best", zorder=3,
        )  # fmt: skip
    ax.set_xlim(-0.5, len(actions) - 0.5)
    ax.set_ylim(len(states) - 0.5, -0.5)
    ax.set_xlabel("action")
    ax.set_ylabel("state")
    right = ax.twinx()
    right.set_ylim(ax.get_ylim())
    right.set_yticks(rows, [str(int(n)) for n in counts.sum(axis=1)], fontsize=QTABLE_FONT)
    right.tick_params(length=0)
    right.set_ylabel("visits")
    # the pad is a fraction of the table's height: about a fifth of an inch
    pad = 0.2 / (QTABLE_ROW_IN * max(len(states), 1))
    colourbar = fig.colorbar(image, ax=[ax, right], location="top", shrink=0.7, aspect=30, pad=pad)
    colourbar.set_label("Q-value (reward units): positive red, negative blue, 0 white")
    handles: list[Artist] = [
        Line2D([], [], marker="o", linestyle="", color="black", markeredgecolor="white",
               label="greedy action"),
        Line2D([], [], marker="s", linestyle="", markerfacecolor="none",
               markeredgecolor="black", label="tied for best (picked at random)"),
        Patch(facecolor=_UNVISITED_GREY, edgecolor="0.5", label="state never visited"),
    ]  # fmt: skip
    fig.legend(
        handles=handles, loc="outside lower center", ncols=3, frameon=False, fontsize="small"
    )
    robots = (
        f", mean of {values.shape[0]} robots' tables weighted by visits" if values.ndim == 3 else ""
    )
    fig.suptitle(
        f"Learned Q-table: {len(states)} states x {len(actions)} actions{robots}\n"
        f"{int(learned.sum())} of {len(states)} states learned"
    )
    return fig


def qtable_png(
    states: list[str],
    actions: list[str],
    values: NDArray[np.float64],
    visits: NDArray[np.int64],
) -> bytes:
    """The Q-table picture (``qtable_figure``) as PNG bytes, ``qtable_figsize`` x DPI pixels."""
    return png(qtable_figure(states, actions, values, visits))


# ---------------------------------------------------------------- all of them


def render(
    result: SimulationResult,
    name: str,
    *,
    scale: ColourScale = "auto",
    at: float | None = None,
    resolution: int = HEATMAP_RESOLUTION,
) -> bytes:
    """The one picture ``name`` (one of ``PICTURE_NAMES``), drawn on its own; ``at`` and
    ``resolution`` choose a heatmap's slice and grid (``heatmap_png``)."""
    planes: dict[str, Plane] = {"heatmap_xy": "xy", "heatmap_xz": "xz", "heatmap_yz": "yz",
                                "heatmap_all": "all"}  # fmt: skip
    if name in planes:
        return heatmap_png(result, planes[name], at=at, resolution=resolution, scale=scale)
    drawers = {"trajectory": trajectory_png, "concentration": concentration_png,
               "learning": learning_png}  # fmt: skip
    if name not in drawers:
        raise ValueError(f"there is no picture {name!r}; there are {', '.join(PICTURE_NAMES)}")
    if at is not None or resolution != HEATMAP_RESOLUTION:
        raise ValueError(f"only heatmaps take at and resolution, not {name!r}")
    return drawers[name](result)


def render_all(result: SimulationResult, *, scale: ColourScale = "auto") -> dict[str, bytes]:
    """Every picture, keyed by ``PICTURE_NAMES``; the field is evaluated once for the four
    heatmaps."""
    planes = ("xy", "xz", "yz")
    slices = heatmap_slices(result, planes)
    resolved = _resolve_scale(result, scale)
    pictures = {
        f"heatmap_{p}": png(heatmap_figure(result, {p: slices[p]}, resolved)) for p in planes
    }
    pictures["heatmap_all"] = png(heatmap_figure(result, slices, resolved))
    pictures["trajectory"] = trajectory_png(result)
    pictures["concentration"] = concentration_png(result)
    pictures["learning"] = learning_png(result)
    return {name: pictures[name] for name in PICTURE_NAMES}
