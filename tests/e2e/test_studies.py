"""A study end to end with real workers: its statistics equal those computed here from the
jobs' own metrics, its table and pictures come back whole, and cancel stops it."""

from __future__ import annotations

import csv
import io
import itertools
import math
import statistics
import time
from collections.abc import Callable
from typing import Any

import pyarrow.parquet as pq
import pytest

from nanonav.engine.metrics import RANGES
from tests.conftest import Api
from tests.e2e.test_jobs import LONG, decode_png
from tests.processes import FIRST_JOB_S, Worker

pytestmark = pytest.mark.timeout(300)

STUDY: dict[str, Any] = {
    "name": "policy x obstacles",
    "base": {"robots": {"count": 1}, "learning": {"episodes": 3, "max_steps": 150}},
    "grid": {"robots.policy": ["q_learning", "gradient"], "obstacles.count": [0, 10]},
    "seeds": [1, 2, 3],
    "compare": "robots.policy",
}
METRICS = (
    "total_steps", "final_distance", "average_distance", "average_concentration",
    "success_rate", "collisions", "path_efficiency",
)  # fmt: skip
# Student t quantile t(0.975, 2), for three seeds.
T_975_2 = 4.302652729911275


def wait_study(api: Api, study_id: int, timeout: float) -> dict[str, Any]:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        study: dict[str, Any] = api.client.get(f"/studies/{study_id}").json()
        if study["status"] in {"succeeded", "failed", "cancelled"}:
            return study
        time.sleep(0.1)
    raise AssertionError(f"study {study_id} did not finish: {study['jobs']}")


def signed_rank_p(differences: list[float]) -> float:
    """Two-sided exact Wilcoxon signed-rank p-value by enumerating every sign pattern (zeros
    dropped, tied magnitudes sharing their mean rank)."""
    nonzero = [d for d in differences if d != 0]
    if not nonzero:
        return 1.0
    order = sorted(abs(d) for d in nonzero)
    ranks = {a: statistics.fmean([i + 1 for i, b in enumerate(order) if b == a]) for a in order}
    observed = sum(ranks[abs(d)] for d in nonzero if d > 0)
    total = sum(ranks[abs(d)] for d in nonzero)
    extreme = abs(observed - total / 2)
    patterns = list(itertools.product([0, 1], repeat=len(nonzero)))
    hits = sum(
        1
        for signs in patterns
        if abs(sum(ranks[abs(d)] for d, s in zip(nonzero, signs, strict=True) if s) - total / 2)
        >= extreme - 1e-12
    )
    return min(1.0, hits / len(patterns))


def pooled_wilson(values: list[float], trials: int) -> tuple[float, float]:
    """Wilson on the seeds' pooled trials, counted as their spread allows (``describe_share``)."""
    mean, n = statistics.fmean(values), len(values)
    total = trials * n
    spread = n / (n - 1) * sum((1 / n) ** 2 * (v - mean) ** 2 for v in values)
    z = 1.959963984540054
    effective = float(total)
    if spread > 0 and 0 < mean < 1:
        effective = min(total, mean * (1 - mean) / spread * (z / T_975_2) ** 2)
    centre = (mean + z * z / (2 * effective)) / (1 + z * z / effective)
    half = (
        z
        / (1 + z * z / effective)
        * math.sqrt(mean * (1 - mean) / effective + z * z / (4 * effective * effective))
    )
    return max(0.0, centre - half), min(1.0, centre + half)


def interval_of(
    values: list[float], bounds: tuple[float, float] | None, method: str, trials: int
) -> tuple[float, float]:
    """The 95 % interval of three values worked out here, for the method the range calls for
    (a share of ``trials`` per seed pools them)."""
    mean, n = statistics.fmean(values), len(values)
    sd = statistics.stdev(values)
    if method == "pooled_wilson":
        return pooled_wilson(values, trials)
    outcomes = bounds == (0.0, 1.0) and all(v in (0.0, 1.0) for v in values)
    if sd == 0.0 and not outcomes:  # n outcomes alike still leave a proportion uncertain
        return mean, mean
    if bounds is None:
        assert method == "student_t"
        half = T_975_2 * sd / math.sqrt(n)
        return mean - half, mean + half
    if bounds == (0.0, 1.0):
        if outcomes:
            assert method == "wilson"
            z = 1.959963984540054
            centre = (mean + z * z / (2 * n)) / (1 + z * z / n)
            half = z / (1 + z * z / n) * math.sqrt(mean * (1 - mean) / n + z * z / (4 * n * n))
            return max(0.0, centre - half), min(1.0, centre + half)
        assert method == "logit_t"
        half = T_975_2 * sd / (math.sqrt(n) * mean * (1 - mean))
        centre = math.log(mean / (1 - mean))
        return 1 / (1 + math.exp(-(centre - half))), 1 / (1 + math.exp(-(centre + half)))
    assert method == "log_t"
    half = T_975_2 * sd / (math.sqrt(n) * mean)
    return mean * math.exp(-half), mean * math.exp(half)


