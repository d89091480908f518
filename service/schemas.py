"""What the API answers with: response models, each with an example for the OpenAPI page; and
the body of ``POST /policies`` (a scenario's and a study's are the library's own schemas)."""

from __future__ import annotations

from collections.abc import Mapping
from datetime import datetime
from typing import Annotated, Any, Literal

from pydantic import (
    Base64Bytes,
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    ValidatorFunctionWrapHandler,
    field_validator,
)
from pydantic_core import ErrorDetails, PydanticCustomError

from nanonav.engine import qlearning
from nanonav.engine.observations import OBSERVATION_LABELS
from nanonav.pictures import job as job_pictures
from nanonav.policy import MAX_ACTIONS, MAX_Q, MAX_STATES, MAX_TABLES, UNVISITED
from nanonav.scenario import TRAINING_DECISIONS, ActionSet, CommunicationModel
from nanonav.status import Status
from nanonav.store import JobRecord, JobStatus, PolicyRecord, policy_name
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


METRICS_SUMMARY_EXAMPLE: dict[str, Any] = {
    "total_steps": 46.0,
    "mean_steps_to_reach": 48.1,
    "episode_steps": 84.3,
    "success_rate": 1.0,
    "final_distance": 0.30,
    "final_distance_reached": 0.30,
    "final_distance_unreached": None,
    "average_distance": 11.7,
    "average_concentration": 0.65,
    "collisions": 0.1,
    "path_efficiency": 0.97,
    "mean_return": 28.3,
    "duration_s": 0.0004,
    "robots": 15,
    "reached": 300,
    "worlds": 20,
}


class Metrics(BaseModel):
    """The metrics document of a finished run (the engine's ``SimulationResult.to_dict()``)."""

    model_config = ConfigDict(
        extra="allow",
        json_schema_extra={
            "examples": [
                {
                    "scenario": {"seed": 0, "...": "..."},
                    "completed": True,
                    "summary": METRICS_SUMMARY_EXAMPLE,
                    "uncertainty": {
                        "success_rate": {"n": 20, "sd": 0.0, "ci_low": 1.0, "ci_high": 1.0},
                        "total_steps": {"n": 20, "sd": 12.3, "ci_low": 40.2, "ci_high": 51.7},
                    },
                    "worlds": [METRICS_SUMMARY_EXAMPLE | {"worlds": None}],
                    "robots": [
                        {
                            "robot": 0,
                            "reached": True,
                            "total_steps": 44,
                            "steps_to_reach": 44,
                            "final_distance": 0.4,
                            "average_distance": 9.8,
                            "average_concentration": 0.41,
                            "duration_s": 0.0001,
                            "collisions": 0,
                            "path_length": 22.0,
                            "path_efficiency": 0.97,
                            "return": 27.1,
                        }
                    ],
                    "episodes": [
                        {
                            "episode": 0,
                            "steps": 640,
                            "success_rate": 1.0,
                            "mean_return": 30.6,
                            "epsilon": 1.0,
                            "collisions": 3,
                        }
                    ],
                    "work": {"robot_steps": 40440, "engine_s": 0.038},
                }
            ]
        },
    )

    scenario: dict[str, Any]
    completed: bool
    summary: dict[str, Any] = Field(
        description="Table 1 for the swarm, each number the mean over the evaluation worlds: "
        "total_steps (median over robots of the steps to reach, a failure counting max_steps), "
        "mean_steps_to_reach (robots that reached), episode_steps, success_rate, "
        "final_distance (all robots) and final_distance_reached / _unreached, "
        "average_distance, average_concentration, collisions, path_efficiency, mean_return, "
        "duration_s; robots, reached (over all worlds), worlds."
    )
    uncertainty: dict[str, Any] = Field(
        default_factory=dict,
        description="Per summary number: n (worlds where it exists), sd and the 95% interval of "
        "its mean over the evaluation worlds, kept to the number's range, and the method that "
        "made it: 'pooled_wilson' (a share of trials, success_rate and never_delivered of "
        "robots, treated_fraction of cells: Wilson on the worlds' trials pooled, as many as the "
        "spread between worlds allows), 'wilson' (0/1 outcomes), 'logit_t' (other values in "
        "[0, 1]), 'log_t' (values that cannot be negative) or 'student_t'.",
    )
    worlds: list[dict[str, Any]] = Field(
        default_factory=list, description="Every evaluation world's own summary."
    )
    robots: list[dict[str, Any]] = Field(
        description="Per robot, in the first (recorded) evaluation world."
    )
    episodes: list[dict[str, Any]] = Field(description="The learning curve, per training episode.")
    work: dict[str, Any]


