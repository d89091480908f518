"""What a finished job gives: its metrics, its trajectory and its Q-table."""

from __future__ import annotations

from typing import Any

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
)

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
