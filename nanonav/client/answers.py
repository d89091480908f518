"""The client's answers: small frozen dataclasses with the fields a script needs and the
whole JSON answer in ``raw``."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import MISSING, Field, dataclass, field, fields
from datetime import datetime
from typing import Any, TypeVar, cast

from nanonav.status import FINISHED, Status

GridValue = bool | int | float | str | None


def _time(value: Any) -> datetime | None:
    return None if value is None else datetime.fromisoformat(str(value))


@dataclass(frozen=True, kw_only=True)
class Job:
    """A job as ``GET /jobs/{id}`` answers it."""

    id: int
    status: Status
    progress: float  # share of the run's work done, 0 to 1
    episode: int  # episodes finished: training episodes, then evaluation worlds
    episodes: int  # training_episodes + evaluation_worlds
    training_episodes: int = 0
    evaluation_worlds: int = 0
    error: str | None  # why it failed, in words
    study_id: int | None
    scenario: dict[str, Any]  # fully resolved: preset applied, defaults filled, seed included
    created_at: datetime
    started_at: datetime | None
    finished_at: datetime | None
    attempts: int
    cancel_requested: bool
    links: dict[str, Any]
    raw: dict[str, Any] = field(repr=False, compare=False)

    @classmethod
    def of(cls, data: dict[str, Any]) -> Job:
        progress = data["progress"]
        return cls(
            id=int(data["id"]),
            status=cast(Status, data["status"]),
            progress=float(progress["fraction"]),
            episode=int(progress["episode"]),
            episodes=int(progress["episodes"]),
            training_episodes=int(progress.get("training_episodes", 0)),
            evaluation_worlds=int(progress.get("evaluation_worlds", 0)),
            error=data.get("error"),
            study_id=data.get("study_id"),
            scenario=data["scenario"],
            created_at=datetime.fromisoformat(data["created_at"]),
            started_at=_time(data.get("started_at")),
            finished_at=_time(data.get("finished_at")),
            attempts=int(data.get("attempts", 0)),
            cancel_requested=bool(data.get("cancel_requested")),
            links=data.get("links") or {},
            raw=data,
        )

    @property
    def finished(self) -> bool:
        """Succeeded, failed or cancelled: its status will not change again."""
        return self.status in FINISHED


@dataclass(frozen=True, kw_only=True)
class JobCounts:
    """A study's jobs per status."""

    total: int
    queued: int
    running: int
    succeeded: int
    failed: int
    cancelled: int

    @property
    def finished(self) -> int:
        return self.succeeded + self.failed + self.cancelled


@dataclass(frozen=True, kw_only=True)
class Interval:
    """A metric over a grid point's succeeded seeds: mean and its 95% interval, kept to the
    metric's range; ``method`` names how (see the study's ``interval``)."""

    n: int
    mean: float | None
    sd: float | None
    ci_low: float | None
    ci_high: float | None
    method: str = "student_t"


@dataclass(frozen=True, kw_only=True)
class Difference:
    """One compared value minus the baseline, paired seed by seed."""

    n: int
    mean_difference: float | None
    sd: float | None
    ci_low: float | None
    ci_high: float | None
    p_value: float | None  # Wilcoxon signed-rank, two-sided
    method: str = "student_t"
    p_holm: float | None = None  # p_value adjusted by Holm's over the metric's comparisons
    holm_comparisons: int | None = None  # how many comparisons p_holm adjusts over
    resolvable: float | None = None  # the smallest difference these seeds find, 80 % power


@dataclass(frozen=True, kw_only=True)
class StudyPoint:
    index: int
    values: dict[str, GridValue]  # this point's value of every grid key
    jobs: dict[str, int]  # its jobs per status
    metrics: dict[str, Interval]


@dataclass(frozen=True, kw_only=True)
class Comparison:
    values: dict[str, GridValue]  # the other grid keys' values
    method: GridValue
    baseline: GridValue
    metrics: dict[str, Difference]


@dataclass(frozen=True, kw_only=True)
class StudySummary:
    """A study as ``GET /studies`` lists it."""

    id: int
    name: str
    status: Status
    created_at: datetime
    cancel_requested: bool
    jobs: JobCounts
    links: dict[str, Any]
    raw: dict[str, Any] = field(repr=False, compare=False)

    @classmethod
    def of(cls, data: dict[str, Any]) -> StudySummary:
        return cls(**_summary_fields(data))

    @property
    def finished(self) -> bool:
        """Every job has finished: the statistics will not change again."""
        return self.status in FINISHED