class Trajectory(BaseModel):
    """The evaluation episode, every ``stride``-th step (the last step is always included)."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "stride": 10,
                    "length": 20,
                    "step": [0, 10, 20],
                    "robots": [[[1.0, 2.0, 3.0]], [[1.5, 2.0, 3.0]], [[2.0, 2.0, 3.0]]],
                    "cells": [[[5.0, 5.0, 5.0]], [[5.1, 5.0, 5.0]], [[5.1, 4.9, 5.0]]],
                    "obstacles": [[[0.0, 0.0, 0.0]], [[0.0, 0.0, 0.0]], [[0.0, 0.0, 0.0]]],
                    "obstacle_radius": 1.5,
                    "concentration": [[0.2], [0.3], [0.5]],
                    "distance": [[6.0], [4.0], [3.2]],
                    "reached": [False],
                    "robot_steps": [20],
                }
            ]
        }
    )

    stride: int
    length: int = Field(description="Steps the episode lasted (T).")
    step: list[int] = Field(description="The step number of every row below.")
    robots: list[list[list[float]]] = Field(description="[row][robot][x, y, z]")
    cells: list[list[list[float]]] = Field(description="[row][cell][x, y, z]")
    obstacles: list[list[list[float]]] = Field(
        description="[row][obstacle][x, y, z]; a single row when the obstacles do not move"
    )
    obstacle_radius: float
    concentration: list[list[float]] = Field(
        description="[row][robot] true biomarker concentration at the robot"
    )
    distance: list[list[float]] = Field(description="[row][robot] distance to nearest cell")
    reached: list[bool] = Field(description="[robot] whether it reached a cell")
    robot_steps: list[int] = Field(description="[robot] steps it was active")
    headings: list[list[list[float]]] | None = Field(
        None,
        description="[row][robot][x, y, z] the robot's unit heading (physics.model "
        "active_brownian only; null otherwise)",
    )
    sensed: list[list[float]] | None = Field(
        None,
        description="[row][robot] the reading the robot took, with its Berg-Purcell noise, "
        "beside the true concentration (active_brownian only; null otherwise)",
    )
    cell_loads: list[list[int]] | None = Field(
        None,
        description="[row][cell] payloads the cell had received (null for results stored "
        "before they were recorded)",
    )
    delivered_to: list[int] | None = Field(
        None, description="[robot] the cell it delivered its payload to, -1 if none"
    )
    signals: list[list[float]] | None = Field(
        None,
        description="[row][robot] the net signal (attractant minus repellent; broadcast: 1 "
        "while a message waits) the robot read (communication.model other than none only)",
    )


class GreedyState(BaseModel):
    """What a greedy robot does in one state."""

    state: str
    action: str = Field(
        description="The label of the action with the largest Q, the first if several tie; "
        "'unvisited' for a state never visited whose row is all zeros (no action is preferred)."
    )
    value: float | None = Field(description="The largest Q of the state; null when unvisited.")
    visits: int = Field(description="Times any action was chosen in this state, in this run.")
    learned: bool = Field(
        description="false for a state never visited with nothing learned; a table evaluated "
        "from another job (policy_from) is learned where that job learned, visited or not."
    )
    ties: list[str] = Field(
        description="Every action sharing the largest Q when there are several (a greedy robot "
        "picks among them at random); empty otherwise."
    )
    gap: float | None = Field(
        None,
        description="The action gap: the largest Q minus the next largest (0 when actions tie); "
        "null when unvisited. A small gap is a choice the learner barely prefers.",
    )


class QTable(BaseModel):
    """The learned Q-table: ``values[state][action]`` (or ``[robot][state][action]``), and the
    greedy policy read from it."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "states": [
                        "conc=low|trend=rising|obstacle=none|cell=none",
                        "conc=high|trend=falling|obstacle=near|cell=near",
                        "conc=high|trend=falling|obstacle=near|cell=sensed",
                    ],
                    "actions": ["follow_gradient", "approach_cell", "avoid_obstacle", "explore"],
                    "values": [[0.1, 0.0, -0.2, 0.05], [1.2, 3.4, 0.0, 0.1], [0.0, 0.0, 0.0, 0.0]],
                    "visits": [[10, 2, 1, 4], [3, 9, 0, 1], [0, 0, 0, 0]],
                    "greedy": [
                        {
                            "state": "conc=low|trend=rising|obstacle=none|cell=none",
                            "action": "follow_gradient",
                            "value": 0.1,
                            "visits": 17,
                            "learned": True,
                            "ties": [],
                            "gap": 0.05,
                        },
                        {
                            "state": "conc=high|trend=falling|obstacle=near|cell=near",
                            "action": "approach_cell",
                            "value": 3.4,
                            "visits": 13,
                            "learned": True,
                            "ties": [],
                            "gap": 2.2,
                        },
                        {
                            "state": "conc=high|trend=falling|obstacle=near|cell=sensed",
                            "action": "unvisited",
                            "value": None,
                            "visits": 0,
                            "learned": False,
                            "ties": [],
                            "gap": None,
                        },
                    ],
                }
            ]
        }
    )

    states: list[str]
    actions: list[str]
    values: list[Any] = Field(
        description="[state][action] for a table the swarm shares, [robot][state][action] when "
        "every robot learns its own."
    )
    visits: list[Any] = Field(description="How often each action was chosen, shaped as values.")
    greedy: list[GreedyState] = Field(
        description="A row per state: its greedy action. For per-robot tables, the greedy "
        "table of their mean over robots, each state-action pair weighted by the robots' visits "
        "(a pair no robot chose: the plain mean). Empty for a job without a Q-table."
    )


