"""What the API answers with: response models, each with an example for the OpenAPI page."""

from __future__ import annotations

from datetime import datetime
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from nanonav.store import JobRecord

Status = Literal["queued", "running", "succeeded", "failed", "cancelled"]
PLOTS = ("trajectory", "concentration", "learning")
PLANES = ("xy", "xz", "yz", "all")

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
        "plots": {name: f"/jobs/42/plots/{name}.png" for name in PLOTS},
    },
}


class Progress(BaseModel):
    episode: int = Field(description="Episodes finished so far.")
    episodes: int = Field(description="Episodes the run has in all.")
    fraction: float = Field(ge=0.0, le=1.0, description="Share of the run's work done.")


class JobLinks(BaseModel):
    model_config = ConfigDict(populate_by_name=True)

    self_: str = Field(alias="self")
    cancel: str
    metrics: str
    trajectory: str
    qtable: str
    heatmap: str
    plots: dict[str, str]


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
    links: JobLinks

    @classmethod
    def of(cls, job: JobRecord) -> Job:
        base = f"/jobs/{job.id}"
        return cls(
            id=job.id,
            status=job.status.value,
            progress=Progress(episode=job.episode, episodes=job.episodes, fraction=job.fraction),
            scenario=job.scenario,
            created_at=job.created_at,
            started_at=job.started_at,
            finished_at=job.finished_at,
            error=job.error,
            attempts=job.attempts,
            cancel_requested=job.cancel_requested,
            links=JobLinks(
                self_=base,
                cancel=f"{base}/cancel",
                metrics=f"{base}/metrics",
                trajectory=f"{base}/trajectory",
                qtable=f"{base}/qtable",
                heatmap=f"{base}/heatmap.png",
                plots={name: f"{base}/plots/{name}.png" for name in PLOTS},
            ),
        )


class JobPage(BaseModel):
    """A page of jobs, newest first."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [{"jobs": [JOB_EXAMPLE], "next_cursor": "MzA", "next": "/jobs?cursor=MzA"}]
        }
    )

    jobs: list[Job]
    next_cursor: str | None = Field(
        description="Pass as ?cursor= for the next page; null at the end."
    )
    next: str | None = Field(description="The next page's URL, or null.")


class Metrics(BaseModel):
    """The metrics document of a finished run (the engine's ``SimulationResult.to_dict()``)."""

    model_config = ConfigDict(
        extra="allow",
        json_schema_extra={
            "examples": [
                {
                    "scenario": {"seed": 0, "...": "..."},
                    "completed": True,
                    "summary": {
                        "total_steps": 312,
                        "final_distance": 0.4,
                        "average_distance": 9.8,
                        "average_concentration": 0.41,
                        "duration_s": 0.05,
                        "success_rate": 1.0,
                        "collisions": 2,
                        "path_efficiency": 0.91,
                        "mean_steps_to_reach": 312.0,
                        "mean_return": 42.0,
                        "robots": 1,
                        "reached": 1,
                    },
                    "robots": [
                        {
                            "robot": 0,
                            "reached": True,
                            "total_steps": 312,
                            "final_distance": 0.4,
                            "average_distance": 9.8,
                            "average_concentration": 0.41,
                            "duration_s": 0.05,
                            "collisions": 2,
                            "path_length": 156.0,
                            "path_efficiency": 0.91,
                            "return": 42.0,
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
    summary: dict[str, Any]
    robots: list[dict[str, Any]]
    episodes: list[dict[str, Any]]
    work: dict[str, Any]


class Trajectory(BaseModel):
    """The evaluation episode, every ``stride``-th step (the last step is always included)."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "stride": 10,
                    "length": 20,
                    "steps": [0, 10, 20],
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
    steps: list[int] = Field(description="The step number of every row below.")
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


class QTable(BaseModel):
    """The learned Q-table: ``values[state][action]`` (or ``[robot][state][action]``)."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "states": [
                        "conc=low|trend=rising|obstacle=none|cell=none",
                        "conc=high|trend=falling|obstacle=near|cell=near",
                    ],
                    "actions": ["follow_gradient", "approach_cell", "avoid_obstacle", "explore"],
                    "values": [[0.1, 0.0, -0.2, 0.05], [1.2, 3.4, 0.0, 0.1]],
                    "visits": [[10, 2, 1, 4], [3, 9, 0, 1]],
                }
            ]
        }
    )

    states: list[str]
    actions: list[str]
    values: list[Any]
    visits: list[Any]


class Health(BaseModel):
    model_config = ConfigDict(
        json_schema_extra={
            "examples": [{"status": "ok", "database": True, "revision": "0001", "head": "0001"}]
        }
    )

    status: Literal["ok", "unavailable"]
    database: bool = Field(description="Whether the database answered.")
    revision: str | None = Field(description="The database's migration revision.")
    head: str | None = Field(description="The newest migration this code knows.")


class Version(BaseModel):
    model_config = ConfigDict(
        json_schema_extra={"examples": [{"name": "nanonav", "version": "0.1.0"}]}
    )

    name: str
    version: str
