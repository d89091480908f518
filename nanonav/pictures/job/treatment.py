"""The swarm's treatment over the steps: how many cells were treated, and how many payloads each
cell had received, in the evaluation episode. Only a run whose robots deliver payloads (cells
that can be treated, or robots that signal once bound) has it: robots that only take up space
carry nothing to deliver."""

from __future__ import annotations

import numpy as np
from matplotlib.artist import Artist
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator
from numpy.typing import NDArray

from nanonav.engine import SimulationResult, Trajectory
from nanonav.engine.simulation import swarm_metrics
from nanonav.pictures.figure import png
from nanonav.pictures.job.catalogue import treatment_drawn
from nanonav.pictures.job.common import (
    CELL_RED,
    counted,
    evaluation_trajectory,
    recorded_world,
    sized_figure,
    step_label,
)
from nanonav.scenario import Scenario

# Up to this many cells, each cell's payloads are a line of its own with a legend entry; more
# are stacked, a band per cell, whose top is every payload delivered.
MAX_CELL_LINES = 8
_TOTAL_GREY = "0.35"
_CAPACITY_GREY = "0.45"
# matplotlib's tab10 without its red (the cells' colour elsewhere), then tab20's lighter half
_CELL_COLOURS = (
    "#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22",
    "#17becf", "#aec7e8", "#ffbb78", "#98df8a", "#c5b0d5", "#c49c94", "#f7b6d2", "#dbdb8d",
)  # fmt: skip


def delivers_payloads(scenario: Scenario) -> bool:
    """Whether the robots of ``scenario`` carry payloads to the cells: when the cells take them
    (``cells.capacity``) or a robot bound to a cell signals (``communication.model``). Robots
    that only take up space (``robots.exclusion``) report the swarm's numbers but deliver
    nothing."""
    return treatment_drawn(scenario.model_dump(mode="json", include={"cells", "communication"}))


def has_treatment(result: SimulationResult) -> bool:
    """Whether ``result``'s robots deliver payloads (``delivers_payloads``) and its episode
    recorded the cell loads (every episode records them, the paper's too, but only a swarm's
    that delivers are drawn)."""
    trajectory = result.trajectory
    return (
        trajectory is not None
        and trajectory.cell_loads is not None
        and swarm_metrics(result.scenario)
        and delivers_payloads(result.scenario)
    )


def _loads(result: SimulationResult) -> tuple[Trajectory, NDArray[np.int64]]:
    trajectory = evaluation_trajectory(result)
    if trajectory.cell_loads is None or not has_treatment(result):
        raise ValueError(
            "this result has no treatment to draw: only a run whose cells can be treated "
            "(cells.capacity) or whose robots signal (communication.model) delivers payloads"
        )
    return trajectory, trajectory.cell_loads


def treated_counts(loads: NDArray[np.int64], capacity: int | None) -> NDArray[np.int64]:
    """Per history row, the cells treated by then (load at capacity); with no capacity, the
    cells that had received a payload."""
    threshold = 1 if capacity is None else capacity
    counts: NDArray[np.int64] = (loads >= threshold).sum(axis=1)
    return counts


def treatment_figure(result: SimulationResult) -> Figure:
    """Two panels over the steps of the evaluation episode: the cells treated by each step
    (with no capacity, no cell is ever treated: the cells that had received a payload), with a
    line at every cell; and the payloads each cell had received, a line per cell up to
    ``MAX_CELL_LINES`` cells (with the capacity as a line), a band per cell stacked beyond
    (with the payloads that would treat every cell as a line)."""
    trajectory, loads = _loads(result)
    capacity = result.scenario.cells.capacity
    steps = trajectory.step
    cells = loads.shape[1]
    fig = sized_figure("treatment")
    treated_ax, loads_ax = fig.subplots(2, 1, sharex=True, height_ratios=(2, 3))
    counts = treated_counts(loads, capacity)
    treated_ax.fill_between(steps, counts, step="post", color=CELL_RED, alpha=0.15, linewidth=0)
    treated_ax.step(steps, counts, where="post", color=CELL_RED, linewidth=1.8)
    treated_ax.axhline(cells, color=_CAPACITY_GREY, linestyle="--", linewidth=1.0)
    treated_ax.set_ylim(0, cells * 1.08 + 0.2)
    treated_ax.yaxis.set_major_locator(MaxNLocator(nbins=6, integer=True))
    what = "cells treated" if capacity is not None else "cells with a payload"
    treated_ax.set_ylabel(what)
    treated_ax.set_title(
        f"{what} (of {cells})" if capacity is not None
        else f"cells that received a payload (of {cells}; no capacity: none is ever treated)",
        fontsize="medium",
    )  # fmt: skip
    done = _all_treated_at(steps, counts, cells) if capacity is not None else None
    if done is not None:
        for ax in (treated_ax, loads_ax):
            ax.axvline(done, color=_TOTAL_GREY, linestyle=":", linewidth=1.0)
    handles: list[Artist] = [
        Line2D([], [], color=CELL_RED, linewidth=1.8, label=what),
        Line2D([], [], color=_CAPACITY_GREY, linestyle="--", linewidth=1.0,
               label="the cell" if cells == 1 else f"all {cells} cells"),
    ]  # fmt: skip
    if cells <= MAX_CELL_LINES:
        handles += _draw_cell_lines(loads_ax, steps, loads, capacity)
    else:
        handles += _draw_cell_stack(loads_ax, steps, loads, capacity)
    if done is not None:
        handles.append(
            Line2D([], [], color=_TOTAL_GREY, linestyle=":", linewidth=1.0,
                   label=f"every cell treated (step {done})")
        )  # fmt: skip
    loads_ax.set_ylabel("payloads")
    loads_ax.set_xlabel(step_label(result.scenario))
    end = max(int(steps[-1]), 1)
    loads_ax.set_xlim(0, end * 1.015)  # the last step's changes stand clear of the frame
    loads_ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    for ax in (treated_ax, loads_ax):
        ax.grid(alpha=0.3)
    fig.legend(
        handles=handles, loc="outside lower center", ncols=min(len(handles), 4), frameon=False,
        fontsize="small",
    )  # fmt: skip
    fig.suptitle(_treatment_title(result, trajectory, loads, counts, done))
    return fig