def test_a_study_runs_and_its_statistics_match_the_jobs(
    api: Api, start_worker: Callable[..., Worker]
) -> None:
    start_worker()
    start_worker()
    created = api.client.post("/studies", json=STUDY)
    assert created.status_code == 202, created.text
    study = wait_study(api, created.json()["id"], FIRST_JOB_S + 60)
    assert study["status"] == "succeeded", study["jobs"]
    assert study["jobs"]["succeeded"] == 12 and study["progress"] == 1.0
    assert study["finished_at"] is not None

    jobs = api.client.get("/jobs", params={"study": study["id"], "limit": 100}).json()["jobs"]
    summaries: dict[tuple[str, int, int], dict[str, Any]] = {}
    for job in jobs:
        s = job["scenario"]
        key = (s["robots"]["policy"], s["obstacles"]["count"], s["seed"])
        summaries[key] = api.client.get(f"/jobs/{job['id']}/metrics").json()["summary"]
    assert len(summaries) == 12

    for point in study["points"]:
        policy, count = point["values"]["robots.policy"], point["values"]["obstacles.count"]
        assert point["jobs"]["succeeded"] == 3
        for metric in METRICS:
            values = [summaries[(policy, count, seed)][metric] for seed in (1, 2, 3)]
            got = point["metrics"][metric]
            mean = statistics.fmean(values)
            sd = statistics.stdev(values)
            assert got["n"] == 3
            assert got["mean"] == pytest.approx(mean, rel=1e-12, abs=1e-12)
            assert got["sd"] == pytest.approx(sd, rel=1e-9, abs=1e-12)
            summary = summaries[(policy, count, 1)]
            trials = int(summary["robots"]) * int(summary["worlds"])
            low, high = interval_of(values, RANGES[metric], got["method"], trials)
            assert (got["method"] == "pooled_wilson") == (metric == "success_rate")
            assert got["ci_low"] == pytest.approx(low, rel=1e-9, abs=1e-9)
            assert got["ci_high"] == pytest.approx(high, rel=1e-9, abs=1e-9)

    assert len(study["comparisons"]) == 2
    for comparison in study["comparisons"]:
        assert (comparison["method"], comparison["baseline"]) == ("gradient", "q_learning")
        count = comparison["values"]["obstacles.count"]
        for metric in METRICS:
            differences = [
                summaries[("gradient", count, seed)][metric]
                - summaries[("q_learning", count, seed)][metric]
                for seed in (1, 2, 3)
            ]
            got = comparison["metrics"][metric]
            assert got["n"] == 3
            assert got["mean_difference"] == pytest.approx(
                statistics.fmean(differences), rel=1e-9, abs=1e-12
            )
            if len(set(differences)) > 1:
                half = T_975_2 * statistics.stdev(differences) / math.sqrt(3)
                assert got["ci_high"] - got["ci_low"] == pytest.approx(2 * half, rel=1e-9)
            assert got["p_value"] == pytest.approx(signed_rank_p(differences), abs=1e-12)

    text = api.client.get(f"/studies/{study['id']}/results.csv").text
    rows = list(csv.DictReader(io.StringIO(text)))
    assert len(rows) == 12
    for row in rows:
        key = (row["robots.policy"], int(row["obstacles.count"]), int(row["seed"]))
        assert row["status"] == "succeeded"
        assert float(row["total_steps"]) == summaries[key]["total_steps"]
        assert float(row["path_efficiency"]) == summaries[key]["path_efficiency"]

    parquet = api.client.get(f"/studies/{study['id']}/results.csv", params={"format": "parquet"})
    assert parquet.headers["content-type"] == "application/vnd.apache.parquet"
    table = pq.read_table(io.BytesIO(parquet.content)).to_pylist()
    assert len(table) == 12
    for row, csv_row in zip(table, rows, strict=True):
        assert row["job_id"] == int(csv_row["job_id"])
        assert row["obstacles.count"] == int(csv_row["obstacles.count"])
        for metric in METRICS:
            assert row[metric] == float(csv_row[metric])

    assert "policies" in study["links"]["plots"]  # its q_learning points learn tables
    for name in (*METRICS, "learning", "policies"):
        response = api.client.get(f"/studies/{study['id']}/plots/{name}.png")
        assert response.status_code == 200, response.text
        image = decode_png(response.content)
        assert image[..., :3].std() > 0.05
        assert "immutable" in response.headers["cache-control"]  # the study has finished


