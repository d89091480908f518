"""A study's report: failed jobs counted beside the statistics, never in them; pairs only on
seeds where both jobs succeeded; long learning curves are binned."""

from __future__ import annotations

import statistics
from collections import Counter
from typing import Any

import pytest

from nanonav import stats
from nanonav.studies.report import (
    METRICS,
    PAPER_METRICS,
    WALL_CLOCK,
    WALL_CLOCK_COLUMN,
    JobOutcome,
    learning_curve,
    report,
    status_of,
    study_metrics,
    table,
    table_columns,
)
from nanonav.studies.spec import StudySpec, point_values

SPEC = StudySpec.model_validate(
    {"grid": {"robots.policy": ["q_learning", "gradient"]}, "seeds": [1, 2, 3, 4],
     "compare": "robots.policy"}
)  # fmt: skip


def outcome(job_id: int, point: int, seed: int, steps: float | None, status: str = "succeeded"
            ) -> JobOutcome:  # fmt: skip
    if status != "succeeded":
        return JobOutcome(job_id, point, seed, status, None)
    metrics = {metric: 1.0 for metric in METRICS} | {"total_steps": steps}
    return JobOutcome(job_id, point, seed, status, metrics)


JOBS = [
    outcome(1, 0, 1, 100.0),
    outcome(2, 1, 1, 90.0),
    outcome(3, 0, 2, 120.0),
    outcome(4, 1, 2, None, status="failed"),
    outcome(5, 0, 3, 80.0),
    outcome(6, 1, 3, 60.0),
    outcome(7, 0, 4, None, status="cancelled"),
    outcome(8, 1, 4, 70.0),
]


def test_failed_and_cancelled_jobs_are_counted_not_averaged() -> None:
    found = report(SPEC, point_values(SPEC), JOBS)
    first, second = found["points"]
    assert first["jobs"] == {"queued": 0, "running": 0, "succeeded": 3, "failed": 0,
                             "cancelled": 1}  # fmt: skip
    assert second["jobs"]["failed"] == 1 and second["jobs"]["succeeded"] == 3
    assert first["metrics"]["total_steps"]["n"] == 3
    assert first["metrics"]["total_steps"]["mean"] == pytest.approx(100.0)
    assert second["metrics"]["total_steps"]["mean"] == pytest.approx(statistics.fmean([90, 60, 70]))


def test_differences_pair_only_seeds_where_both_succeeded() -> None:
    (comparison,) = report(SPEC, point_values(SPEC), JOBS)["comparisons"]
    assert (comparison["method"], comparison["baseline"], comparison["values"]) == (
        "gradient", "q_learning", {}
    )  # fmt: skip
    steps = comparison["metrics"]["total_steps"]
    assert steps["n"] == 2  # seeds 1 and 3: seed 2 failed on one side, seed 4 was cancelled
    assert steps["mean_difference"] == pytest.approx(statistics.fmean([90 - 100, 60 - 80]))


def test_each_metrics_p_values_are_adjusted_by_holm_over_its_comparisons() -> None:
    """Two methods against the baseline at two obstacle counts: four comparisons of each
    metric, adjusted together (Holm's step-down over the four raw p-values)."""
    spec = StudySpec.model_validate(
        {"grid": {"robots.policy": ["q_learning", "gradient", "random"],
                  "obstacles.count": [0, 10]},
         "seeds": list(range(1, 9)), "compare": "robots.policy"}
    )  # fmt: skip
    values = point_values(spec)
    shifts = {"q_learning": 0.0, "gradient": -3.0, "random": 0.4}
    jobs: list[JobOutcome] = []
    for point, point_value in enumerate(values):
        for seed in spec.seeds or []:
            steps = 100.0 + seed * (1 + point) % 7 + shifts[str(point_value["robots.policy"])]
            jobs.append(outcome(len(jobs) + 1, point, seed, steps * (1 + 0.01 * seed)))
    found = report(spec, values, jobs)
    family = [c["metrics"]["total_steps"] for c in found["comparisons"]]
    assert len(family) == 4
    raw = [d["p_value"] for d in family]
    assert [d["p_holm"] for d in family] == pytest.approx(stats.holm(raw))
    assert all(d["holm_comparisons"] == 4 for d in family)
    assert all(d["p_holm"] >= d["p_value"] for d in family)
    assert min(d["p_holm"] for d in family) == pytest.approx(min(1.0, 4 * min(raw)))
    assert "Holm" in found["adjustment"]
    assert "80 %" in found["resolution"]
    # and the smallest difference these 8 seeds would find, from each comparison's spread
    for difference in family:
        assert difference["resolvable"] == stats.resolvable_difference(difference["sd"], 8)
        assert difference["resolvable"] > 0
    # a metric no method moves: every raw p-value is 1, and so is every adjusted one
    assert [c["metrics"]["success_rate"]["p_holm"] for c in found["comparisons"]] == [1.0] * 4