class Queue(BaseModel):
    queued: int = Field(description="Jobs waiting for a worker.")
    running: int = Field(description="Jobs a worker holds.")
    oldest_queued_at: datetime | None = Field(description="When the longest-waiting job came.")


class Workers(BaseModel):
    seen: int = Field(
        description="Worker processes that said they were alive lately, ready to take jobs."
    )
    preparing: int = Field(
        0,
        description="Worker processes alive lately that still prepare the engine before they "
        "take a job: on a first start a worker compiles it, which takes about a minute.",
    )
    window_s: float = Field(description="How far back 'lately' reaches, in seconds.")


class Webhooks(BaseModel):
    due: int = Field(
        description="Webhooks to send now: their next try's time has come, or their job or "
        "study has ended."
    )
    retrying: int = Field(description="Webhooks due again once a failed try's backoff passed.")
    oldest_due_at: datetime | None = Field(
        description="Since when the longest-waiting of the due ones could have been sent."
    )
    overdue_s: float | None = Field(description="How long ago that was, in seconds.")
    last_pass_at: datetime | None = Field(
        description="When a worker's webhook sender last made progress (a pass or a try)."
    )
    window_s: float = Field(
        description="A sender that made progress this many seconds ago or less counts as "
        "sending: the presence window and one try's timeouts (3 x NANONAV_WEBHOOK_TIMEOUT_S)."
    )


class Health(BaseModel):
    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "status": "ok",
                    "database": True,
                    "revision": "0002",
                    "head": "0002",
                    "queue": {"queued": 3, "running": 2, "oldest_queued_at": "2026-11-30T04:00Z"},
                    "workers": {"seen": 2, "window_s": 30.0},
                    "webhooks": {
                        "due": 1,
                        "retrying": 0,
                        "oldest_due_at": "2026-11-30T04:00Z",
                        "overdue_s": 0.4,
                        "last_pass_at": "2026-11-30T04:00Z",
                        "window_s": 60.0,
                    },
                    "note": None,
                }
            ]
        }
    )

    status: Literal["ok", "unavailable"]
    database: bool = Field(description="Whether the database answered.")
    revision: str | None = Field(description="The database's migration revision.")
    head: str | None = Field(description="The newest migration this code knows.")
    queue: Queue | None = Field(None, description="The queue, when the database answered.")
    workers: Workers | None = Field(None, description="Workers seen, when the database answered.")
    webhooks: Webhooks | None = Field(
        None, description="Webhooks to send and their senders, when the database answered."
    )
    note: str | None = Field(
        None,
        description="Why queued jobs or due webhooks may not be moving, e.g. that no worker "
        "is running, or that none has sent webhooks lately (the status stays ok: jobs run).",
    )


class Version(BaseModel):
    model_config = ConfigDict(
        json_schema_extra={"examples": [{"name": "nanonav", "version": "0.1.0"}]}
    )

    name: str
    version: str


# ---------------------------------------------------------------- studies

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
MAX_LABEL = 200
Label = Annotated[str, Field(min_length=1, max_length=MAX_LABEL)]
Row = Annotated[list[float], Field(min_length=1, max_length=MAX_ACTIONS)]
Table = Annotated[list[Row], Field(min_length=1, max_length=MAX_STATES)]
Tables = Annotated[list[Table], Field(min_length=1, max_length=MAX_TABLES)]

