"""A job as the API answers it: its progress, links, callback and pages of jobs."""

from __future__ import annotations

from collections.abc import Mapping
from datetime import datetime
from typing import Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
)

from nanonav.pictures import job as job_pictures
from nanonav.scenario import TRAINING_DECISIONS
from nanonav.status import Status
from nanonav.store import JobRecord, JobStatus, policy_name
from service.paging import CURSOR_PATTERN

PLOTS = ("trajectory", "concentration", "learning", "qtable", "treatment")
PLANES = ("xy", "xz", "yz", "all")


def plot_link(base: str, name: str) -> str:
    """Where a job's picture is: with ``?v=`` its drawing's version once it has been drawn anew,
    so that no cache keeps a copy of the older drawing."""
    version = job_pictures.version(name)
    return f"{base}/plots/{name}.png" + ("" if version == 1 else f"?v={version}")


JOB_EXAMPLE: dict[str, Any] = {
    "id": 42,
    "status": "running",
    "progress": {"episode": 3, "episodes": 11, "fraction": 0.31},
    "scenario": {"preset": None, "seed": 0, "robots": {"count": 1}, "...": "..."},
    "created_at": "2026-11-22T04:00:00Z",
    "started_at": "2026-11-22T04:00:01Z",
    "finished_at": None,
    "error": None,
    "attempts": 1,
    "cancel_requested": False,
    "links": {
        "self": "/jobs/42",
        "cancel": "/jobs/42/cancel",
        "metrics": "/jobs/42/metrics",
        "trajectory": "/jobs/42/trajectory",
        "qtable": "/jobs/42/qtable",
        "heatmap": "/jobs/42/heatmap.png",
        "plots": {name: plot_link("/jobs/42", name) for name in PLOTS if name != "treatment"},
    },
}


class TrainingRow(BaseModel):
    """A row of a network's training curve: the training episodes that ended since the row
    before (their actions sampled, as the trainer takes them)."""

    decisions: int = Field(description="Decisions trained when the row was closed.")
    episodes: int = Field(description="Training episodes that ended since the row before.")
    success_rate: float | None = Field(
        description="The share of them whose robot reached a cell (null: none ended)."
    )
    return_: float | None = Field(
        alias="return", description="Their mean return (null: none ended)."
    )

    model_config = ConfigDict(populate_by_name=True, serialize_by_alias=True)


class Progress(BaseModel):
    """How far the run is: it trains its episodes, then plays its evaluation worlds, and both
    count as episodes here."""

    episode: int = Field(
        description="Episodes finished so far: training episodes, then evaluation worlds."
    )
    episodes: int = Field(
        description="Episodes the run has in all: training_episodes + evaluation_worlds."
    )
    training_episodes: int = Field(0, description="Of them, the training episodes.")
    evaluation_worlds: int = Field(0, description="Of them, the greedy evaluation worlds.")
    fraction: float = Field(ge=0.0, le=1.0, description="Share of the run's work done.")
    decisions: int | None = Field(
        None,
        description="A network the job trains (robots.policy ppo, recurrent_ppo): the "
        "decisions trained so far (written every few seconds and at each checkpoint); null "
        "for other policies.",
    )
    training_decisions: int | None = Field(
        None, description="Of a network the job trains, the decisions it trains for in all."
    )
    training_curve: list[TrainingRow] | None = Field(
        None,
        description="Of a network the job trains, its training curve so far: a row about "
        "every twentieth of its decisions, written as it trains (the metrics' training_curve "
        "once it has ended); null for other policies.",
    )


def training_decisions(scenario: Mapping[str, Any]) -> int:
    """The decisions a stored scenario's network trains for (learning.decisions, or the
    default where it gave none)."""
    given = (scenario.get("learning") or {}).get("decisions")
    return int(given) if given is not None else TRAINING_DECISIONS


def offers_qtable(job: JobRecord) -> bool:
    """Whether the job has a Q-table to offer: the store keeps one (a fixed rule's run and a
    network's have none), and it holds what was learned or evaluated: the run trained for some
    episodes, or evaluated a table (policy_from). An untrained learner's table is all zeros."""
    trained = int((job.scenario.get("learning") or {}).get("episodes", 0)) > 0
    return job.has_qtable and (trained or job.scenario.get("policy_from") is not None)


class JobLinks(BaseModel):
    """Where the job's results are, as far as it has them: null (and no picture) until it
    succeeds; a cancelled job that had started keeps its metrics, Q-table and their pictures."""

    model_config = ConfigDict(populate_by_name=True)

    self_: str = Field(alias="self")
    cancel: str
    metrics: str | None
    trajectory: str | None
    qtable: str | None
    heatmap: str | None
    plots: dict[str, str]
    study: str | None = Field(None, description="The study the job belongs to, if any.")
    trained_policy: str | None = Field(
        None, description="The network the job trained, kept as a policy, once it succeeded."
    )


