"""Pictures of a batch study, as PNG bytes: one metric across the swept values of a parameter,
the mean learning curves of several scenarios, and what their learners learned.

The numbers arrive already summarised (means and confidence bounds, see ``nanonav.stats``); this
module only draws them, so it reads no result, job or database (``nanonav.pictures.study`` turns
a study's report into them). As for a job's pictures, each figure is its own
``matplotlib.figure.Figure`` on the Agg canvas, saved to a ``BytesIO``, never pyplot, and each PNG
is exactly ``figsize x DPI`` pixels.

A series keeps its colour in every picture of a study: colours are given by the order in which
labels first appear in a call, so callers pass the scenarios in the same (the study's) order.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Collection, Hashable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from matplotlib.artist import Artist
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.text import Text
from matplotlib.ticker import MaxNLocator, NullLocator
from matplotlib.typing import LineStyleType
from numpy.typing import NDArray

from nanonav.pictures.figure import new_figure, png

METRIC_FIGSIZE = (8.0, 5.0)
# with paired comparisons, the means and beside them the differences (a forest plot)
COMPARED_FIGSIZE = (13.0, 5.0)
# a share's axis: 0 to 1 with a margin, so that a mean or a cap at 0 or 1 is drawn whole and
# inside the frame, not on it
SHARE_LIMITS = (-0.04, 1.04)
# a Holm-adjusted p below this is marked as a difference the study resolves
SIGNIFICANT = 0.05
LEARNING_WIDTH = 8.0
LEARNING_PANEL_HEIGHT = 3.0
NO_DATA = "no finished jobs yet"
# A learning curve longer than this is drawn as this many bin averages: tens of thousands of
# episodes would otherwise make the PNG slow to draw and no easier to read.
MAX_CURVE_POINTS = 2000
# Up to this many distinct swept values, each gets its own tick, labelled with its value.
MAX_TICKED_VALUES = 12
# Swept values that are all positive and span this ratio or more go on a logarithmic axis
# (robot counts 1, 15, 100, 1000 would otherwise crowd at the left).
LOG_AXIS_RATIO = 100.0
# Series at the same x are spread over this fraction of the gap between neighbouring x values,
# so their error bars stand apart.
DODGE = 0.15
# About how many characters of legend text fit across an 8-inch figure, handles included.
LEGEND_WIDTH_CHARS = 90

# matplotlib's tab10, in order; after ten series the colours repeat with another line style,
# marker and hatch.
SERIES_COLOURS: tuple[str, ...] = (
    "#1f77b4",
    "#ff7f0e",
    "#2ca02c",
    "#d62728",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#7f7f7f",
    "#bcbd22",
    "#17becf",
)
_LINE_STYLES: tuple[LineStyleType, ...] = ("-", "--", ":", "-.")
_MARKERS = ("o", "s", "^", "D")
_HATCHES = ("", "//", "..", "xx")

_TITLE_SIZE = 14
_LABEL_SIZE = 12
_TICK_SIZE = 10.5
_LEGEND_SIZE = 10.5
_GRID_ALPHA = 0.3
_BAND_ALPHA = 0.2


@dataclass(frozen=True)
class Series:
    """One scenario's summary along an axis: a mean and its confidence bounds at each x. A
    ``None`` mean is a gap (no data there); a ``None`` bound means no interval (e.g. n < 2)."""

    label: str
    x: Sequence[float | int | str]
    mean: Sequence[float | None]
    low: Sequence[float | None]
    high: Sequence[float | None]
    # a policy that learns nothing: on a learning chart, one level (its first mean and
    # bounds) across the episodes, not a curve whose wiggles would read as learning
    level: bool = False

    def __post_init__(self) -> None:
        lengths = (len(self.x), len(self.mean), len(self.low), len(self.high))
        if len(set(lengths)) != 1:
            raise ValueError(
                f"series {self.label!r}: x, mean, low and high must have one value per point, "
                f"not {lengths[0]}, {lengths[1]}, {lengths[2]} and {lengths[3]}"
            )


@dataclass(frozen=True)
class Difference:
    """One paired comparison in one metric: a method minus its baseline on the seeds both
    ran, with its 95% interval and its p-value adjusted by Holm's method over ``family``
    comparisons (``None``: not tested, e.g. fewer than two pairs)."""

    label: str
    mean: float | None
    low: float | None
    high: float | None
    p_holm: float | None
    family: int | None


@dataclass(frozen=True)
class _Style:
    colour: str
    line_style: LineStyleType
    marker: str
    hatch: str


def _styles(series: Sequence[Series]) -> dict[str, _Style]:
    styles: dict[str, _Style] = {}
    for one in series:
        if one.label not in styles:
            i = len(styles)
            cycle = i // len(SERIES_COLOURS) % len(_LINE_STYLES)
            styles[one.label] = _Style(
                SERIES_COLOURS[i % len(SERIES_COLOURS)],
                _LINE_STYLES[cycle],
                _MARKERS[cycle],
                _HATCHES[cycle],
            )
    return styles


def _floats(values: Sequence[float | None]) -> NDArray[np.float64]:
    """``None`` (and NaN or infinity) become NaN, which matplotlib leaves undrawn: a gap."""
    out = np.array([np.nan if v is None else float(v) for v in values], dtype=np.float64)
    out[~np.isfinite(out)] = np.nan
    return out


def _has_data(series: Series) -> bool:
    return bool(np.isfinite(_floats(series.mean)).any())


def _is_number(value: object) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool | np.bool_)


def _readable(metric: str) -> str:
    return metric.replace("_", " ")


def _tick_label(value: object) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def _style_axes(ax: Axes) -> None:
    ax.tick_params(labelsize=_TICK_SIZE)
    ax.grid(alpha=_GRID_ALPHA)
    ax.set_axisbelow(True)


def _say_no_data(ax: Axes, text: str = NO_DATA) -> None:
    ax.text(
        0.5,
        0.5,
        text,
        transform=ax.transAxes,
        ha="center",
        va="center",
        fontsize=_LABEL_SIZE + 1,
        color="0.4",
    )
    ax.set_yticks([])


def _error_bars(
    ax: Axes,
    x: NDArray[np.float64],
    mean: NDArray[np.float64],
    low: NDArray[np.float64],
    high: NDArray[np.float64],
    colour: str,
) -> None:
    shown = np.isfinite(mean) & np.isfinite(low) & np.isfinite(high)
    if not shown.any():
        return
    below = np.clip(mean[shown] - low[shown], 0.0, None)
    above = np.clip(high[shown] - mean[shown], 0.0, None)
    drawn = ax.errorbar(
        x[shown],
        mean[shown],
        yerr=np.vstack([below, above]),
        fmt="none",
        ecolor=colour,
        elinewidth=1.4,
        capsize=4,
        capthick=1.4,
    )
    for part in (*drawn.lines[1], *drawn.lines[2]):
        part.set_clip_on(False)  # a cap at a bound is drawn whole


def _draw_lines(ax: Axes, series: Sequence[Series], styles: Mapping[str, _Style]) -> list[Artist]:
    every_x = np.array([float(v) for one in series for v in one.x])
    distinct = np.unique(every_x[np.isfinite(every_x)])
    log = len(distinct) >= 2 and distinct[0] > 0 and distinct[-1] / distinct[0] >= LOG_AXIS_RATIO
    positions = np.log10(distinct) if log else distinct
    gap = float(np.min(np.diff(positions))) if len(positions) >= 2 else 1.0
    step = DODGE * gap / (len(series) - 1) if len(series) > 1 else 0.0
    handles: list[Artist] = []
    for i, one in enumerate(series):
        style = styles[one.label]
        x = np.array([float(v) for v in one.x])
        order = np.argsort(x, kind="stable")
        x = x[order]
        mean, low, high = (_floats(v)[order] for v in (one.mean, one.low, one.high))
        shift = (i - (len(series) - 1) / 2) * step
        drawn_x = 10.0 ** (np.log10(x) + shift) if log else x + shift
        ax.plot(
            drawn_x,
            mean,
            color=style.colour,
            linestyle=style.line_style,
            marker=style.marker,
            markersize=6,
            linewidth=1.8,
        )
        _error_bars(ax, drawn_x, mean, low, high, style.colour)
        handles.append(
            Line2D(
                [],
                [],
                color=style.colour,
                linestyle=style.line_style,
                marker=style.marker,
                markersize=6,
                linewidth=1.8,
                label=one.label,
            )
        )
    if log:
        ax.set_xscale("log")
    if len(distinct) <= MAX_TICKED_VALUES:
        ax.set_xticks(distinct, labels=[f"{v:g}" for v in distinct])
        ax.xaxis.set_minor_locator(NullLocator())
    _style_axes(ax)
    return handles


def _draw_bars(ax: Axes, series: Sequence[Series], styles: Mapping[str, _Style]) -> list[Artist]:
    groups: dict[Hashable, int] = {}
    labels: list[str] = []
    for one in series:
        for value in one.x:
            if value not in groups:
                groups[value] = len(groups)
                labels.append(_tick_label(value))
    width = 0.8 / len(series)
    handles: list[Artist] = []
    for i, one in enumerate(series):
        style = styles[one.label]
        x = (
            np.array([groups[v] for v in one.x], dtype=np.float64)
            + (i - (len(series) - 1) / 2) * width
        )
        mean, low, high = (_floats(v) for v in (one.mean, one.low, one.high))
        present = np.isfinite(mean)
        ax.bar(
            x[present],
            mean[present],
            width=width * 0.92,
            color=style.colour,
            hatch=style.hatch,
            edgecolor="white",
            linewidth=0.6,
        )
        _error_bars(ax, x, mean, low, high, "0.15")
        handles.append(
            Patch(facecolor=style.colour, hatch=style.hatch, edgecolor="white", label=one.label)
        )
    crowded = sum(len(label) for label in labels) > 70
    ax.set_xticks(
        range(len(labels)),
        labels=labels,
        rotation=25 if crowded else 0,
        ha="right" if crowded else "center",
    )
    ax.set_xlim(-0.6, len(labels) - 0.4)
    ax.axhline(0.0, color="0.3", linewidth=0.8)
    _style_axes(ax)
    ax.grid(False, axis="x")
    return handles


def _legend(fig: Figure, handles: list[Artist]) -> None:
    """Below the axes, never over the data; as many columns as labels of this length fit."""
    if len(handles) <= 1:
        return
    longest = max(len(str(h.get_label())) for h in handles)
    fig.legend(
        handles=handles,
        fontsize=_LEGEND_SIZE,
        loc="outside lower center",
        ncols=max(1, min(len(handles), LEGEND_WIDTH_CHARS // (longest + 6))),
        frameon=False,
    )


def _keep_to_share(series: Sequence[Series]) -> list[Series]:
    """Each mean and bound of a share inside [0, 1]: an interval made to stay there does, but a
    rounding past 1 must not lift the axis."""

    def inside(values: Sequence[float | None]) -> list[float | None]:
        return [None if v is None else min(max(float(v), 0.0), 1.0) for v in values]

    return [
        Series(one.label, one.x, inside(one.mean), inside(one.low), inside(one.high), one.level)
        for one in series
    ]


def metric_png(
    metric: str,
    series: Sequence[Series],
    *,
    x_label: str | None,
    title: str | None = None,
    bounds: tuple[float, float] | None = None,
    differences: Sequence[Difference] = (),
) -> bytes:
    """``metric_figure`` as a PNG."""
    return png(metric_figure(metric, series, x_label=x_label, title=title, bounds=bounds,
                             differences=differences))  # fmt: skip


def metric_figure(
    metric: str,
    series: Sequence[Series],
    *,
    x_label: str | None,
    title: str | None = None,
    bounds: tuple[float, float] | None = None,
    differences: Sequence[Difference] = (),
) -> Figure:
    """One metric (mean and confidence interval) for each series at each swept value.

    When every x is a number, one line per series with markers and error bars, series nudged
    apart on x so their bars do not hide each other; the axis is logarithmic when the values are
    positive and span a factor of 100 or more. Otherwise (policies, field models: names), a
    grouped bar chart, one group per x in first-seen order. Without any mean to draw, the axes
    say so, and the PNG is still valid and of the same size. A share (``bounds`` (0, 1)) is drawn
    on an axis from 0 to 1 with a margin (``SHARE_LIMITS``), so nothing sits on the frame; a
    metric that cannot be negative (``bounds`` from 0) on an axis from 0, to 1 if all is 0.

    With ``differences`` (a study that compares), a second panel beside the means draws each
    paired difference with its interval around a line at 0, its Holm-adjusted p beside it
    and marked where it is below ``SIGNIFICANT``: an effect the means' own intervals hide
    (they vary with the seeds, the paired difference does not) is seen at a glance.
    """
    share = bounds == (0.0, 1.0)
    if share:
        series = _keep_to_share(series)
    fig = new_figure(*(COMPARED_FIGSIZE if differences else METRIC_FIGSIZE))
    if differences:
        ax, forest = fig.subplots(1, 2, width_ratios=(3, 2))
        _draw_forest(forest, metric, differences)
    else:
        ax = fig.add_subplot()
    handles: list[Artist] = []
    if not any(_has_data(one) for one in series):
        _say_no_data(ax)
        ax.set_xticks([])
    elif all(_is_number(v) for one in series for v in one.x):
        handles = _draw_lines(ax, series, _styles(series))
    else:
        handles = _draw_bars(ax, series, _styles(series))
    if share:
        ax.set_ylim(*SHARE_LIMITS)
    elif bounds is not None and bounds[0] == 0.0 and handles:
        highest = max((v for one in series for v in (*one.mean, *one.high) if v is not None),
                      default=0.0)  # fmt: skip
        ax.set_ylim(0.0, ax.get_ylim()[1] if highest > 0 else 1.0)
    if bounds is not None and bounds[0] == 0.0:
        for line in ax.get_lines():
            line.set_clip_on(False)  # a mean at a bound keeps its whole marker
    ax.set_ylabel(_readable(metric), fontsize=_LABEL_SIZE)
    if x_label:
        ax.set_xlabel(x_label, fontsize=_LABEL_SIZE)
    if title:
        (fig.suptitle if differences else ax.set_title)(title, fontsize=_TITLE_SIZE)
    _legend(fig, handles)
    return fig


def _draw_forest(ax: Axes, metric: str, differences: Sequence[Difference]) -> None:
    """Each difference a row, top to bottom in the given order: its mean as a dot and its
    interval as a bar, a line at 0 (no difference), and its Holm-adjusted p on the right."""
    _style_axes(ax)
    ax.axvline(0.0, color="0.3", linewidth=1.0, zorder=1)
    rows = np.arange(len(differences))[::-1].astype(np.float64)
    mean = _floats([d.mean for d in differences])
    low, high = _floats([d.low for d in differences]), _floats([d.high for d in differences])
    marked = np.array([d.p_holm is not None and d.p_holm < SIGNIFICANT for d in differences])
    whole = np.isfinite(low) & np.isfinite(high) & np.isfinite(mean)
    ax.hlines(rows[whole], low[whole], high[whole], color="0.2", linewidth=1.6, zorder=2)
    for chosen, face in ((marked, "0.1"), (~marked, "white")):
        shown = chosen & np.isfinite(mean)
        ax.scatter(mean[shown], rows[shown], s=42, facecolors=face, edgecolors="0.1",
                   linewidths=1.3, zorder=3)  # fmt: skip
    ax.set_yticks(rows, [d.label for d in differences], fontsize=_TICK_SIZE)
    ax.set_ylim(-0.7, len(differences) - 0.3)
    ax.grid(False, axis="y")
    for row, one in zip(rows, differences, strict=True):
        if one.p_holm is None:
            said = "not tested"
        else:
            said = f"p Holm {one.p_holm:.2g}" + (" *" if one.p_holm < SIGNIFICANT else "")
        ax.annotate(said, (1.0, row), xycoords=("axes fraction", "data"), xytext=(6, 0),
                    textcoords="offset points", va="center", fontsize=_TICK_SIZE)  # fmt: skip
    family = max((d.family or 0 for d in differences), default=0)
    ax.set_xlabel(f"{_readable(metric)}, paired difference", fontsize=_LABEL_SIZE)
    over = f", Holm over {family}" if family else ""
    ax.set_title(f"method minus baseline, 95% CI{over}\n(filled: p Holm < {SIGNIFICANT:g})",
                 fontsize=_LABEL_SIZE)  # fmt: skip


def bin_average(columns: NDArray[np.float64], limit: int) -> NDArray[np.float64]:
    """Rows of ``columns`` (one per quantity, points along axis 1) averaged over consecutive bins
    so that at most ``limit`` points remain. NaN (no data) is left out of a bin's mean; a bin
    with no data at all stays NaN, a gap."""
    rows, n = columns.shape
    if n <= limit:
        return columns
    size = math.ceil(n / limit)
    bins = math.ceil(n / size)
    padded = np.full((rows, bins * size), np.nan)
    padded[:, :n] = columns
    blocks = padded.reshape(rows, bins, size)
    finite = np.isfinite(blocks)
    counts = finite.sum(axis=2)
    sums = np.where(finite, blocks, 0.0).sum(axis=2)
    averages = np.full((rows, bins), np.nan)
    np.divide(sums, counts, out=averages, where=counts > 0)
    return averages


def _draw_curve(ax: Axes, one: Series, style: _Style) -> None:
    if not all(_is_number(v) for v in one.x):
        raise ValueError(f"series {one.label!r}: a learning curve needs numeric episodes on x")
    if one.level:
        _draw_level(ax, one, style)
        return
    x = np.array([float(v) for v in one.x])
    order = np.argsort(x, kind="stable")
    columns = np.vstack([x[order]] + [_floats(v)[order] for v in (one.mean, one.low, one.high)])
    x, mean, low, high = bin_average(columns, MAX_CURVE_POINTS)
    band = np.isfinite(low) & np.isfinite(high)
    if band.any():
        ax.fill_between(
            x,
            np.where(band, low, 0.0),
            np.where(band, high, 0.0),
            where=band,
            color=style.colour,
            alpha=_BAND_ALPHA,
            linewidth=0,
        )
    ax.plot(
        x,
        mean,
        color=style.colour,
        linestyle=style.line_style,
        linewidth=1.6,
        marker=style.marker if len(x) <= 60 else None,
        markersize=3.5,
    )


def _draw_level(ax: Axes, one: Series, style: _Style) -> None:
    """A fixed policy's level: a dashed line at its mean and its interval as a band, across
    the episodes it ran."""
    x = [float(v) for v in one.x]
    mean, low, high = (_floats(v[:1])[0] for v in (one.mean, one.low, one.high))
    if not np.isfinite(mean):
        return
    span = (min(x), max(x))
    if np.isfinite(low) and np.isfinite(high):
        ax.fill_between(span, low, high, color=style.colour, alpha=_BAND_ALPHA, linewidth=0)
    ax.plot(span, (mean, mean), color=style.colour, linestyle="--", linewidth=1.6)


def learning_png(
    panels: Mapping[str, Sequence[Series]],
    *,
    title: str | None = None,
    empty: str = NO_DATA,
    shares: Collection[str] = (),
    x_label: str = "episode",
    whole_x: bool = True,
) -> bytes:
    """Mean learning curves with their confidence bands, one panel per quantity (the key is the
    panel's y label), stacked on a shared axis of episodes (or ``x_label``) with whole-numbered
    ticks (unless not ``whole_x``).

    Curves longer than ``MAX_CURVE_POINTS`` are drawn as bin averages (of the mean and of each
    bound), so thousands of episodes draw quickly. A ``level`` series (a policy that learns
    nothing) is a dashed line with its band, and the legend says so. A panel without data
    says ``empty`` (why there is none); with no panel at all, one empty panel does. The panels
    named in ``shares`` run from 0 to 1 with a margin (``SHARE_LIMITS``), their bands kept
    inside 0 to 1.
    """
    count = max(len(panels), 1)
    fig = new_figure(LEARNING_WIDTH, LEARNING_PANEL_HEIGHT * count)
    axes = fig.subplots(count, 1, sharex=True, squeeze=False)[:, 0]
    styles = _styles([one for group in panels.values() for one in group])
    levels = {one.label for group in panels.values() for one in group if one.level}
    drawn = False
    if not panels:
        _say_no_data(axes[0], empty)
    for ax, (name, group) in zip(axes, panels.items(), strict=False):
        ax.set_ylabel(name, fontsize=_LABEL_SIZE)
        _style_axes(ax)
        if not any(_has_data(one) for one in group):
            _say_no_data(ax, empty)
            continue
        share = name in shares
        for one in _keep_to_share(group) if share else group:
            _draw_curve(ax, one, styles[one.label])
        if share:
            ax.set_ylim(*SHARE_LIMITS)
        drawn = True
    axes[-1].set_xlabel(x_label, fontsize=_LABEL_SIZE)
    if whole_x:
        axes[-1].xaxis.set_major_locator(MaxNLocator(integer=True))
    if title:
        fig.suptitle(title, fontsize=_TITLE_SIZE)
    if drawn:
        _legend(
            fig,
            [
                Line2D(
                    [],
                    [],
                    color=s.colour,
                    linewidth=2.2,
                    linestyle="--" if label in levels else s.line_style,
                    label=f"{label} (fixed: its mean)" if label in levels else label,
                )
                for label, s in styles.items()
            ],
        )
    else:
        axes[-1].set_xticks([])
    return png(fig)


# The habits picture: inches per row (one state of one grid point) and for the fixed parts.
HABIT_ROW_IN = 0.42
HABIT_FIXED_IN = 2.2
HABITS_WIDTH = 10.0


@dataclass(frozen=True)
class HabitRow:
    """One bar of the habits picture: a state of a grid point, the share of seeds whose greedy
    action is each action there, and what to say beside it."""

    label: str  # the grid point and the state
    shares: Mapping[str, float]  # action -> share of the point's seeds, summing to at most 1
    note: str  # its visits and action gap


def habits_png(rows: Sequence[HabitRow], *, title: str | None = None) -> bytes:
    """``habits_figure`` as a PNG."""
    return png(habits_figure(rows, title=title))


NOTE_START = 1.01  # where a habit's note begins, in shares of seeds (the bars end at 1)
NOTE_PAD_PX = 6.0  # between the longest note and the frame


def habits_figure(rows: Sequence[HabitRow], *, title: str | None = None) -> Figure:
    """A horizontal bar per row, split by greedy action (a colour per action, the same in every
    row) in proportion to the seeds that chose it, the note at the bar's end, the axis as long
    as the longest note needs to stay inside the frame. No row: a panel that says so."""
    fig = new_figure(HABITS_WIDTH, HABIT_FIXED_IN + HABIT_ROW_IN * max(len(rows), 1))
    ax = fig.add_subplot()
    _style_axes(ax)
    if not rows:
        _say_no_data(ax)
        ax.set_yticks([])
    actions: list[str] = []
    for row in rows:
        actions.extend(a for a in row.shares if a not in actions)
    colours = {a: SERIES_COLOURS[i % len(SERIES_COLOURS)] for i, a in enumerate(actions)}
    for y, row in enumerate(rows):
        left = 0.0
        for action, share in row.shares.items():
            ax.barh(y, share, left=left, color=colours[action], edgecolor="white", height=0.7)
            left += share
    notes = [
        ax.text(NOTE_START, y, row.note, va="center", fontsize=_LEGEND_SIZE)
        for y, row in enumerate(rows)
    ]
    if rows:
        ax.set_yticks(range(len(rows)), [r.label for r in rows], fontsize=_LEGEND_SIZE)
        ax.set_ylim(len(rows) - 0.5, -0.5)
    ax.set_xticks([0.0, 0.25, 0.5, 0.75, 1.0])
    ax.set_xlabel("share of seeds whose greedy action it is", fontsize=_LABEL_SIZE)
    if title:
        fig.suptitle(title, fontsize=_TITLE_SIZE)
    _legend(fig, [Patch(facecolor=colours[a], label=a) for a in actions])
    ax.set_xlim(0.0, 1.5)
    if notes:
        _fit_notes(fig, ax, notes)
    return fig


def _fit_notes(fig: Figure, ax: Axes, notes: Sequence[Text]) -> None:
    """Lengthen the x axis until the longest note, which starts at ``NOTE_START``, ends inside
    the frame (a note of 30 seeds ran over it and off the image)."""
    fig.draw_without_rendering()  # the layout first: it sets the frame's width
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
    frame = ax.get_window_extent(renderer)
    longest = max(note.get_window_extent(renderer).width for note in notes)
    room = frame.width - NOTE_PAD_PX - longest
    if room > 0:
        ax.set_xlim(0.0, max(1.5, NOTE_START * frame.width / room))
