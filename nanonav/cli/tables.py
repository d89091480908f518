"""What the command prints as text: Table 1 of a run, a study's intervals and comparisons, and
a list of jobs. Pure functions of plain data, so a local run and a job fetched from a server
print alike."""

from __future__ import annotations

import textwrap
from collections.abc import Mapping, Sequence
from datetime import datetime
from typing import Any

from nanonav import table1
from nanonav.client import Job, Policy, Study
from nanonav.table1 import number

MAX_ROBOT_ROWS = 20
WIDTH = 100  # where notes under a table wrap


def text_table(
    columns: Sequence[str], rows: Sequence[Sequence[str]], *, align_right: Sequence[bool]
) -> list[str]:
    """Columns padded to their widest cell, under a rule of dashes."""
    widths = [max(len(c), *(len(r[i]) for r in rows)) for i, c in enumerate(columns)]

    def line(cells: Sequence[str]) -> str:
        return "  ".join(
            cell.rjust(w) if right else cell.ljust(w)
            for cell, w, right in zip(cells, widths, align_right, strict=True)
        ).rstrip()

    rule = "  ".join("-" * w for w in widths)
    return [line(columns), rule, *(line(r) for r in rows)]


# ---------------------------------------------------------------- Table 1


def plural(count: int, word: str) -> str:
    return f"{count} {word}{'s' if count != 1 else ''}"


def grid_text(value: Any) -> str:
    """A grid value in a table: null as the study's JSON says it, the rest as Python does."""
    return "null" if value is None else str(value)


def policy_words(scenario: Mapping[str, Any], sent: Policy | None = None) -> str:
    """What decides a job's robots: a policy sent to the service (``policy-3 "chemotaxis", a
    network sent`` when ``sent`` is its record, else ``policy-3, sent``), the table another job
    learned (``job 12's table``), else the scenario's policy, and a learner's action set
    (``q_learning (behaviors)``)."""
    source = scenario.get("policy_from")
    if isinstance(source, str):
        if sent is None:
            return f"{source}, sent"
        named = f' "{sent.name}"' if sent.name else ""
        return f"{source}{named}, a {sent.kind} sent"
    if source is not None:
        return f"job {source}'s table"
    robots = scenario.get("robots") or {}
    policy = str(robots.get("policy", ""))
    if policy == "q_learning":
        return f"{policy} ({(scenario.get('learning') or {}).get('actions', 'behaviors')})"
    return policy


def _decided_by(scenario: Mapping[str, Any]) -> str:
    """``policy_words`` in one word for a list's column: policy-3, job-12, gradient."""
    source = scenario.get("policy_from")
    if source is not None:
        return source if isinstance(source, str) else f"job-{source}"
    return str((scenario.get("robots") or {}).get("policy", ""))


def format_table(document: Mapping[str, Any], sent: Policy | None = None) -> str:
    """Table 1 of the paper as text, from a run's metrics document (``SimulationResult.to_dict``
    or ``GET /jobs/{id}/metrics``), with success rate, collisions and path efficiency, and for a
    swarm a per-robot table (the first ``MAX_ROBOT_ROWS`` robots); ``sent``, the policy its
    ``policy_from`` names, if it was sent to the service, to name it in the heading."""
    scenario = document["scenario"]
    summary = document.get("summary") or {}
    robots_rows = document.get("robots") or []
    rows = table1.rows(document)
    robots = int(scenario["robots"]["count"])
    worlds = summary.get("worlds")
    header = (
        f"Table 1: {scenario.get('preset') or 'custom scenario'}, seed {scenario['seed']}, "
        f"{plural(robots, 'robot')}, {plural(int(scenario['cells']['count']), 'cell')}, "
        f"{policy_words(scenario, sent)}, "
        f"{plural(int(scenario['learning']['episodes']), 'training episode')}, then "
        + (f"the mean over {plural(int(worlds), 'evaluation world')}" if worlds else "evaluation")
    )
    columns = ("Parameter", "Result", "95% CI over worlds" if worlds else "")
    lines = [header, *text_table(columns, rows, align_right=(False, True, True))]
    if robots > 1 and robots_rows:
        lines += ["", "Per robot (the first evaluation world):"]
        shown = robots_rows[:MAX_ROBOT_ROWS]
        physical = (scenario.get("physics") or {}).get("model") == "active_brownian"
        length = table1.micrometres if physical else number
        concentration = table1.nanomolar if physical else number
        robot_rows = [
            (
                str(row.get("robot")),
                number(row.get("reached")),
                number(row.get("total_steps")),
                length(row.get("final_distance")),
                length(row.get("average_distance")),
                concentration(row.get("average_concentration")),
                number(row.get("collisions")),
                number(row.get("path_efficiency")),
            )
            for row in shown
        ]
        robot_columns = ("robot", "reached", "steps", "final dist", "avg dist", "avg conc",
                         "collisions", "path eff")  # fmt: skip
        lines += text_table(robot_columns, robot_rows, align_right=(True,) * len(robot_columns))
        if len(robots_rows) > len(shown):
            lines.append(
                f"... and {len(robots_rows) - len(shown)} more robots (see --json or metrics.json)"
            )
    return "\n".join(lines)


# ---------------------------------------------------------------- studies


def _figure(value: float | None) -> str:
    """Four significant digits, thousands grouped, ``n/a`` for a missing value."""
    if value is None:
        return "n/a"
    if value != 0 and 1e4 <= abs(value) < 1e12:
        return f"{value:,.0f}"
    return f"{value:.4g}"


