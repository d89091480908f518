"""The swarm's numbers in a study: reported, tabled and exported once a job has them, never as
empty columns for a study of the paper's scenarios; proportions kept to [0, 1]."""

from __future__ import annotations

import csv
import io
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from nanonav import stats
from nanonav.engine.metrics import SWARM
from nanonav.studies.export import to_csv, to_parquet
from nanonav.studies.report import (
    METRICS,
    PAPER_METRICS,
    SWARM_METRICS,
    WALL_CLOCK,
    WALL_CLOCK_COLUMN,
    JobOutcome,
    report,
    reported_metrics,
    study_metrics,
    table,
    table_columns,
)
from nanonav.studies.spec import StudySpec, point_values, points

SPEC = StudySpec.model_validate(
    {"grid": {"communication.model": ["none", "attractant"]}, "seeds": [1, 2, 3],
     "compare": "communication.model"}
)  # fmt: skip
# What a job of the paper's scenarios keeps, and what a swarm's with cells.capacity adds.
PAPER = dict.fromkeys(PAPER_METRICS, 1.0)
TREATED = [0.25, 0.9, 0.95]


def swarm_numbers(seed: int) -> dict[str, Any]:
    treated = TREATED[seed - 1]
    return {"robots_per_cell": 2.0 + seed, "most_robots_on_a_cell": 3.0, "bumps": 10.0 * seed,
            "cells_treated": 20 * treated, "treated_fraction": treated,
            "time_to_treat_all": 400.0 - seed, "never_delivered": 0.5 + 0.1 * seed}  # fmt: skip


def paper_jobs() -> list[JobOutcome]:
    return [
        JobOutcome(point * 3 + seed, point, seed, "succeeded", dict(PAPER))
        for point in (0, 1)
        for seed in (1, 2, 3)
    ]


def swarm_jobs() -> list[JobOutcome]:
    return [
        JobOutcome(point * 3 + seed, point, seed, "succeeded", PAPER | swarm_numbers(seed))
        for point in (0, 1)
        for seed in (1, 2, 3)
    ]


def test_the_swarms_numbers_are_among_the_metrics_a_study_can_read() -> None:
    assert SWARM_METRICS == SWARM and METRICS == PAPER_METRICS + SWARM


def test_a_study_of_the_papers_scenarios_has_no_swarm_column_statistic_or_comparison() -> None:
    jobs = paper_jobs()
    found = report(SPEC, point_values(SPEC), jobs)
    assert found["metrics"] == list(PAPER_METRICS)
    assert all(set(point["metrics"]) == set(PAPER_METRICS) for point in found["points"])
    assert all(set(c["metrics"]) == set(PAPER_METRICS) for c in found["comparisons"])
    columns = table_columns(SPEC, jobs)
    assert not set(columns) & set(SWARM)
    rows = table(point_values(SPEC), jobs)
    assert not set(rows[0]) & set(SWARM)
    header = next(csv.reader(io.StringIO(to_csv(columns, rows))))
    assert header == columns
    assert pq.read_table(io.BytesIO(to_parquet(columns, rows))).column_names == columns


def test_a_study_whose_jobs_have_them_reports_tables_and_exports_them() -> None:
    jobs = swarm_jobs()
    found = report(SPEC, point_values(SPEC), jobs)
    assert found["metrics"] == list(METRICS)
    treated = found["points"][0]["metrics"]["treated_fraction"]
    assert treated["n"] == 3 and treated["mean"] == pytest.approx(sum(TREATED) / 3)
    (comparison,) = found["comparisons"]
    assert comparison["metrics"]["bumps"]["n"] == 3
    assert comparison["metrics"]["bumps"]["mean_difference"] == pytest.approx(0.0)
    columns = table_columns(SPEC, jobs)
    assert columns[-len(METRICS) - 1 :] == [*METRICS, WALL_CLOCK_COLUMN]
    rows = table(point_values(SPEC), jobs)
    parquet = pq.read_table(io.BytesIO(to_parquet(columns, rows)))
    for key in SWARM:
        assert parquet.schema.field(key).type == pa.float64(), key
    assert parquet.column("treated_fraction").to_pylist()[:3] == TREATED
    exported = list(csv.DictReader(io.StringIO(to_csv(columns, rows))))
    assert exported[1]["time_to_treat_all"] == "398.0"


def test_a_metric_shows_once_any_job_that_succeeded_has_it() -> None:
    # exclusion alone: the contact numbers, none of the treatment's
    contacts = {"robots_per_cell": 1.5, "most_robots_on_a_cell": 2.0, "bumps": 4.0}
    jobs = [
        JobOutcome(1, 0, 1, "succeeded", dict(PAPER)),
        JobOutcome(2, 1, 1, "succeeded", PAPER | contacts),
        JobOutcome(3, 1, 2, "failed", None),
        JobOutcome(4, 1, 3, "queued", None),
    ]
    assert reported_metrics(jobs) == (*PAPER_METRICS, *contacts)
    assert reported_metrics(jobs[:1]) == PAPER_METRICS
    assert reported_metrics([]) == PAPER_METRICS  # a study yet to finish a job: the paper's
    rows = table(point_values(SPEC), jobs)
    assert rows[0]["bumps"] is None and rows[1]["bumps"] == 4.0
    assert "treated_fraction" not in rows[1]


def test_treated_and_undelivered_shares_are_proportions_with_intervals_in_0_1() -> None:
    jobs = [
        JobOutcome(seed, 0, seed, "succeeded", PAPER | swarm_numbers(seed) | {"success_rate": t})
        for seed, t in zip((1, 2, 3), TREATED, strict=True)
    ]
    point = report(SPEC, point_values(SPEC), jobs)["points"][0]["metrics"]
    treated, success = point["treated_fraction"], point["success_rate"]
    assert 0.0 <= treated["ci_low"] <= treated["mean"] <= treated["ci_high"] <= 1.0
    # shares of trials: the seeds' cells x worlds and robots x worlds, pooled
    scenario = points(SPEC)[0].scenario
    cells = scenario.cells.count * scenario.evaluation.worlds
    robots = scenario.robots.count * scenario.evaluation.worlds
    assert treated == stats.describe_share(TREATED, [cells] * 3).to_dict()
    assert success == stats.describe_share(TREATED, [robots] * 3).to_dict()
    assert treated["method"] == success["method"] == "pooled_wilson"
    undelivered = point["never_delivered"]
    assert undelivered["method"] == "pooled_wilson"
    assert 0.0 <= undelivered["ci_low"] < undelivered["ci_high"] <= 1.0
    assert point["time_to_treat_all"]["method"] == "log_t"  # steps: never negative


def test_a_job_keeps_the_swarms_numbers_only_when_its_run_reports_them() -> None:
    paper = study_metrics({"summary": {"total_steps": 7.0, "robots": 3}})
    assert set(paper) == {*PAPER_METRICS, WALL_CLOCK}
    swarm = study_metrics({"summary": {"total_steps": 7.0, **swarm_numbers(1)}})
    assert set(swarm) == {*METRICS, WALL_CLOCK} and swarm["treated_fraction"] == TREATED[0]
