"""The heatmap, the paper's Figure 5: the true biomarker concentration in a plane over the whole
cube at the end of the evaluation episode, with the robots' paths projected on it, the cells and
the obstacles the slice cuts."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from matplotlib import patheffects
from matplotlib.artist import Artist
from matplotlib.axes import Axes
from matplotlib.colors import LogNorm, Normalize
from matplotlib.figure import Figure
from matplotlib.image import AxesImage
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch
from numpy.typing import NDArray

from nanonav.engine import SimulationResult, Trajectory, field_and_gradient
from nanonav.engine.fields import biomarker_of
from nanonav.pictures.figure import png
from nanonav.pictures.job.catalogue import (
    HEATMAP_RESOLUTION,
    MAX_HEATMAP_RESOLUTION,
    MIN_HEATMAP_RESOLUTION,
)
from nanonav.pictures.job.common import (
    CELL_RED,
    ROBOT_BLUE,
    START_GREEN,
    ColourScale,
    concentration_unit,
    evaluation_trajectory,
    last_row,
    length_unit,
    recorded_world,
    resolve_scale,
    sized_figure,
    thin,
)

Plane = Literal["xy", "xz", "yz", "all"]

# A log colour scale shows this many decades below its top, at most.
LOG_DECADES = 5.0
# The colour scale runs between these quantiles of the drawn slices' values (a linear one from
# 0): the concentration at a cell is decades above the field the robots climb elsewhere, and a
# scale topped by it drew the whole cube in the darkest colour. What lies beyond is drawn in
# the end colours, and the colour bar's arrows say so.
SCALE_QUANTILES = (0.005, 0.995)
# Fewer paths than in 3-D, so that they do not hide the field.
MAX_HEATMAP_PATHS = 10

_PLANE_AXES: dict[str, tuple[int, int, int]] = {"xy": (0, 1, 2), "xz": (0, 2, 1), "yz": (1, 2, 0)}
_AXIS_NAMES = "xyz"
_HEATMAP_CMAP = "viridis"
_FIELD_NAMES = {
    "gaussian": "Gaussian",
    "inverse_square": "inverse-square",
    "diffusion": "diffusion",
    "sampled_gaussian": "sampled Gaussian",
}


def _target_cell(trajectory: Trajectory) -> int:
    """The cell nearest to robot 0 at the last step: the one the heatmap slices through."""
    cells = trajectory.cells[-1]
    robot = trajectory.robots[-1, 0]
    return int(np.argmin(np.linalg.norm(cells - robot, axis=1)))


@dataclass(frozen=True)
class Slice:
    """The true concentration in one plane: ``grid[row, column]`` at the centre of the pixel
    ``(u, v) = (axis[column], axis[row])``, where the plane cuts its normal axis at ``level``."""

    plane: str
    level: float
    axis: NDArray[np.float64]
    grid: NDArray[np.float64]


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
    trajectory = evaluation_trajectory(result)
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
    concentration, _ = field_and_gradient(
        biomarker_of(result.scenario), cells, trajectory.emitter_offsets, np.concatenate(blocks)
    )
    grids = concentration.reshape(len(planes), resolution, resolution)
    return {plane: Slice(plane, levels[i], axis, grids[i]) for i, plane in enumerate(planes)}


def _norm(slices: list[Slice], scale: Literal["linear", "log"]) -> Normalize:
    """One colour scale for the slices, chosen from their values (``SCALE_QUANTILES``): a
    linear one from 0, a log one over the positive values and at most ``LOG_DECADES``."""
    values = np.concatenate([s.grid.ravel() for s in slices])
    values = values[np.isfinite(values)]
    if scale == "linear":
        top = float(np.quantile(values, SCALE_QUANTILES[1])) if values.size else 0.0
        return Normalize(vmin=0.0, vmax=top if top > 0 else 1.0)
    positive = values[values > 0]
    if not positive.size:
        return LogNorm(vmin=0.1, vmax=1.0)
    low, top = (float(q) for q in np.quantile(positive, SCALE_QUANTILES))
    low = max(low, top * 10.0**-LOG_DECADES)
    return LogNorm(vmin=low if low < top else top / 10.0, vmax=top)


def _extend(slices: list[Slice], norm: Normalize) -> Literal["neither", "both", "min", "max"]:
    """Which ends of the colour bar get an arrow: where some value lies beyond the scale."""
    values = np.concatenate([s.grid.ravel() for s in slices])
    above = bool((values > (norm.vmax or 0.0)).any())
    below = isinstance(norm, LogNorm) and bool((values < (norm.vmin or 0.0)).any())
    return "both" if above and below else "max" if above else "min" if below else "neither"


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
        path = thin(trajectory.robots[: last_row(trajectory, i) + 1, i])
        ax.plot(path[:, a], path[:, b], color=ROBOT_BLUE, linewidth=1.2,
                path_effects=_HALO, zorder=2)  # fmt: skip
        ends[i] = path[-1, [a, b]]
    starts = trajectory.robots[0, :shown]
    ax.scatter(starts[:, a], starts[:, b], s=18, color=START_GREEN, edgecolors="white",
               linewidths=0.7, zorder=4)  # fmt: skip
    reached = trajectory.reached[:shown]
    if reached.any():
        for colour, line in (("white", 3.0), (ROBOT_BLUE, 1.5)):
            ax.scatter(ends[reached, 0], ends[reached, 1], s=34, facecolors="none",
                       edgecolors=colour, linewidths=line, zorder=7)  # fmt: skip
    if not reached.all():
        ax.scatter(ends[~reached, 0], ends[~reached, 1], s=50, marker="X", color=ROBOT_BLUE,
                   edgecolors="white", linewidths=0.7, zorder=7)  # fmt: skip
    return bool(reached.any()), bool((~reached).any())


def _draw_slice(ax: Axes, result: SimulationResult, cut: Slice, norm: Normalize) -> _Drawn:
    trajectory = evaluation_trajectory(result)
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
                   edgecolors=CELL_RED, linewidths=2, zorder=6)  # fmt: skip
    if near.any():
        ax.scatter(cells[near, a], cells[near, b], s=80, color=CELL_RED, edgecolors="white",
                   linewidths=1.2, zorder=6)  # fmt: skip
    ax.set_xlim(-half, half)
    ax.set_ylim(-half, half)
    ax.set_aspect("equal")
    length = length_unit(result.scenario)
    ax.set_xlabel(f"{_AXIS_NAMES[a]} ({length})")
    ax.set_ylabel(f"{_AXIS_NAMES[b]} ({length})")
    ax.set_title(f"{cut.plane.upper()} plane at {_AXIS_NAMES[fixed]} = {cut.level:.1f}")
    return _Drawn(image, obstacles_cut, bool(near.any()), bool((~near).any()), reached, failed)


def _heatmap_legend_handles(drawn: list[_Drawn], robots: int) -> list[Artist]:
    paths = "robot path (projected)"
    if robots > MAX_HEATMAP_PATHS:
        paths = f"paths of the first {MAX_HEATMAP_PATHS} of {robots} robots (projected)"
    handles: list[Artist] = [
        Line2D([], [], color=ROBOT_BLUE, linewidth=1.2, path_effects=_HALO, label=paths),
        Line2D([], [], marker="o", linestyle="", color=START_GREEN, markeredgecolor="white",
               label="robot start"),
    ]  # fmt: skip
    if any(d.reached for d in drawn):
        handles.append(Line2D([], [], marker="o", linestyle="", markerfacecolor="none",
                              markeredgecolor=ROBOT_BLUE, markeredgewidth=1.5,
                              label="robot end, reached"))  # fmt: skip
    if any(d.failed for d in drawn):
        handles.append(Line2D([], [], marker="X", linestyle="", color=ROBOT_BLUE,
                              markeredgecolor="white", markersize=8,
                              label="robot end, not reached"))  # fmt: skip
    if any(d.cells_in for d in drawn):
        handles.append(Line2D([], [], marker="o", linestyle="", color=CELL_RED,
                              markeredgecolor="white", markersize=9,
                              label="cell in the slice"))  # fmt: skip
    if any(d.cells_off for d in drawn):
        handles.append(Line2D([], [], marker="o", linestyle="", markerfacecolor="none",
                              markeredgecolor=CELL_RED, markeredgewidth=2, markersize=8,
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
    trajectory = evaluation_trajectory(result)
    planes = tuple(slices)
    single = len(planes) == 1
    fig = sized_figure("heatmap_xy" if single else "heatmap_all")
    axes = fig.subplots(1, len(planes), squeeze=False)[0]
    norm = _norm(list(slices.values()), scale)
    drawn = [_draw_slice(ax, result, slices[p], norm) for ax, p in zip(axes, planes, strict=True)]
    colourbar = fig.colorbar(drawn[0].image, ax=list(axes), shrink=0.9,
                             extend=_extend(list(slices.values()), norm))  # fmt: skip
    unit = concentration_unit(result.scenario)
    colourbar.set_label(
        f"biomarker concentration ({unit}{', log scale' if scale == 'log' else ''})"
    )
    model = _FIELD_NAMES[biomarker_of(result.scenario).model]
    where = "through the cell nearest to robot 0" if through_target else "at the chosen level"
    fig.suptitle(
        f"Biomarker concentration, {model} field, at the last step ({trajectory.length})\n"
        f"of {recorded_world(result)}; slice{'' if single else 's'} {where}"
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
    figure = heatmap_figure(result, slices, resolve_scale(result, scale), through_target=at is None)
    return png(figure)