def test_cancel_stops_a_studys_unfinished_jobs(
    api: Api, start_worker: Callable[..., Worker]
) -> None:
    start_worker()
    body = {"base": LONG, "grid": {"robots.speed": [0.5, 1.0]}, "replicates": 3}
    study = api.client.post("/studies", json=body).json()
    deadline = time.monotonic() + FIRST_JOB_S
    while api.client.get(f"/studies/{study['id']}").json()["jobs"]["running"] == 0:
        assert time.monotonic() < deadline, "no job of the study started"
        time.sleep(0.1)
    answer = api.client.post(f"/studies/{study['id']}/cancel").json()
    assert answer["cancel_requested"] is True
    assert answer["jobs"]["cancelled"] == 5 and answer["jobs"]["running"] == 1
    ended = wait_study(api, study["id"], 10)
    assert ended["status"] == "cancelled"
    assert ended["jobs"]["cancelled"] == 6 and ended["jobs"]["succeeded"] == 0


def test_a_physical_study_over_robot_radius_runs_with_a_fitting_step_at_each(
    api: Api, start_worker: Callable[..., Worker]
) -> None:
    # the physical question's study, small: robot radius x policy in tumour-microswimmers
    start_worker()
    spec = {
        "name": "radius x policy",
        "base": {
            "preset": "tumour-microswimmers",
            "physics": {"model": "active_brownian", "time_limit_s": 2.0},
            "robots": {"count": 4},
            "learning": {"episodes": 0},
            "evaluation": {"worlds": 2},
        },
        "grid": {
            "physics.robot_radius_um": [0.5, 5.0],
            "robots.policy": ["uncontrolled", "exact_gradient"],
        },
        "seeds": [1, 2],
        "compare": "robots.policy",
    }
    created = api.client.post("/studies", json=spec)
    assert created.status_code == 202, created.text
    study = wait_study(api, created.json()["id"], FIRST_JOB_S + 120)
    assert study["status"] == "succeeded", study["jobs"]
    jobs = api.client.get("/jobs", params={"study": study["id"], "limit": 100}).json()["jobs"]
    assert len(jobs) == 8
    for job in jobs:
        physics = job["scenario"]["physics"]
        # each radius got its own step, filled in, and the same 2 s
        assert physics["dt_s"] * job["scenario"]["learning"]["max_steps"] == pytest.approx(2.0)
        assert physics["rotational_diffusion_s"] * physics["dt_s"] <= 0.05
        metrics = api.client.get(f"/jobs/{job['id']}/metrics").json()
        assert metrics["physics"]["time_limit_s"] == pytest.approx(2.0)
    assert len(study["comparisons"]) == 2
    for name in ("success_rate", "learning"):
        response = api.client.get(f"/studies/{study['id']}/plots/{name}.png")
        assert response.status_code == 200 and response.content.startswith(b"\x89PNG"), name
    # no point learns (no training episode): no policies to show
    assert "policies" not in study["links"]["plots"]
    missing = api.client.get(f"/studies/{study['id']}/plots/policies.png")
    assert missing.status_code == 404 and "learns a Q-table" in missing.text


def test_a_swarm_study_over_communication_reports_the_cells_treated(
    api: Api, start_worker: Callable[..., Worker]
) -> None:
    # the swarm's question, small: communication model in the diffuse tumour, paired by seed
    start_worker()
    spec = {
        "name": "signals",
        "base": {
            "preset": "diffuse-tumour",
            "cells": {"count": 5},
            "robots": {"count": 30},
            "learning": {"max_steps": 300},
            "evaluation": {"worlds": 1},
        },
        "grid": {"communication.model": ["none", "attractant_repellent", "broadcast"]},
        "seeds": [1, 2],
        "compare": "communication.model",
    }
    created = api.client.post("/studies", json=spec)
    assert created.status_code == 202, created.text
    study = wait_study(api, created.json()["id"], FIRST_JOB_S + 120)
    assert study["status"] == "succeeded", study["jobs"]
    assert len(study["comparisons"]) == 2  # each model against the first, paired by seed
    assert "treated_fraction" in study["links"]["plots"]
    for name in ("treated_fraction", "time_to_treat_all"):
        response = api.client.get(f"/studies/{study['id']}/plots/{name}.png")
        assert response.status_code == 200 and response.content.startswith(b"\x89PNG"), name
    table = api.client.get(f"/studies/{study['id']}/results.csv")
    assert table.status_code == 200 and "treated_fraction" in table.text.splitlines()[0]