def _all_treated_at(steps: NDArray[np.int64], counts: NDArray[np.int64], cells: int) -> int | None:
    """The step of the first row at which every cell was treated, None if one never was."""
    rows = np.flatnonzero(counts >= cells)
    return int(steps[rows[0]]) if len(rows) else None


def _draw_cell_lines(
    ax: Axes, steps: NDArray[np.int64], loads: NDArray[np.int64], capacity: int | None
) -> list[Artist]:
    """A step line per cell at its exact load, each drawn thinner than the one before, over it,
    so that cells with the same load stay visible as nested lines (a line nudged up apart read
    3.13 payloads, over the capacity line at 3). A payload count is never negative, nor is its
    axis: the line at 0 is drawn over the frame."""
    cells = loads.shape[1]
    top = int(loads.max(initial=0))
    widths = np.linspace(4.0, 1.4, cells) if cells > 1 else np.array([1.6])
    handles: list[Artist] = []
    for j in range(cells):
        colour = _CELL_COLOURS[j % len(_CELL_COLOURS)]
        ax.step(steps, loads[:, j], where="post", color=colour, linewidth=widths[j],
                clip_on=False)  # fmt: skip
        handles.append(Line2D([], [], color=colour, linewidth=widths[j], label=f"cell {j}"))
    if capacity is not None:
        ax.axhline(capacity, color=_CAPACITY_GREY, linestyle="-.", linewidth=1.0)
        handles.append(Line2D([], [], color=_CAPACITY_GREY, linestyle="-.", linewidth=1.0,
                              label=f"capacity: {_payloads(capacity)} treat"
                                    f"{'s' if capacity == 1 else ''} a cell"))  # fmt: skip
        top = max(top, capacity)
    ax.set_ylim(0, top * 1.1 + 0.5)
    ax.set_title("payloads each cell had received", fontsize="medium")
    return handles


def _draw_cell_stack(
    ax: Axes, steps: NDArray[np.int64], loads: NDArray[np.int64], capacity: int | None
) -> list[Artist]:
    """A band per cell, stacked: each band's height is that cell's payloads, the top every
    payload delivered."""
    cells = loads.shape[1]
    colours = [_CELL_COLOURS[j % len(_CELL_COLOURS)] for j in range(cells)]
    ax.stackplot(steps, loads.T, colors=colours, step="post", linewidth=0, alpha=0.85)
    total = loads.sum(axis=1)
    ax.step(steps, total, where="post", color=_TOTAL_GREY, linewidth=1.2)
    top = int(total.max(initial=0))
    handles: list[Artist] = [
        Patch(
            facecolor=colours[0], alpha=0.85, label=f"a band per cell ({counted(cells, 'cell')})"
        ),
        Line2D([], [], color=_TOTAL_GREY, linewidth=1.2, label="payloads delivered in all"),
    ]
    if capacity is not None:
        ax.axhline(capacity * cells, color=_CAPACITY_GREY, linestyle="-.", linewidth=1.0)
        every = f"payloads that treat every cell ({capacity} x {cells})"
        handles.append(
            Line2D([], [], color=_CAPACITY_GREY, linestyle="-.", linewidth=1.0, label=every)
        )
        top = max(top, capacity * cells)
    ax.set_ylim(0, top * 1.08 + 0.5)
    ax.set_title("payloads each cell had received, stacked", fontsize="medium")
    return handles


def _treatment_title(
    result: SimulationResult,
    trajectory: Trajectory,
    loads: NDArray[np.int64],
    counts: NDArray[np.int64],
    done: int | None,
) -> str:
    cells = loads.shape[1]
    capacity = result.scenario.cells.capacity
    delivered = int(loads[-1].sum())
    robots = trajectory.robots.shape[1]
    if capacity is None:
        return (
            f"Payloads delivered to {_the_cells(cells)}, {recorded_world(result)}\n"
            f"{_payloads(delivered)} from {counted(robots, 'robot')} reached "
            f"{counted(int(counts[-1]), 'cell')} in {counted(trajectory.length, 'step')}"
        )
    treated = (
        f"every cell treated at step {done}"
        if done is not None
        else f"{int(counts[-1])} of {cells} treated in {counted(trajectory.length, 'step')}"
    )
    return (
        f"Treatment of {_the_cells(cells)} ({_payloads(capacity)} treat"
        f"{'s' if capacity == 1 else ''} a cell), "
        f"{recorded_world(result)}\n"
        f"{treated}; {_payloads(delivered)} from {counted(robots, 'robot')}"
    )


def _payloads(count: int) -> str:
    return counted(count, "payload")


def _the_cells(cells: int) -> str:
    return "the cancer cell" if cells == 1 else f"the {cells} cancer cells"


def treatment_png(result: SimulationResult) -> bytes:
    """The treatment picture (``treatment_figure``) as PNG bytes; ``ValueError`` for a result
    without the swarm's numbers."""
    return png(treatment_figure(result))