def test_a_metric_a_job_lacks_is_left_out_of_its_sample() -> None:
    jobs = [outcome(1, 0, 1, None), outcome(2, 0, 2, 50.0)]
    found = report(SPEC, point_values(SPEC), jobs)
    assert found["points"][0]["metrics"]["total_steps"]["n"] == 1
    assert found["points"][0]["metrics"]["success_rate"]["n"] == 2


@pytest.mark.parametrize(
    ("counts", "cancelled", "expected"),
    [
        ({"queued": 4}, False, "queued"),
        ({"queued": 3, "succeeded": 1}, False, "running"),
        ({"running": 1, "succeeded": 3}, True, "running"),
        ({"succeeded": 4}, False, "succeeded"),
        ({"succeeded": 3, "failed": 1}, False, "failed"),
        ({"succeeded": 3, "cancelled": 1}, False, "cancelled"),
        ({"succeeded": 3, "failed": 1}, True, "cancelled"),
    ],
)
def test_a_studys_status_follows_its_jobs(
    counts: dict[str, int], cancelled: bool, expected: str
) -> None:
    assert status_of(Counter(counts), cancelled) == expected


def test_a_job_keeps_its_study_metrics_and_a_binned_learning_curve() -> None:
    episodes: list[dict[str, Any]] = [
        {"episode": e, "steps": e, "success_rate": e % 2, "mean_return": 2.0 * e}
        for e in range(1000)
    ]
    document = {"summary": {"total_steps": 7, "robots": 1}, "episodes": episodes}
    kept = study_metrics(document)
    assert kept["total_steps"] == 7 and "robots" not in kept
    assert set(kept) == {*PAPER_METRICS, WALL_CLOCK}  # the wall-clock time, for the export
    curve = learning_curve(document)
    assert len(curve["episode"]) == 200
    assert curve["episode"][0] == 2.0 and curve["steps"][0] == 2.0  # mean of episodes 0..4
    assert curve["success_rate"][0] == pytest.approx(0.4)
    assert curve["mean_return"][-1] == pytest.approx(2.0 * statistics.fmean(range(995, 1000)))
    short = learning_curve({"summary": {}, "episodes": episodes[:3]})
    assert short["steps"] == [0.0, 1.0, 2.0]


def test_the_table_has_a_row_per_job_with_empty_metrics_unless_it_succeeded() -> None:
    rows = table(point_values(SPEC), JOBS)
    assert [r["job_id"] for r in rows] == list(range(1, 9))
    assert rows[3] == {"job_id": 4, "seed": 2, "robots.policy": "gradient", "status": "failed",
                       **{m: None for m in METRICS}, WALL_CLOCK_COLUMN: None}  # fmt: skip
    assert rows[0]["total_steps"] == 100.0


def test_the_wall_clock_time_is_exported_but_never_summarised_drawn_or_compared() -> None:
    """How long a job took is the machine's, not the scenario's: no interval, chart or paired
    test of it, only a column of the export that says it is wall-clock time."""
    jobs = [
        JobOutcome(i + 1, point, seed, "succeeded", {"total_steps": 10.0, WALL_CLOCK: 0.5 + i})
        for i, (point, seed) in enumerate((p, s) for p in (0, 1) for s in (1, 2, 3, 4))
    ]
    found = report(SPEC, point_values(SPEC), jobs)
    assert WALL_CLOCK not in found["metrics"] and WALL_CLOCK not in METRICS
    assert all(WALL_CLOCK not in point["metrics"] for point in found["points"])
    assert all(WALL_CLOCK not in c["metrics"] for c in found["comparisons"])
    assert table_columns(SPEC, jobs)[-1] == WALL_CLOCK_COLUMN == "wall_clock_duration_s"
    assert [row[WALL_CLOCK_COLUMN] for row in table(point_values(SPEC), jobs)][:2] == [0.5, 1.5]
