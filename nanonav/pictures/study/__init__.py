"""A study's pictures: one metric against the swept numeric parameter (a line per compared
method, CI bars; the compared parameter itself when it is the only numeric one), or grouped bars
when no swept parameter is numeric; the mean learning
curves of every grid point with CI bands; and what the learners of each grid point learned.
This module picks what goes on which axis; drawing is ``charts``'s."""

from __future__ import annotations

import numbers
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from nanonav import stats
from nanonav.engine.metrics import RANGES
from nanonav.pictures.study import charts
from nanonav.policy import habits
from nanonav.studies.report import METRICS, PAPER_METRICS, JobOutcome
from nanonav.studies.spec import GridValue, StudySpec, points

LEARNING_PANELS = {
    "steps": "steps per episode",
    "success_rate": "success rate",
    "mean_return": "mean return per robot",
}
PICTURES = (*METRICS, "learning", "policies", "training")
"""Every picture a study can have; ``pictures_of`` says which a given study has."""
HABIT_STATES = 3
"""The most visited states the policies picture shows for each grid point that learns."""
EVERY_STUDYS_PICTURES = (*PAPER_METRICS, "learning")
"""The pictures every study has, whatever its jobs report."""
SECONDS_PANEL = "time per episode (s)"
"""The first learning panel of a study whose every point is active Brownian: steps x dt_s."""
VERSION = 7
"""The version of the drawing of every picture of a study: it goes up when a picture drawn
before would now be drawn differently, so that a copy kept of the older drawing is drawn again.
2: series and groups named in words (``robots policy: q_learning``, not
``robots.policy=q_learning``), and a metric's title no longer says its interval is Student t's
(bounded metrics have others: ``nanonav.stats``). 3: an active Brownian study's learning curves
give each episode's length in seconds. 4: a study that sweeps only its compared number draws it
as a line, a share's axis runs from 0 to 1, episodes are whole numbers, a study without
training episodes says so, and the wall-clock duration is no metric. 5: a share of trials
has the interval of its seeds' pooled trials (``nanonav.stats.describe_share``), so a perfect
column no longer draws the longest bar. 6: a study that compares draws its paired
differences beside the means (a forest plot, Holm-adjusted p marked), and a policy that learns
nothing is a level on the learning curves, not a curve. 7: a study whose points train networks
draws their training curves against the decisions trained, beside every other point's level
(``training``)."""
TRAINING_PANEL = "success rate"
"""The training picture's one panel: a learner's training episodes, a fixed point's evaluation."""
NO_TRAINING = "no network of this study has finished its training yet"
"""What the training picture of a study none of whose learners has succeeded yet says."""
NO_EPISODES = "no training episodes in this study"
"""What the learning picture of a study whose finished jobs trained for no episode says."""


def _numeric(values: Sequence[GridValue]) -> bool:
    return all(isinstance(v, numbers.Real) and not isinstance(v, bool) for v in values)


def axis_key(spec: StudySpec) -> str | None:
    """The grid key drawn along x: the first swept numeric key that is not compared, else the
    compared key itself when it is numeric (a study that compares robot counts, say, and sweeps
    nothing else draws the counts as a line, not a bar per count)."""
    found = next(
        (k for k, values in spec.grid.items() if k != spec.compare and _numeric(values)), None
    )
    if found is None and spec.compare is not None and _numeric(spec.grid[spec.compare]):
        return spec.compare
    return found


def readable_key(key: str) -> str:
    """A grid key in words, its section kept, as a field alone can be ambiguous (``count``,
    ``step``): ``robots.policy`` is robots policy, ``learning.shared_table`` learning shared
    table."""
    return key.replace(".", " ").replace("_", " ")


def _readable_value(value: GridValue) -> str:
    if value is None:
        return "null"  # as the study's JSON says it
    if isinstance(value, bool):
        return "true" if value else "false"  # as the study's JSON says it
    return f"{value:g}" if isinstance(value, float) else str(value)


def _label(values: dict[str, GridValue], keys: Sequence[str]) -> str:
    return ", ".join(f"{readable_key(k)}: {_readable_value(values[k])}" for k in keys)


def pictures_of(
    report: dict[str, Any], learns: bool = False, trains: bool = False
) -> tuple[str, ...]:
    """The pictures of the study ``report`` describes: a chart of each metric it reports (the
    swarm's only once a job has them: ``nanonav.studies.report.reported_metrics``), the
    learning curves, if any of its points ``learns`` (``learning_points``) its policies, and
    if any ``trains`` a network (``training_points``) the training curves."""
    metrics = (m for m in METRICS if m in report["metrics"])
    return (*metrics, "learning", *learner_pictures(learns, trains))


def learner_pictures(learns: bool, trains: bool = False) -> tuple[str, ...]:
    """The pictures of a study's learners: its policies if a point ``learns`` a Q-table
    (``learning_points``), its training curves if one ``trains`` a network
    (``training_points``)."""
    return (*(("policies",) if learns else ()), *(("training",) if trains else ()))


