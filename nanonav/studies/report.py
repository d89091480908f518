"""What a study's jobs add up to: per grid point and metric, n, mean, sd and a confidence
interval; with ``compare``, paired differences seed by seed against the first value listed.

Pure functions over plain data: the store supplies each job's status and metrics, the API and
the command line show what comes out. Only succeeded jobs enter the statistics; the others are
counted, per status, beside them.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from nanonav import stats
from nanonav.engine.metrics import RANGES, SHARES_OF, SWARM
from nanonav.scenario import Scenario
from nanonav.status import STATUSES, Status
from nanonav.studies.spec import GridValue, StudySpec, points

# The paper's Table 1, then success, collisions and path efficiency: every study reports them.
# Table 1's duration is left out: it is the wall-clock time a run took on whatever machine ran
# it, not a result of the scenario, so it is neither summarised, drawn nor compared.
PAPER_METRICS = (
    "total_steps",
    "final_distance",
    "average_distance",
    "average_concentration",
    "success_rate",
    "collisions",
    "path_efficiency",
)
WALL_CLOCK = "duration_s"
"""A job's wall-clock time per evaluation world (Table 1's duration), kept for the export only."""
WALL_CLOCK_COLUMN = "wall_clock_duration_s"
"""The export's column of ``WALL_CLOCK``, named so that no one takes it for a result."""
# The swarm's numbers (``nanonav.engine.metrics``): only runs whose robots take up space, treat
# cells or signal have them, so a study reports each only once one of its jobs has it.
SWARM_METRICS: tuple[str, ...] = SWARM
METRICS = PAPER_METRICS + SWARM_METRICS


def trials(scenario: Scenario, metric: str) -> int:
    """How many trials a job of ``scenario`` counts ``metric``'s share over (``SHARES_OF``)."""
    counted = scenario.robots.count if SHARES_OF[metric] == "robots" else scenario.cells.count
    return counted * scenario.evaluation.worlds


# A job's learning curve is kept at most this many points long (episodes averaged in bins).
CURVE_POINTS = 200
CURVE_KEYS = ("steps", "success_rate", "mean_return")


@dataclass(frozen=True)
class JobOutcome:
    """One job of a study, as the store has it."""

    job_id: int
    point: int
    seed: int
    status: str
    metrics: dict[str, Any] | None  # its METRICS; None unless it succeeded
    curve: dict[str, list[float | None]] | None = None  # its binned learning curve, if asked


def study_metrics(document: dict[str, Any]) -> dict[str, Any]:
    """The metrics a study reads of a succeeded job's metrics document: the paper's, those of
    the swarm's its run has, and its wall-clock time (``WALL_CLOCK``, for the export)."""
    summary = document.get("summary") or {}
    return {key: summary.get(key) for key in (*PAPER_METRICS, WALL_CLOCK)} | {
        key: summary[key] for key in SWARM_METRICS if key in summary
    }


def reported_metrics(jobs: Sequence[JobOutcome]) -> tuple[str, ...]:
    """The metrics a study of ``jobs`` reports, in ``METRICS`` order: the paper's always, each
    of the swarm's once a job that succeeded has it (so a study of the paper's scenarios has
    no column, chart or statistic of numbers none of its runs gives)."""
    given = tuple(key for key in SWARM_METRICS if any(_value(j, key) is not None for j in jobs))
    return PAPER_METRICS + given


def learning_curve(document: dict[str, Any]) -> dict[str, list[float | None]]:
    """A job's learning curve averaged in at most ``CURVE_POINTS`` bins of episodes (jobs of one
    grid point have as many episodes, so they bin alike); of a network the job trained, also
    its training curve's rows (``decisions``, ``training_success_rate``: None where no
    training episode ended), which jobs of one grid point close at the same decisions."""
    episodes = document.get("episodes") or []
    bins = max(1, math.ceil(len(episodes) / CURVE_POINTS))
    curve: dict[str, list[float | None]] = {"episode": [], **{key: [] for key in CURVE_KEYS}}
    for start in range(0, len(episodes), bins):
        chunk = episodes[start : start + bins]
        curve["episode"].append(float(np.mean([e["episode"] for e in chunk])))
        for key in CURVE_KEYS:
            curve[key].append(float(np.mean([float(e[key]) for e in chunk])))
    rows = document.get("training_curve")
    if rows:
        curve["decisions"] = [float(row["decisions"]) for row in rows]
        curve["training_success_rate"] = [row.get("success_rate") for row in rows]
    return curve


