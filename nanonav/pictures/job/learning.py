"""The learning curve: one point per training episode with its moving mean, and the greedy
evaluation after them, its mean over the evaluation worlds with the 95% interval."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, get_args

import numpy as np
from matplotlib.artist import Artist
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator
from numpy.typing import NDArray

from nanonav.engine import SimulationResult
from nanonav.pictures.figure import png
from nanonav.pictures.job.common import ROBOT_BLUE, sized_figure
from nanonav.scenario import TRAINED_POLICIES, Policy

_POLICY_NAMES = {
    "q_learning": "Q-learning",
    "gradient": "gradient climbing",
    "run_and_tumble": "run and tumble",
    "rule": "the fixed rule",
    "simple_rule": "the simple rule",
    "random": "the random walk",
    "uncontrolled": "the uncontrolled swimmer",
    "exact_gradient": "steering by the exact gradient",
    "steer_and_tumble": "steering and tumbling",
    "blind_tumble": "the blind tumbler",
    "ppo": "PPO",
    "recurrent_ppo": "recurrent PPO",
}
# Policies that learn nothing: their episodes are independent trials of the same behaviour.
BASELINES = frozenset(get_args(Policy)) - {"q_learning"} - TRAINED_POLICIES
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


def learning_panels(result: SimulationResult) -> tuple[_Panel, ...]:
    """The learning curve's panels: in active_brownian an episode's length in seconds (steps
    times dt_s), physical time being what its scenario speaks in; in the lattice, in steps."""
    physics = result.scenario.physics
    if physics.model != "active_brownian":
        return _LEARNING_PANELS
    seconds = _Panel("steps", "episode_steps", "time per episode", "time (s)", physics.step_s)
    return (seconds, *_LEARNING_PANELS[1:])


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

    Only the metrics document is read (the evaluation's summary, uncertainty and worlds, never
    the trajectory), so a result stored without its trajectory draws the same curve.
    """
    baseline = result.scenario.robots.policy in BASELINES
    evaluated = result.completed and bool(result.summary)
    trial_name, trials = _trials(result, evaluated)
    if not trials and not evaluated:
        raise ValueError("this result has no finished episode to draw a learning curve from")
    every = learning_panels(result)
    panels = every if trials and not baseline else every[:3]
    show_evaluation = evaluated and not baseline
    planned = result.scenario.learning.episodes if trial_name == "episode" else len(trials)
    index = np.array([float(e["episode"]) for e in trials])
    last = max(len(trials), planned) - 1.0  # the last episode planned or finished
    gap = max(1.0, 0.06 * max(last, 1.0))  # between the last episode and the evaluation
    x_eval = last + gap if trials else 0.0
    window = smoothing_window(len(trials))
    fig = sized_figure("learning")
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
    style: dict[str, Any] = {"color": ROBOT_BLUE, "linewidth": 0.8}
    if points:
        style.update(marker="o", markersize=2.5)
    if window > 1:
        ax.plot(index, values, alpha=0.3, **style)
        ax.plot(index, moving_mean(values, window), color=ROBOT_BLUE, linewidth=2.0)
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
            Line2D([], [], color=ROBOT_BLUE, linewidth=0.8, alpha=0.3 if window > 1 else 1.0,
                   marker="o" if points else None, markersize=2.5, label=f"each {trial_name}")
        )  # fmt: skip
    if trial_name is not None and window > 1:
        handles.append(
            Line2D([], [], color=ROBOT_BLUE, linewidth=2.0, label=f"moving mean of {window}")
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
        if policy in TRAINED_POLICIES:
            decisions = result.scenario.training_decisions
            return f"{name}: a network trained in the job for {decisions:,} decisions, evaluated"
        if "decide_calls" in result.work:  # decided from outside: a network
            return f"A network ({actions}), sent as {source}: evaluated, it does not learn"
        if isinstance(source, str):
            table = f"the table sent as {source}"
        else:
            table = f"the table of job {source}" if source is not None else "an untrained table"
        return f"Q-learning ({actions}): {table}, evaluated without training"
    return f"Learning curve: Q-learning ({actions}), {done} training episodes{stopped}"


def learning_png(result: SimulationResult) -> bytes:
    """The learning curve (``learning_figure``) as PNG bytes."""
    return png(learning_figure(result))