def learning_points(spec: StudySpec) -> list[int]:
    """The grid points whose robots learn a Q-table (q_learning trained for at least an
    episode): those the policies picture shows."""
    return [
        p.index
        for p in points(spec)
        if p.scenario.robots.policy == "q_learning" and p.scenario.learning.episodes > 0
    ]


_DECISION_UNITS = ((1e6, " (millions)"), (1e3, " (thousands)"), (1.0, ""))


def training_points(spec: StudySpec) -> list[int]:
    """The grid points whose jobs train a network (robots.policy ppo, recurrent_ppo): those
    the training picture draws as curves."""
    return [p.index for p in points(spec) if p.scenario.trains]


def training_png(
    spec: StudySpec, values: Sequence[dict[str, GridValue]], jobs: Sequence[JobOutcome]
) -> bytes:
    """Does the learner beat the rule, as its training went: each point that trains a network
    as a curve of its training episodes' success rate against the decisions trained (the mean
    over its succeeded seeds, with their CI; the actions sampled, as it trains), and every
    other point as a level, its evaluation's success rate over its seeds with their CI, drawn
    across the same decisions. A learner's own evaluation (greedy) is in the success_rate
    picture beside the rule's, paired by seed."""
    trained = set(training_points(spec))
    succeeded = [job for job in jobs if job.status == "succeeded"]
    curves: dict[int, list[dict[str, list[Any]]]] = {}
    for job in succeeded:
        if job.point in trained and job.curve is not None and job.curve.get("decisions"):
            curves.setdefault(job.point, []).append(job.curve)
    reach = max((c["decisions"][-1] for found in curves.values() for c in found), default=0.0)
    # decisions in millions or thousands: a reader sees the figures, not an offset in a corner
    scale, unit = next((s, u) for s, u in _DECISION_UNITS if reach >= s or s == 1)
    series: list[charts.Series] = []
    for index, point_values in enumerate(values):
        label = _label(point_values, list(spec.grid)) or "base scenario"
        if index in trained:
            found = curves.get(index, [])
            length = min((len(c["decisions"]) for c in found), default=0)
            if length == 0:
                continue
            described = []
            for row in range(length):
                shares = [c["training_success_rate"][row] for c in found]
                kept = [float(s) for s in shares if s is not None]
                described.append(stats.describe(kept, bounds=(0.0, 1.0)) if kept else None)
            series.append(
                charts.Series(
                    label,
                    [d / scale for d in found[0]["decisions"][:length]],
                    [None if d is None else d.mean for d in described],
                    [None if d is None else d.ci_low for d in described],
                    [None if d is None else d.ci_high for d in described],
                )
            )
        elif reach > 0:
            rates = [
                float(job.metrics["success_rate"])
                for job in succeeded
                if job.point == index and job.metrics is not None
                and job.metrics.get("success_rate") is not None
            ]  # fmt: skip
            if not rates:
                continue
            level = stats.describe(rates, bounds=(0.0, 1.0))
            series.append(
                charts.Series(
                    label, [0.0, reach / scale], [level.mean] * 2, [level.ci_low] * 2,
                    [level.ci_high] * 2, level=True,
                )
            )  # fmt: skip
    return charts.learning_png(
        {TRAINING_PANEL: series} if series else {},
        title=f"{spec.name or 'Study'}: training curves (learners) and evaluations (fixed)",
        empty=NO_TRAINING,
        shares={TRAINING_PANEL},
        x_label=f"decisions trained{unit}",
        whole_x=False,
    )


def policies_png(
    spec: StudySpec,
    values: Sequence[dict[str, GridValue]],
    tables: Mapping[int, Sequence[Mapping[str, NDArray[Any]]]],
) -> bytes:
    """What the learners of every grid point learned: the ``HABIT_STATES`` states its seeds'
    tables visit most, each as a bar of the greedy action counted over seeds, with its share of
    visits and the mean action gap beside it. ``tables`` holds each point's succeeded jobs'
    Q-tables (``nanonav.policy.habits``)."""
    rows = []
    for index, point_values_ in enumerate(values):
        found = tables.get(index, [])
        label = _label(point_values_, list(spec.grid)) or "base scenario"
        for habit in habits(found, HABIT_STATES):
            seeds = max(sum(habit.greedy.values()), 1)
            gap = "" if habit.mean_gap is None else f", mean gap {habit.mean_gap:.2g}"
            rows.append(
                charts.HabitRow(
                    f"{label}\n{habit.state}",
                    {a: n / seeds for a, n in habit.greedy.items()},
                    f"{habit.visit_share:.0%} of visits{gap}, {seeds} seeds",
                )
            )
    title = f"{spec.name or 'Study'}: greedy action in the most visited states, over seeds"
    return charts.habits_png(rows, title=title)


