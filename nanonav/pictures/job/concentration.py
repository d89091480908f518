"""Concentration and distance over the steps, the paper's Figure 4: the biomarker concentration
at the robots and their distance to the nearest cell in the evaluation episode."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator
from numpy.typing import NDArray

from nanonav.engine import SimulationResult, Trajectory
from nanonav.pictures.figure import png
from nanonav.pictures.job.common import (
    CELL_RED,
    ROBOT_BLUE,
    concentration_unit,
    evaluation_trajectory,
    last_row,
    length_unit,
    reach_summary,
    recorded_world,
    resolve_scale,
    sized_figure,
    step_label,
)


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


DECADES_FOR_LOG = 2  # positive values felt spanning this many powers of ten: a log axis


def spans_decades(values: NDArray[np.float64]) -> bool:
    """Whether the positive concentrations felt span ``DECADES_FOR_LOG`` powers of ten or more:
    a Gaussian field felt far from its cells (the diffuse tumour) is flat at 0 on a linear axis
    however it changes."""
    felt = values[np.isfinite(values) & (values > 0)]
    return felt.size > 1 and float(felt.max()) >= 10.0**DECADES_FOR_LOG * float(felt.min())


def _concentration_label(log_scale: bool, unit: str) -> str:
    return f"biomarker concentration ({unit}{', log scale' if log_scale else ''})"


def concentration_figure(result: SimulationResult) -> Figure:
    """Figure 4: the biomarker concentration at the robots and their distance to the nearest
    cell over the steps of the evaluation episode, each robot only while it searches (a robot
    that reached a cell stops, while the cell drifts on).

    One robot, as in the paper: concentration (red, left axis) and distance (blue, right axis)
    up to the step it stopped. A swarm: three panels over the robots still searching at each
    step, the median and the interquartile band of their distance, of their concentration, and
    how many still search, so that thousands of robots read as easily as two.
    """
    trajectory = evaluation_trajectory(result)
    log_scale = resolve_scale(result, "auto") == "log" or spans_decades(trajectory.concentration)
    fig = sized_figure("concentration")
    units = (
        length_unit(result.scenario), concentration_unit(result.scenario),
        step_label(result.scenario),
    )  # fmt: skip
    if trajectory.robots.shape[1] == 1:
        _draw_one_robot(fig, trajectory, log_scale, units)
    else:
        _draw_searching_swarm(fig, trajectory, log_scale, units)
    fig.suptitle(
        "Biomarker concentration and distance to the nearest cell, "
        f"{recorded_world(result)}\n{reach_summary(result.scenario, trajectory)}"
    )
    return fig


def _draw_one_robot(
    fig: Figure, trajectory: Trajectory, log_scale: bool, units: tuple[str, str, str]
) -> None:
    left = fig.add_subplot()
    right = left.twinx()
    end = last_row(trajectory, 0) + 1
    steps = trajectory.step[:end]
    left.plot(steps, trajectory.concentration[:end, 0], color=CELL_RED, linewidth=1.8)
    right.plot(steps, trajectory.distance[:end, 0], color=ROBOT_BLUE, linewidth=1.8)
    if log_scale:
        left.set_yscale("log")
    left.set_xlabel(units[2])
    left.set_ylabel(_concentration_label(log_scale, units[1]), color=CELL_RED)
    right.set_ylabel(f"distance to the nearest cell ({units[0]})", color=ROBOT_BLUE)
    left.tick_params(axis="y", colors=CELL_RED)
    right.tick_params(axis="y", colors=ROBOT_BLUE)
    right.set_ylim(bottom=0)
    left.set_xlim(0, max(int(steps[-1]), 1))
    left.grid(alpha=0.3)
    fig.legend(
        handles=[
            Line2D([], [], color=CELL_RED, linewidth=1.8, label="concentration at the robot"),
            Line2D([], [], color=ROBOT_BLUE, linewidth=1.8, label="distance to the nearest cell"),
        ],
        loc="outside lower center",
        ncols=2,
        frameon=False,
    )


def _draw_searching_swarm(
    fig: Figure, trajectory: Trajectory, log_scale: bool, units: tuple[str, str, str]
) -> None:
    stats = searching_stats(trajectory)
    n = trajectory.robots.shape[1]
    distance_ax, concentration_ax, count_ax = fig.subplots(
        3, 1, sharex=True, height_ratios=(3, 3, 1.7)
    )
    for ax, quartiles, colour in (
        (distance_ax, stats.distance, ROBOT_BLUE),
        (concentration_ax, stats.concentration, CELL_RED),
    ):
        ax.fill_between(stats.step, quartiles[:, 0], quartiles[:, 2], color=colour, alpha=0.2,
                        linewidth=0)  # fmt: skip
        ax.plot(stats.step, quartiles[:, 1], color=colour, linewidth=1.8)
        ax.grid(alpha=0.3)
    distance_ax.set_ylabel(f"distance\n({units[0]})")
    distance_ax.set_ylim(bottom=0)
    distance_ax.set_title("distance to the nearest cell", fontsize="medium")
    if log_scale:
        concentration_ax.set_yscale("log")
    concentration_ax.set_ylabel(f"concentration\n({units[1]}{', log' if log_scale else ''})")
    concentration_ax.set_title("biomarker concentration at the robot", fontsize="medium")
    count_ax.fill_between(stats.step, stats.searching, step="post", color=ROBOT_BLUE, alpha=0.2,
                          linewidth=0)  # fmt: skip
    count_ax.step(stats.step, stats.searching, where="post", color=ROBOT_BLUE, linewidth=1.5)
    count_ax.set_ylim(0, n * 1.05)
    count_ax.set_ylabel("robots")
    count_ax.set_title(f"robots still searching (of {n})", fontsize="medium")
    count_ax.yaxis.set_major_locator(MaxNLocator(nbins=3, integer=True))
    count_ax.grid(alpha=0.3)
    count_ax.set_xlabel(units[2])
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