StudyStatus = Status  # a study's status: its jobs', and cancelled once a cancel was asked


def status_of(counts: Mapping[str, int], cancel_requested: bool) -> StudyStatus:
    """The study's status from its jobs': queued, then running until every job has finished;
    then cancelled if a cancel was asked or a job was cancelled, failed if a job failed, else
    succeeded."""
    queued = counts.get("queued", 0)
    if queued + counts.get("running", 0):
        return "queued" if queued == sum(counts.values()) else "running"
    if cancel_requested or counts.get("cancelled", 0):
        return "cancelled"
    return "failed" if counts.get("failed", 0) else "succeeded"


def status_counts(jobs: Sequence[JobOutcome]) -> Counter[str]:
    counts: Counter[str] = Counter({status: 0 for status in STATUSES})
    counts.update(job.status for job in jobs)
    return counts


def _value(job: JobOutcome, metric: str) -> float | None:
    if job.status != "succeeded" or job.metrics is None:
        return None
    value = job.metrics.get(metric)
    return None if value is None or not math.isfinite(value) else float(value)


def report(
    spec: StudySpec, values: Sequence[dict[str, GridValue]], jobs: Sequence[JobOutcome]
) -> dict[str, Any]:
    """The statistics of a study whose grid points have ``values`` (in point order): each
    metric's mean over the seeds that succeeded with its interval, a share of trials
    (``SHARES_OF``) by ``stats.describe_share`` over the seeds' pooled trials, any other metric
    by ``stats.describe`` within its range; and the paired comparisons."""
    by_point: dict[int, list[JobOutcome]] = {i: [] for i in range(len(values))}
    for job in jobs:
        by_point[job.point].append(job)
    metrics = reported_metrics(jobs)
    scenarios = [point.scenario for point in points(spec)]
    point_rows = []
    for index, point_values in enumerate(values):
        members = by_point[index]
        counts = status_counts(members)
        described = {}
        for metric in metrics:
            sample = [v for v in (_value(j, metric) for j in members) if v is not None]
            if metric in SHARES_OF:
                each = trials(scenarios[index], metric)
                found = stats.describe_share(sample, [each] * len(sample))
            else:
                found = stats.describe(sample, bounds=RANGES[metric])
            described[metric] = found.to_dict()
        point_rows.append(
            {"index": index, "values": point_values, "jobs": dict(counts), "metrics": described}
        )
    return {
        "metrics": list(metrics),
        "interval": stats.CONFIDENCE_METHOD,
        "test": stats.TEST_METHOD,
        "adjustment": stats.ADJUSTMENT_METHOD,
        "resolution": stats.RESOLVABLE_METHOD,
        "points": point_rows,
        "comparisons": comparisons(spec, values, by_point, metrics),
    }


def comparisons(
    spec: StudySpec,
    values: Sequence[dict[str, GridValue]],
    by_point: dict[int, list[JobOutcome]],
    metrics: Sequence[str],
) -> list[dict[str, Any]]:
    """Each value of ``spec.compare`` against its first, at every combination of the other grid
    keys, on the seeds where both jobs succeeded, in each of ``metrics``."""
    key = spec.compare
    if key is None:
        return []
    baseline_value = spec.grid[key][0]
    groups: dict[tuple[Any, ...], dict[GridValue, int]] = {}
    for index, point_values in enumerate(values):
        others = tuple((k, v) for k, v in point_values.items() if k != key)
        groups.setdefault(others, {})[point_values[key]] = index
    found = []
    # each metric's comparisons, the family Holm's adjustment is made over
    families: dict[str, list[dict[str, Any]]] = {metric: [] for metric in metrics}
    for others, members in groups.items():
        baseline = {job.seed: job for job in by_point[members[baseline_value]]}
        for method in spec.grid[key][1:]:
            treated = {job.seed: job for job in by_point[members[method]]}
            compared = {}
            for metric in metrics:
                pairs = [
                    (a, b)
                    for seed in sorted(treated.keys() & baseline.keys())
                    if (a := _value(treated[seed], metric)) is not None
                    and (b := _value(baseline[seed], metric)) is not None
                ]
                found_pair = stats.paired([a for a, _ in pairs], [b for _, b in pairs])
                difference: dict[str, Any] = found_pair.to_dict()
                difference["resolvable"] = stats.resolvable_difference(found_pair.sd, found_pair.n)
                compared[metric] = difference
                families[metric].append(difference)
            found.append(
                {
                    "values": dict(others),
                    "method": method,
                    "baseline": baseline_value,
                    "metrics": compared,
                }
            )
    for family in families.values():
        adjust_by_holm(family)
    return found