def metric_png(spec: StudySpec, report: dict[str, Any], metric: str) -> bytes:
    """``metric``'s mean and CI at every grid point of ``report``; ``ValueError`` for a metric
    the report does not have (one of the swarm's that no job of the study gives)."""
    if metric not in report["metrics"]:
        raise ValueError(f"no job of this study reports {metric}")
    axis = axis_key(spec)
    rows = report["points"]
    if axis is not None:
        grouping = [k for k in spec.grid if k != axis]
    else:
        grouping = [spec.compare] if spec.compare is not None else []
    series: dict[str, dict[str, list[Any]]] = {}
    for row in rows:
        values = row["values"]
        label = _label(values, grouping) or "all seeds"
        if axis is not None:
            x: GridValue = values[axis]
        else:
            x = _label(values, [k for k in spec.grid if k not in grouping]) or "base scenario"
        found = row["metrics"][metric]
        line = series.setdefault(label, {"x": [], "mean": [], "low": [], "high": []})
        line["x"].append(x)
        line["mean"].append(found["mean"])
        line["low"].append(found["ci_low"])
        line["high"].append(found["ci_high"])
    drawn = [
        charts.Series(label, s["x"], s["mean"], s["low"], s["high"]) for label, s in series.items()
    ]
    title = f"{spec.name or 'Study'}: {metric.replace('_', ' ')}, mean with 95% CI"
    x_label = None if axis is None else readable_key(axis)
    return charts.metric_png(metric, drawn, x_label=x_label, title=title, bounds=RANGES[metric],
                             differences=differences(spec, report, metric))  # fmt: skip


def differences(spec: StudySpec, report: dict[str, Any], metric: str) -> list[charts.Difference]:
    """The report's paired comparisons in ``metric``, labelled "method minus baseline" and by the
    other grid keys' values, in the report's order."""
    others = [k for k in spec.grid if k != spec.compare]
    found = []
    for comparison in report.get("comparisons", []):
        difference = comparison["metrics"].get(metric)
        if difference is None:
            continue
        method, baseline = comparison["method"], comparison["baseline"]
        label = f"{_readable_value(method)} vs {_readable_value(baseline)}"
        where = _label(comparison["values"], others)
        found.append(charts.Difference(
            f"{label}\n{where}" if where else label, difference.get("mean_difference"),
            difference.get("ci_low"), difference.get("ci_high"), difference.get("p_holm"),
            difference.get("holm_comparisons"),
        ))  # fmt: skip
    return found


def learning_png(
    spec: StudySpec, values: Sequence[dict[str, GridValue]], jobs: Sequence[JobOutcome]
) -> bytes:
    """The learning curve of every grid point, averaged over its succeeded seeds, with CIs; a
    point whose policy learns nothing (anything but ``q_learning``) is a level, the mean of its
    episodes over its seeds with their CI, since its episodes are trials of one behaviour and
    a curve would make their noise look like learning. When every point is active Brownian,
    an episode's length is in seconds (each point's steps times its own dt_s), as its
    scenarios speak."""
    step_s = [p.scenario.physics.step_s if p.scenario.physics.model == "active_brownian" else None
              for p in points(spec)]  # fmt: skip
    seconds = all(dt is not None for dt in step_s)
    titles = dict(LEARNING_PANELS)
    if seconds:
        titles["steps"] = SECONDS_PANEL
    panels: dict[str, list[charts.Series]] = {title: [] for title in titles.values()}
    finished = [job for job in jobs if job.status == "succeeded" and job.curve is not None]
    fixed = [p.scenario.robots.policy != "q_learning" for p in points(spec)]
    for index, point_values in enumerate(values):
        curves = [job.curve for job in finished if job.point == index and job.curve is not None]
        length = min((len(c["episode"]) for c in curves), default=0)
        if length == 0:
            continue
        # an episode's number is never missing (only a training row's share may be)
        episodes = [e for e in curves[0]["episode"][:length] if e is not None]
        label = _label(point_values, list(spec.grid)) or "base scenario"
        for key, title in titles.items():
            matrix = np.array([c[key][:length] for c in curves], dtype=np.float64)
            if key == "steps" and seconds:
                matrix *= step_s[index] or 1.0
            if fixed[index]:
                # its episodes are trials of one behaviour: each seed's mean over them, and
                # their mean and interval over the seeds, as one level
                level = stats.describe(np.nanmean(matrix, axis=1).tolist())
                described = [level] * length
            else:
                described = [stats.describe(column.tolist()) for column in matrix.T]
            panels[title].append(
                charts.Series(
                    label,
                    episodes,
                    [d.mean for d in described],
                    [d.ci_low for d in described],
                    [d.ci_high for d in described],
                    level=fixed[index],
                )
            )
    return charts.learning_png(
        panels,
        title=f"{spec.name or 'Study'}: learning curves",
        empty=NO_EPISODES if finished else charts.NO_DATA,
        shares={titles["success_rate"]},
    )