@dataclass(frozen=True, kw_only=True)
class Study(StudySummary):
    """A study as ``GET /studies/{id}`` answers it, with its statistics so far."""

    finished_at: datetime | None
    progress: float  # share of its jobs' work done, 0 to 1
    spec: dict[str, Any]  # as submitted, seeds resolved
    metrics: list[str]
    points: list[StudyPoint]
    comparisons: list[Comparison]
    interval: str  # how the confidence intervals are computed
    test: str  # how the paired p-values are computed
    adjustment: str = ""  # how they are adjusted for the study's many comparisons
    resolution: str = ""  # what each difference's resolvable is

    @classmethod
    def of(cls, data: dict[str, Any]) -> Study:
        return cls(
            **_summary_fields(data),
            finished_at=_time(data.get("finished_at")),
            progress=float(data["progress"]),
            spec=data["spec"],
            metrics=list(data["metrics"]),
            points=[
                StudyPoint(
                    index=int(p["index"]),
                    values=p["values"],
                    jobs=p["jobs"],
                    metrics={k: _known(Interval, v) for k, v in p["metrics"].items()},
                )
                for p in data["points"]
            ],
            comparisons=[
                Comparison(
                    values=c["values"],
                    method=c["method"],
                    baseline=c["baseline"],
                    metrics={k: _known(Difference, v) for k, v in c["metrics"].items()},
                )
                for c in data["comparisons"]
            ],
            interval=str(data.get("interval", "")),
            test=str(data.get("test", "")),
            adjustment=str(data.get("adjustment", "")),
            resolution=str(data.get("resolution", "")),
        )


@dataclass(frozen=True, kw_only=True)
class Policy:
    """A policy as ``POST /policies`` answers it and ``GET /policies`` lists it: a Q-table or a
    network (``kind``) made elsewhere, that a scenario evaluates by naming ``policy_from``."""

    id: int
    policy_from: str  # what a scenario's policy_from names it by: "policy-<id>"
    name: str | None
    action_set: str  # the learning.actions it is for
    communication: list[str]  # the communication.model values whose states are its rows
    state_count: int
    action_count: int
    table_count: int  # 1 for a table every robot starts from, else one per robot
    per_robot: bool
    created_at: datetime
    links: dict[str, Any]
    raw: dict[str, Any] = field(repr=False, compare=False)
    kind: str = "table"  # or "network": an ONNX model, whose state_count is its input width

    @classmethod
    def of(cls, data: dict[str, Any]) -> Policy:
        return cls(
            id=int(data["id"]),
            policy_from=str(data["policy_from"]),
            name=data.get("name"),
            action_set=str(data["action_set"]),
            communication=list(data["communication"]),
            state_count=int(data["state_count"]),
            action_count=int(data["action_count"]),
            table_count=int(data["table_count"]),
            per_robot=bool(data["per_robot"]),
            created_at=datetime.fromisoformat(data["created_at"]),
            links=data.get("links") or {},
            raw=data,
            kind=str(data.get("kind", "table")),
        )


@dataclass(frozen=True, kw_only=True)
class PolicyDetail(Policy):
    """A policy as ``GET /policies/{id}`` answers it: a table's rows and values, or what a
    network reads and what it costs. Fields of the other kind are None."""

    actions: list[str]
    states: list[str] | None = None  # a table's rows
    values: list[Any] | None = None  # [state][action], or [robot][state][action]
    greedy: list[dict[str, Any]] | None = None  # a table's greedy action of every state
    observation: list[str] | None = None  # a network's input columns
    model_bytes: int | None = None  # a network's ONNX model's size
    memory: int | None = None  # a recurrent network's memory inputs (0 for none)
    multiply_adds: int | None = None  # a network's multiply-adds an observation
    live_bytes: int | None = None  # a network's most memory held at once, an observation

    @classmethod
    def of(cls, data: dict[str, Any]) -> PolicyDetail:
        summary = Policy.of(data)
        shown = {f.name: getattr(summary, f.name) for f in fields(Policy)}
        return cls(
            **shown,
            actions=list(data["actions"]),
            states=data.get("states"),
            values=data.get("values"),
            greedy=data.get("greedy"),
            observation=data.get("observation"),
            model_bytes=data.get("model_bytes"),
            memory=data.get("memory"),
            multiply_adds=data.get("multiply_adds"),
            live_bytes=data.get("live_bytes"),
        )


_D = TypeVar("_D", JobCounts, Interval, Difference)


def _known(kind: type[_D], data: Mapping[str, Any]) -> _D:
    """``kind`` from the keys it knows, so that a newer server's extra keys break nothing, and
    an older server's missing ones take their defaults."""
    return kind(**{f.name: data[f.name] for f in fields(kind) if f.name in data or _required(f)})


def _required(known: Field[Any]) -> bool:
    return known.default is MISSING and known.default_factory is MISSING


def _summary_fields(data: dict[str, Any]) -> dict[str, Any]:
    return {
        "id": int(data["id"]),
        "name": str(data["name"]),
        "status": cast(Status, data["status"]),
        "created_at": datetime.fromisoformat(data["created_at"]),
        "cancel_requested": bool(data["cancel_requested"]),
        "jobs": _known(JobCounts, data["jobs"]),
        "links": data.get("links") or {},
        "raw": data,
    }


def parse_cell(text: str) -> GridValue | None:
    """A CSV cell of a study table as the value it was: empty is missing (None), ``True`` and
    ``False`` are booleans (as Python's csv writes them), integers and decimals are numbers, the
    rest stays text."""
    if text == "":
        return None
    if text in ("True", "False"):
        return text == "True"
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text