def adjust_by_holm(family: Sequence[dict[str, Any]]) -> None:
    """Each difference of ``family`` (one metric's comparisons) given ``p_holm``, its p-value
    adjusted by Holm's method over those of the family that have one, and ``holm_comparisons``,
    how many that is (a difference without a p-value gets neither)."""
    tested = [d for d in family if d.get("p_value") is not None]
    adjusted = stats.holm([d["p_value"] for d in tested]) if tested else []
    for difference in family:
        difference["p_holm"] = None
        difference["holm_comparisons"] = None
    for difference, p_holm in zip(tested, adjusted, strict=True):
        difference["p_holm"] = p_holm
        difference["holm_comparisons"] = len(tested)


def table(
    values: Sequence[dict[str, GridValue]], jobs: Sequence[JobOutcome]
) -> list[dict[str, Any]]:
    """A row per job: its id, seed, every grid value, status, the metrics the study reports
    (``reported_metrics``; empty unless it succeeded) and its wall-clock time per world
    (``WALL_CLOCK_COLUMN``), in job order."""
    metrics = reported_metrics(jobs)
    rows = []
    for job in sorted(jobs, key=lambda j: j.job_id):
        row: dict[str, Any] = {"job_id": job.job_id, "seed": job.seed}
        row.update(values[job.point])
        row["status"] = job.status
        row.update({metric: _value(job, metric) for metric in metrics})
        row[WALL_CLOCK_COLUMN] = _value(job, WALL_CLOCK)
        rows.append(row)
    return rows


def table_columns(spec: StudySpec, jobs: Sequence[JobOutcome]) -> list[str]:
    """The table's columns: ids, grid keys, status, the metrics a study of ``jobs`` reports and
    the wall-clock time per world, last."""
    return ["job_id", "seed", *spec.grid, "status", *reported_metrics(jobs), WALL_CLOCK_COLUMN]


DIFFERENCE_COLUMNS = (
    "n",
    "mean_difference",
    "sd",
    "ci_low",
    "ci_high",
    "p_value",
    "p_holm",
    "holm_comparisons",
    "resolvable",
)
"""What the comparisons' table gives of each paired difference, in the report's own names."""


def comparison_columns(spec: StudySpec) -> list[str]:
    """The comparisons' table's columns: the other grid keys, the compared key (its value, the
    method), ``baseline`` (the value it is measured against), ``metric``, then each
    ``DIFFERENCE_COLUMNS``."""
    others = [key for key in spec.grid if key != spec.compare]
    compared = [] if spec.compare is None else [spec.compare, "baseline"]
    return [*others, *compared, "metric", *DIFFERENCE_COLUMNS]


def comparison_table(spec: StudySpec, found: Mapping[str, Any]) -> list[dict[str, Any]]:
    """A row per paired difference of the report ``found`` (a method against the baseline at
    one combination of the other keys, in one metric), in the report's order: what a reader of
    a paper's table takes in, each p-value beside its Holm-adjusted one; none unless the study
    compares."""
    rows = []
    for comparison in found.get("comparisons", []):
        for metric, difference in comparison["metrics"].items():
            row: dict[str, Any] = dict(comparison["values"])
            row[str(spec.compare)] = comparison["method"]
            row["baseline"] = comparison["baseline"]
            row["metric"] = metric
            row.update({column: difference.get(column) for column in DIFFERENCE_COLUMNS})
            rows.append(row)
    return rows
