"""A study as the API answers it: its counts, statistics, comparisons and links."""

from __future__ import annotations

from collections.abc import Mapping
from datetime import datetime
from typing import Any

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
)

from nanonav.status import Status
from service.paging import CURSOR_PATTERN

GridValue = bool | int | float | str | None


class JobCounts(BaseModel):
    total: int
    queued: int
    running: int
    succeeded: int
    failed: int = Field(description="Failed jobs are counted here, never averaged in.")
    cancelled: int

    @classmethod
    def of(cls, found: Mapping[str, int]) -> JobCounts:
        """From jobs per status (a status no job has may be absent)."""
        return cls(
            total=sum(found.values()),
            queued=found.get("queued", 0),
            running=found.get("running", 0),
            succeeded=found.get("succeeded", 0),
            failed=found.get("failed", 0),
            cancelled=found.get("cancelled", 0),
        )


class Interval(BaseModel):
    """A metric over a grid point's succeeded seeds."""

    n: int = Field(description="Succeeded jobs with a value for this metric.")
    mean: float | None = Field(
        description="The mean over those seeds; for a share of trials (success_rate, "
        "treated_fraction, never_delivered), the share of all their trials pooled."
    )
    sd: float | None = Field(description="Sample standard deviation (n - 1); null when n < 2.")
    ci_low: float | None = Field(
        description="95% interval of the mean, inside the metric's range (see method); the "
        "seeds are its independent units."
    )
    ci_high: float | None
    method: str = Field(
        "student_t",
        description="How the interval was made: 'pooled_wilson' (a share of trials: Wilson on "
        "the seeds' pooled trials, counted only as many as the spread between seeds allows), "
        "'student_t', 'wilson' (0/1 outcomes), 'logit_t' (other values in [0, 1]) or 'log_t' "
        "(values that cannot be negative); the study's 'interval' says each in words.",
    )


class Difference(BaseModel):
    """One method minus the baseline, over the seeds where both succeeded."""

    n: int = Field(description="Seeds paired.")
    mean_difference: float | None
    sd: float | None
    ci_low: float | None = Field(description="95% Student t interval of the mean difference.")
    ci_high: float | None
    p_value: float | None = Field(description="Wilcoxon signed-rank, two-sided; null when n < 2.")
    p_holm: float | None = Field(
        None,
        description="p_value adjusted by Holm's method over every comparison of this metric in "
        "the study (the study's 'adjustment' says how); null without a p_value.",
    )
    holm_comparisons: int | None = Field(
        None, description="How many comparisons of this metric p_holm adjusts over."
    )
    resolvable: float | None = Field(
        None,
        description="The smallest mean difference these seeds find with 80 % chance at "
        "two-sided 0.05, given the differences' spread (sd): a paired power calculation by "
        "the t-test. A smaller difference needs about n * (resolvable / difference)^2 seeds. "
        "Null with fewer than two seeds or no spread.",
    )
    method: str = Field("student_t", description="How the interval was made: Student t.")


class StudyPoint(BaseModel):
    index: int
    values: dict[str, GridValue] = Field(description="This point's value of every grid key.")
    jobs: dict[str, int] = Field(description="Its jobs per status.")
    metrics: dict[str, Interval]


class StudyComparison(BaseModel):
    values: dict[str, GridValue] = Field(description="The other grid keys' values.")
    method: GridValue = Field(description="The compared key's value measured...")
    baseline: GridValue = Field(description="...against this one, its first listed value.")
    metrics: dict[str, Difference]


class StudyLinks(BaseModel):
    model_config = ConfigDict(populate_by_name=True)

    self_: str = Field(alias="self")
    cancel: str
    jobs: str
    results_csv: str
    results_parquet: str
    comparisons_csv: str = Field(
        description="The paired comparisons as a table, a row per difference (add "
        "?format=parquet for Parquet); no rows unless the study compares."
    )
    plots: dict[str, str]


STUDY_STATUS_DOC = (
    "queued, running, then succeeded (every job succeeded), failed (a job failed) or cancelled"
)


class StudySummary(BaseModel):
    """A study as lists show it."""

    id: int
    name: str
    status: Status = Field(description=STUDY_STATUS_DOC)
    created_at: datetime
    cancel_requested: bool
    jobs: JobCounts
    links: StudyLinks


class Study(StudySummary):
    """A study, its jobs per status, and its statistics so far."""

    finished_at: datetime | None = Field(description="When its last job finished.")
    progress: float = Field(ge=0.0, le=1.0, description="Share of its jobs' work done.")
    spec: dict[str, Any] = Field(description="The study as submitted, seeds resolved.")
    interval: str = Field(description="How the confidence intervals are computed.")
    test: str = Field(description="How the paired p-values are computed.")
    adjustment: str = Field(
        "", description="How the p-values are adjusted for the study's many comparisons."
    )
    resolution: str = Field(
        "", description="What each paired difference's 'resolvable' is, and how it is found."
    )
    metrics: list[str]
    points: list[StudyPoint]
    comparisons: list[StudyComparison] = Field(
        description="With 'compare': each value of the compared key against the first, at every "
        "combination of the other keys, seed by seed."
    )


class StudyState(BaseModel):
    """A study as its event stream shows it: where it stands, without the statistics (which
    can be large) that `GET /studies/{id}` adds."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "id": 3,
                    "status": "running",
                    "jobs": {
                        "total": 60,
                        "queued": 20,
                        "running": 2,
                        "succeeded": 38,
                        "failed": 0,
                        "cancelled": 0,
                    },
                    "progress": 0.65,
                    "finished_at": None,
                }
            ]
        }
    )

    id: int
    status: Status = Field(description=STUDY_STATUS_DOC)
    jobs: JobCounts
    progress: float = Field(ge=0.0, le=1.0, description="Share of its jobs' work done.")
    finished_at: datetime | None = Field(description="When its last job finished, once done.")


class StudyPage(BaseModel):
    """A page of studies, newest first."""

    studies: list[StudySummary]
    next_cursor: str | None = Field(
        pattern=CURSOR_PATTERN, description="Pass as ?cursor= for the next page; null at the end."
    )
    next: str | None


# ---------------------------------------------------------------- policies

# The longest label a layout has is under 100 characters.