class Callback(BaseModel):
    """The webhook a job or study sends when it ends, and how sending it went."""

    id: int = Field(description="Also sent as the NanoNav-Delivery header and the body's id.")
    url: str
    state: Literal["waiting", "due", "delivered", "failed"] = Field(
        description="waiting: it has not ended; due: to be sent (again) at next_attempt_at; "
        "delivered: the receiver answered 2xx; failed: given up after its attempts."
    )
    event: str | None = Field(
        description="job.succeeded, job.failed, job.cancelled or study.<its status>; null "
        "while waiting."
    )
    attempts: int
    created_at: datetime
    next_attempt_at: datetime | None
    last_attempt_at: datetime | None
    delivered_at: datetime | None
    last_status: int | None = Field(description="The receiver's HTTP status at the last try.")
    last_error: str | None = Field(description="Why the last try failed.")


class Job(BaseModel):
    """A job: its scenario as it will run, where it is, and where its results are."""

    model_config = ConfigDict(json_schema_extra={"examples": [JOB_EXAMPLE]})

    id: int
    status: Status
    progress: Progress
    scenario: dict[str, Any] = Field(
        description="The scenario fully resolved: preset applied, defaults filled, seed included."
    )
    created_at: datetime
    started_at: datetime | None
    finished_at: datetime | None
    error: str | None = Field(description="Why a failed job failed, in words.")
    attempts: int = Field(description="How many times a worker claimed the job.")
    cancel_requested: bool
    study_id: int | None = Field(None, description="The study the job is part of.")
    trained_policy: str | None = Field(
        None,
        description="Once a job that trains a network (robots.policy ppo, recurrent_ppo) "
        "succeeded, the policy its network was kept as, 'policy-<id>', owned by the job's "
        "key: another job or a study evaluates it as policy_from (with robots.policy "
        "q_learning and learning.episodes 0).",
    )
    resumed_from_decisions: int | None = Field(
        None,
        description="A job that trains, taken up by another worker after its first died: the "
        "decisions of the checkpoint it resumed from (the work after it was lost).",
    )
    waiting_for: str | None = Field(
        None,
        description="A queued job that no running worker can take, what it waits for (a job "
        "that trains a network waits for a worker that trains, `nanonav worker --train`); "
        "null otherwise.",
    )
    links: JobLinks

    @classmethod
    def of(cls, job: JobRecord, *, waiting_for: str | None = None) -> Job:
        base = f"/jobs/{job.id}"
        done = job.status is JobStatus.SUCCEEDED
        # a job cancelled while it ran keeps the episodes it finished
        kept = job.status is JobStatus.CANCELLED and job.started_at is not None
        table = offers_qtable(job)
        swarm = job_pictures.treatment_drawn(job.scenario)
        trained = job.trained_policy_id if done else None
        return cls(
            id=job.id,
            status=job.status.value,
            progress=Progress(
                episode=job.episode,
                episodes=job.episodes,
                training_episodes=int((job.scenario.get("learning") or {}).get("episodes", 0)),
                evaluation_worlds=int((job.scenario.get("evaluation") or {}).get("worlds", 0)),
                fraction=job.fraction,
                decisions=job.decisions if job.trains else None,
                training_decisions=training_decisions(job.scenario) if job.trains else None,
                training_curve=job.training_curve if job.trains else None,
            ),
            scenario=job.scenario,
            created_at=job.created_at,
            started_at=job.started_at,
            finished_at=job.finished_at,
            error=job.error,
            attempts=job.attempts,
            cancel_requested=job.cancel_requested,
            study_id=job.study_id,
            trained_policy=None if trained is None else policy_name(trained),
            resumed_from_decisions=job.resumed_from_decisions,
            waiting_for=waiting_for,
            links=JobLinks(
                self_=base,
                cancel=f"{base}/cancel",
                metrics=f"{base}/metrics" if done or kept else None,
                trajectory=f"{base}/trajectory" if done else None,
                qtable=f"{base}/qtable" if (done or kept) and table else None,
                heatmap=f"{base}/heatmap.png" if done else None,
                plots={
                    name: plot_link(base, name)
                    for name in PLOTS
                    if (done or (kept and name in ("learning", "qtable")))
                    and (table or name != "qtable")
                    and (swarm or name != "treatment")
                },
                study=None if job.study_id is None else f"/studies/{job.study_id}",
                trained_policy=None if trained is None else f"/policies/{trained}",
            ),
        )


class JobPage(BaseModel):
    """A page of jobs, newest first."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {"jobs": [JOB_EXAMPLE], "next_cursor": "1e", "next": "/jobs?limit=20&cursor=1e"}
            ]
        }
    )

    jobs: list[Job]
    next_cursor: str | None = Field(
        pattern=CURSOR_PATTERN, description="Pass as ?cursor= for the next page; null at the end."
    )
    next: str | None = Field(description="The next page's URL, or null.")