def _interval(low: float | None, high: float | None) -> str:
    return "n/a" if low is None or high is None else f"[{_figure(low)}, {_figure(high)}]"


def _p(value: float | None) -> str:
    if value is None:
        return "n/a"
    return "<0.001" if value < 0.001 else f"{value:.3f}"


def study_counts(study: Study) -> str:
    """``4 jobs: 3 succeeded, 1 failed, 0 cancelled`` (and those still queued or running)."""
    jobs = study.jobs
    parts = [f"{jobs.succeeded} succeeded", f"{jobs.failed} failed", f"{jobs.cancelled} cancelled"]
    if jobs.running:
        parts.append(f"{jobs.running} running")
    if jobs.queued:
        parts.append(f"{jobs.queued} queued")
    return f"{plural(jobs.total, 'job')}: {', '.join(parts)}"


def format_study(study: Study) -> str:
    """A study's statistics: per grid point and metric n, mean and 95% CI; with ``compare``,
    the paired differences against the baseline, their CI and p-value; and what became of its
    jobs (failed jobs are counted, never averaged in)."""
    name = f' "{study.name}"' if study.name else ""
    lines = [f"Study {study.id}{name}: {study.status}, {study_counts(study)}"]
    keys = list(study.spec.get("grid") or {})
    rows = []
    for point in study.points:
        for i, metric in enumerate(study.metrics):
            found = point.metrics[metric]
            where = [grid_text(point.values[k]) if i == 0 else "" for k in keys]
            rows.append(
                (
                    *where,
                    metric,
                    str(found.n),
                    _figure(found.mean),
                    _interval(found.ci_low, found.ci_high),
                )
            )
    columns = (*keys, "metric", "n", "mean", "95% CI")
    right = (*(False for _ in keys), False, True, True, True)
    lines += ["", *text_table(columns, rows, align_right=right)]
    if study.interval:
        lines += textwrap.wrap(f"Intervals: {study.interval}", WIDTH)
    if study.comparisons:
        compared = study.spec.get("compare")
        others = [k for k in keys if k != compared]
        rows = []
        for comparison in study.comparisons:
            for i, metric in enumerate(study.metrics):
                diff = comparison.metrics[metric]
                where = [grid_text(comparison.values[k]) if i == 0 else "" for k in others]
                pair = (
                    f"{grid_text(comparison.method)} - {grid_text(comparison.baseline)}"
                    if i == 0
                    else ""
                )
                rows.append(
                    (
                        *where,
                        pair,
                        metric,
                        str(diff.n),
                        _figure(diff.mean_difference),
                        _interval(diff.ci_low, diff.ci_high),
                        _p(diff.p_value),
                        _p(diff.p_holm),
                        _figure(diff.resolvable),
                    )
                )
        columns = (
            *others, str(compared), "metric", "n", "mean diff", "95% CI", "p", "p Holm", "resolves"
        )  # fmt: skip
        right = (*(False for _ in others), False, False, True, True, True, True, True, True)
        lines += ["", f"Paired differences, seed by seed ({compared}):"]
        lines += text_table(columns, rows, align_right=right)
        if study.test:
            lines += textwrap.wrap(f"p-values: {study.test}", WIDTH)
        if study.adjustment:
            lines += textwrap.wrap(f"Adjusted: {study.adjustment}", WIDTH)
        if study.resolution:
            lines += textwrap.wrap(f"resolves: {study.resolution}", WIDTH)
    if study.jobs.failed:
        lines += ["", f"{plural(study.jobs.failed, 'failed job')} left out of the means"]
    return "\n".join(lines)


# ---------------------------------------------------------------- jobs


def _when(moment: datetime) -> str:
    local = moment.astimezone() if moment.tzinfo is not None else moment
    return local.strftime("%Y-%m-%d %H:%M:%S")


def format_jobs(jobs: Sequence[Job]) -> str:
    """A line per job: id, status, progress, policy, robots, seed, study and when it came
    (local time)."""
    rows = []
    for job in jobs:
        robots = job.scenario.get("robots") or {}
        rows.append(
            (
                str(job.id),
                job.status,
                f"{100 * job.progress:.0f}%",
                _decided_by(job.scenario),
                str(robots.get("count", "")),
                str(job.scenario.get("seed", "")),
                "-" if job.study_id is None else str(job.study_id),
                _when(job.created_at),
            )
        )
    columns = ("id", "status", "progress", "policy", "robots", "seed", "study", "created")
    right = (True, False, True, False, True, True, True, False)
    return "\n".join(text_table(columns, rows, align_right=right))


def format_policies(policies: Sequence[Policy]) -> str:
    """A line per policy: id, what a scenario names it by, its name, the action set and
    communication models it is for, its shape and when it came (local time)."""
    rows = [
        (
            str(policy.id),
            policy.policy_from,
            policy.name or "-",
            policy.action_set,
            ",".join(policy.communication),
            f"network {policy.state_count}->{policy.action_count}"
            if policy.kind == "network"
            else f"{policy.state_count}x{policy.action_count}"
            + (f" x{policy.table_count} robots" if policy.per_robot else ""),
            _when(policy.created_at),
        )
        for policy in policies
    ]
    columns = ("id", "policy_from", "name", "actions", "communication", "policy", "created")
    right = (True, False, False, False, False, False, False)
    return "\n".join(text_table(columns, rows, align_right=right))
