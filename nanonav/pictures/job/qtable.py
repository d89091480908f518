"""The learned Q-table: the action values as a heatmap, a row per state and a column per
action, with each state's greedy action, its action gap and its visits."""

from __future__ import annotations

import matplotlib
import numpy as np
from matplotlib.artist import Artist
from matplotlib.colors import CenteredNorm
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from numpy.typing import NDArray

from nanonav.engine import SimulationResult
from nanonav.pictures.figure import new_figure, png
from nanonav.policy import MAX_Q, greedy_table, swarm_table

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
# The greedy action's dot, in points^2: its area grows with the state's action gap from the
# smallest (a gap of 0) to the largest (the table's largest gap).
GAP_DOT_MIN = 6.0
GAP_DOT_MAX = 90.0


def gap_dot_sizes(gaps: NDArray[np.float64]) -> NDArray[np.float64]:
    """The greedy dots' areas: in proportion to each state's action gap over the table's
    largest, between ``GAP_DOT_MIN`` and ``GAP_DOT_MAX``, so that a choice the learner barely
    prefers shows as a speck and a clear one as a disc."""
    largest = float(gaps.max()) if len(gaps) else 0.0
    share = gaps / largest if largest > 0.0 else np.zeros_like(gaps)
    sizes: NDArray[np.float64] = GAP_DOT_MIN + (GAP_DOT_MAX - GAP_DOT_MIN) * share
    return sizes


def qtable_figsize(states: list[str], actions: list[str]) -> tuple[float, float]:
    """(width, height) in inches of the Q-table picture: a row per state, a column per action,
    room for the longest labels, the colour bar above and the legend below."""
    wide = len(actions) <= QTABLE_WIDE_UP_TO
    column = QTABLE_WIDE_COLUMN_IN if wide else QTABLE_NARROW_COLUMN_IN
    state_labels = QTABLE_CHAR_IN * max((len(s) for s in states), default=1)
    action_labels = 0.35 if wide else QTABLE_CHAR_IN * max((len(a) for a in actions), default=1)
    width = state_labels + column * len(actions) + 1.8  # the right axis: visits and gap
    height = QTABLE_ROW_IN * len(states) + action_labels + 2.4
    return round(max(width, 6.0), 1), round(height, 1)


# long: one figure's panels, legend and labels, drawn in the order a reader reads them
def qtable_figure(
    states: list[str],
    actions: list[str],
    values: NDArray[np.float64],
    visits: NDArray[np.int64],
) -> Figure:
    """The Q-values as a heatmap, a row per state and a column per action, on a diverging
    colour scale centred on 0. A dot marks each state's greedy action, its area the action gap
    (the best Q minus the next best: how much the choice matters to the learner), and squares
    the actions tied for best (a greedy robot picks among them at random); states never
    visited, with nothing learned, are grey; the right axis gives each state's visits and gap.
    Per-robot tables are shown as their visit-weighted mean (``nanonav.policy.swarm_table``)."""
    table, counts = swarm_table(values, visits)
    greedy = greedy_table(states, actions, values, visits)
    learned = np.array([g.learned for g in greedy], dtype=bool)
    fig = new_figure(*qtable_figsize(states, actions))
    ax = fig.add_subplot()
    reach = float(np.abs(table[learned]).max()) if learned.any() else 0.0
    # a table kept before a policy's values were bounded may hold more than MAX_Q, near the
    # largest float: the colour scale and its ticks stop at MAX_Q, and such values are drawn as
    # at it
    reach = min(reach, MAX_Q)
    shown = np.ma.masked_array(
        np.clip(table, -reach, reach), mask=np.repeat(~learned[:, None], len(actions), axis=1)
    )
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
    gaps = np.array([g.gap or 0.0 for g in greedy if g.learned], float)
    tied = np.array([(column[a], i) for i, g in enumerate(greedy) for a in g.ties], float)
    if len(best):
        ax.scatter(
            best[:, 0], best[:, 1], s=gap_dot_sizes(gaps), color="black", edgecolors="white",
            linewidths=0.6, label="greedy action", zorder=3,
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
    right.set_yticks(
        rows,
        [
            f"{int(n)}" + (f"  gap {g.gap:.2g}" if g.learned and g.gap is not None else "")
            for n, g in zip(counts.sum(axis=1), greedy, strict=True)
        ],
        fontsize=QTABLE_FONT,
    )
    right.tick_params(length=0)
    right.set_ylabel("visits, action gap")
    # the pad is a fraction of the table's height: about a fifth of an inch
    pad = 0.2 / (QTABLE_ROW_IN * max(len(states), 1))
    colourbar = fig.colorbar(image, ax=[ax, right], location="top", shrink=0.7, aspect=30, pad=pad)
    colourbar.set_label("Q-value (reward units): positive red, negative blue, 0 white")
    handles: list[Artist] = [
        Line2D([], [], marker="o", linestyle="", color="black", markeredgecolor="white",
               label="greedy action (area: its gap over the next best)"),
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


def learned_qtable_png(result: SimulationResult) -> bytes:
    """The Q-table ``result`` learned (``qtable_png``); ``ValueError`` for a policy that learns
    none."""
    if result.qtable is None:
        policy = result.scenario.robots.policy
        raise ValueError(f"the {policy!r} policy learns no Q-table; only q_learning does")
    table = result.qtable
    return qtable_png(table.states, table.actions, table.values, table.visits)