_BEHAVIOR_STATES, _BEHAVIOR_ACTIONS = qlearning.labels("behaviors")
NEW_POLICY_EXAMPLES: dict[str, Any] = {
    "greedy": {
        "summary": "A greedy table: an action per state",
        "value": {
            "name": "distilled from PPO",
            "states": _BEHAVIOR_STATES,
            "actions": _BEHAVIOR_ACTIONS,
            "greedy": [
                {"state": state, "action": _BEHAVIOR_ACTIONS[i % 2]}
                for i, state in enumerate(_BEHAVIOR_STATES)
            ],
        },
    },
    "values": {
        "summary": "Action values: a row per state, a column per action",
        "value": {
            "states": _BEHAVIOR_STATES,
            "actions": _BEHAVIOR_ACTIONS,
            "values": [[0.5, 1.0, -0.25, 0.0] for _ in _BEHAVIOR_STATES],
        },
    },
}


class GreedyChoice(BaseModel):
    """A state and the action a greedy robot takes in it, as ``GET /jobs/{id}/qtable`` lists
    them in ``greedy``; its other keys (value, visits, learned, ties, gap) are ignored."""

    model_config = ConfigDict(extra="ignore", strict=True)

    state: Label
    action: Label = Field(
        description=f"An action label, or '{UNVISITED}': no action is preferred in this state."
    )


class NewPolicy(BaseModel):
    """A Q-table or a network made elsewhere (say, by training on NanoNav's Gymnasium or
    PettingZoo environments), for scenarios to evaluate.

    A table: ``states`` and ``actions`` are the labels of its rows and columns, in order:
    exactly those the engine has for one action set and communication model (an environment's
    ``state_labels`` and ``action_labels``). The table is ``values`` or ``greedy``, exactly
    one of them.

    A network: ``onnx``, an ONNX model in base64, that takes a float32 batch of observations
    (batch x the columns ``observation`` names, an environment's ``observation_labels``) and
    gives the logits of ``actions`` (batch x actions) or the action numbers (batch);
    ``observation`` and ``actions`` may be left out when the model's metadata names them
    (``nanonav train`` writes them)."""

    model_config = ConfigDict(
        extra="forbid",
        strict=True,
        json_schema_extra={"examples": [NEW_POLICY_EXAMPLES["greedy"]["value"]]},
    )

    name: str | None = Field(None, max_length=200, description="What to call it in lists.")
    states: list[Label] | None = Field(
        None,
        min_length=1,
        max_length=MAX_STATES,
        description="A table's: the state of each row, in order.",
    )
    actions: list[Label] | None = Field(
        None,
        min_length=1,
        max_length=MAX_ACTIONS,
        description="The action of each column of a table, or of each logit of a network, in "
        "order (for a network, the model's metadata may name them instead).",
    )
    observation: list[Label] | None = Field(
        None,
        min_length=1,
        max_length=len(OBSERVATION_LABELS),
        description="A network's: the observation column of each input, in order (an "
        "environment's observation_labels; the model's metadata may name them instead).",
    )
    onnx: Base64Bytes | None = Field(
        None,
        strict=False,  # base64 text decodes to the model's bytes
        description="A network: the ONNX model's bytes in base64 (at most "
        "NANONAV_POLICY_MODEL_MAX_BYTES decoded). It is checked before it is kept: one float32 "
        "input (batch x observation), a first output of logits (batch x actions) or actions "
        "(batch), the standard operator sets only, weights inside the model, no loops, every "
        "computed value of a fixed size per observation, and one trial run.",
    )
    values: Table | Tables | None = Field(
        None,
        description="Action values, [state][action] for a table every robot starts from, or "
        f"[robot][state][action] for one per robot (at most {MAX_TABLES}); finite numbers "
        f"within +-{MAX_Q:g}, far beyond what any job learns.",
    )
    greedy: list[GreedyChoice] | None = Field(
        None,
        max_length=MAX_STATES,
        description="Instead of values: the greedy action of each state, each state at most "
        "once; it becomes a table of 1.0 for that action and 0 for the others, a row of zeros "
        f"for a state left out or '{UNVISITED}'.",
    )

    @field_validator("values", mode="wrap")
    @classmethod
    def _a_table(cls, value: Any, handler: ValidatorFunctionWrapHandler) -> Any:
        """One error at ``values``: an error of each nesting it could have would point inside
        a schema's alternatives, not inside the body."""
        try:
            return handler(value)
        except ValidationError as error:
            # each error's location starts with its alternative: the one of the value's depth
            alternatives: dict[str | int, list[ErrorDetails]] = {}
            for found in error.errors(include_url=False):
                alternatives.setdefault(found["loc"][0], []).append(found)
            errors = list(alternatives.values())
            first = errors[-1 if _three_deep(value) else 0][0]
            where = "".join(f"[{part}]" for part in first["loc"][1:])
            raise PydanticCustomError(
                "table",
                "values must be a table of numbers, states x actions, or robots x states x "
                "actions: at values{where}, {reason}",
                {"where": where, "reason": first["msg"][:1].lower() + first["msg"][1:]},
            ) from None


def _three_deep(value: Any) -> bool:
    """Whether ``value`` starts as robots x states x actions would: a list of lists of lists."""
    for _ in range(3):
        if not isinstance(value, list) or not value:
            return False
        value = value[0]
    return True


class PolicyLinks(BaseModel):
    model_config = ConfigDict(populate_by_name=True)

    self_: str = Field(alias="self")


POLICY_EXAMPLE: dict[str, Any] = {
    "id": 3,
    "policy_from": "policy-3",
    "name": "distilled from PPO",
    "action_set": "behaviors",
    "communication": ["none"],
    "state_count": 72,
    "action_count": 4,
    "table_count": 1,
    "per_robot": False,
    "kind": "table",
    "created_at": "2026-12-03T10:00:00Z",
    "links": {"self": "/policies/3"},
}


class PolicySummary(BaseModel):
    """A policy as lists show it and ``POST /policies`` answers."""

    model_config = ConfigDict(json_schema_extra={"examples": [POLICY_EXAMPLE]})

    id: int
    policy_from: str = Field(description="What a scenario's policy_from names it by.")
    name: str | None
    action_set: ActionSet = Field(description="The learning.actions its table is for.")
    communication: list[CommunicationModel] = Field(
        description="The communication.model values whose states are its rows (the attractant "
        "models sense the same states; 'directions' is used without communication)."
    )
    state_count: int
    action_count: int
    table_count: int = Field(
        description="1 for a table every robot starts from; else one table per robot, and a "
        "scenario that evaluates it needs as many robots, each learning its own."
    )
    per_robot: bool = Field(description="Whether values is [robot][state][action].")
    kind: Literal["table", "network"] = Field(
        description="'table': a Q-table; 'network': an ONNX model (its state_count is the "
        "width of its observation)."
    )
    created_at: datetime
    links: PolicyLinks

    @classmethod
    def fields_of(cls, record: PolicyRecord) -> dict[str, Any]:
        return {
            "id": record.id,
            "policy_from": record.policy_from,
            "name": record.name,
            "action_set": record.action_set,
            "communication": list(record.communication),
            "state_count": record.states,
            "action_count": record.actions,
            "table_count": record.tables,
            "per_robot": record.per_robot,
            "kind": record.kind,
            "created_at": record.created_at,
            "links": PolicyLinks(self_=f"/policies/{record.id}"),
        }

    @classmethod
    def of(cls, record: PolicyRecord) -> PolicySummary:
        return cls(**cls.fields_of(record))


class Policy(PolicySummary):
    """A policy with its table (labels, values and the greedy action of every state), or a
    network with what it reads and chooses."""

    states: list[str] | None = Field(None, description="A table's rows.")
    actions: list[str]
    values: list[Any] | None = Field(
        None, description="A table's: [state][action], or [robot][state][action]."
    )
    greedy: list[GreedyState] | None = Field(
        None,
        description="A table's: a row per state, as GET /jobs/{id}/qtable gives it (visits are "
        "0: nothing was visited here); for per-robot tables, the greedy table of their plain "
        "mean.",
    )
    observation: list[str] | None = Field(
        None, description="A network's: the observation column of each input."
    )
    model_bytes: int | None = Field(None, description="A network's: its ONNX model's size.")
    memory: int | None = Field(
        None,
        description="A network's: the memory inputs it carries from decision to decision (a "
        "recurrent one's; 0 for none).",
    )
    multiply_adds: int | None = Field(
        None,
        description="A network's: the multiply-adds one observation costs, counted from its "
        "graph when it was sent (what a job's work budget charges for each decision).",
    )
    live_bytes: int | None = Field(
        None,
        description="A network's: the most memory its values hold at once for one "
        "observation, counted from its graph when it was sent.",
    )


class PolicyPage(BaseModel):
    """A page of policies, newest first."""

    policies: list[PolicySummary]
    next_cursor: str | None = Field(
        pattern=CURSOR_PATTERN, description="Pass as ?cursor= for the next page; null at the end."
    )
    next: str | None = Field(description="The next page's URL, or null.")
