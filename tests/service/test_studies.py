"""The studies API without a worker: creation in one transaction, validation naming the grid
value at fault, the job cap, idempotency, listing, cancelling, and what a job knows of its study."""

from __future__ import annotations

import csv
import io
import threading
from typing import Any

import httpx
import pyarrow.parquet as pq
import pytest

from nanonav.settings import Settings
from nanonav.store import JobStatus
from nanonav.store.migrate import upgrade
from service.app import create_app
from tests.conftest import Api, serve
from tests.service.test_api import assert_problem
from worker.job import run_job

GRID: dict[str, Any] = {
    "name": "policy x obstacles",
    "base": {"preset": "paper-single", "learning": {"episodes": 2, "max_steps": 100}},
    "grid": {"robots.policy": ["q_learning", "gradient"], "obstacles.count": [0, 10]},
    "seeds": [1, 2, 3],
    "compare": "robots.policy",
}


def create(api: Api, body: dict[str, Any], **headers: str) -> dict[str, Any]:
    response = api.client.post("/studies", json=body, headers=headers)
    assert response.status_code == 202, response.text
    study: dict[str, Any] = response.json()
    assert response.headers["location"] == f"/studies/{study['id']}"
    return study


def test_every_grid_point_and_seed_becomes_a_queued_job(api: Api) -> None:
    study = create(api, GRID)
    assert study["status"] == "queued"
    assert study["jobs"] == {
        "total": 12, "queued": 12, "running": 0, "succeeded": 0, "failed": 0, "cancelled": 0
    }  # fmt: skip
    assert [p["values"] for p in study["points"]] == [
        {"robots.policy": "q_learning", "obstacles.count": 0},
        {"robots.policy": "q_learning", "obstacles.count": 10},
        {"robots.policy": "gradient", "obstacles.count": 0},
        {"robots.policy": "gradient", "obstacles.count": 10},
    ]
    assert study["points"][0]["metrics"]["total_steps"] == {
        "n": 0, "mean": None, "sd": None, "ci_low": None, "ci_high": None, "method": "log_t"
    }  # fmt: skip
    assert "log_t" in study["interval"] and "Wilcoxon" in study["test"]
    jobs = api.client.get("/jobs", params={"study": study["id"], "limit": 100}).json()["jobs"]
    assert len(jobs) == 12
    seen = set()
    for job in jobs:
        assert job["study_id"] == study["id"]
        assert job["links"]["study"] == f"/studies/{study['id']}"
        scenario = job["scenario"]
        assert scenario["robots"]["count"] == 1  # the preset applied
        assert scenario["learning"]["episodes"] == 2
        seen.add((scenario["robots"]["policy"], scenario["obstacles"]["count"], scenario["seed"]))
    assert len(seen) == 12
    # seed by seed: the oldest jobs are the first seed at every point
    oldest = sorted(jobs, key=lambda j: j["id"])[:4]
    assert {j["scenario"]["seed"] for j in oldest} == {1}


def test_replicates_are_seeds_counting_from_zero(api: Api) -> None:
    body = {**GRID, "seeds": None, "replicates": 2}
    study = create(api, {k: v for k, v in body.items() if v is not None})
    assert study["spec"]["seeds"] == [0, 1]
    assert study["jobs"]["total"] == 8


@pytest.mark.parametrize(
    ("change", "pointer", "words"),
    [
        ({"grid": {"robots.count": [1, 0]}}, "#/grid/robots.count/1", "greater than or equal"),
        ({"grid": {"robots.polcy": ["gradient"]}}, "#/grid/robots.polcy", "not a scenario field"),
        ({"grid": {"seed": [1, 2]}}, "#/grid/seed", "not a scenario field"),
        ({"grid": {"robots.policy": ["gradient", "gradient"]}}, "#/grid/robots.policy/1",
         "already listed"),
        ({"grid": {"obstacles.count": [10, 1000], "obstacles.radius": [1.5, 3.0]}},
         "#/grid/obstacles.count/1", "obstacles.count=1000, obstacles.radius=3.0"),
        ({"base": {"robots": {"count": -1}}}, "#/base/robots/count", "greater than or equal"),
        ({"compare": "robots.speed"}, "#/compare", "one of the grid's keys"),
        ({"seeds": [1, 1]}, "#/seeds", "must not repeat"),
        ({"seeds": [-1]}, "#/seeds/0", ""),
        ({"replicates": 3}, "#/seeds", "either 'seeds' or 'replicates'"),
        ({"grid": {"robots.policy": ["q_learning", "teleport"]}}, "#/grid/robots.policy/1",
         "'q_learning', 'gradient'"),
        ({"grid": {"robots.count": [[1]]}}, "#/grid/robots.count/0", ""),
        ({"seeds": [], "compare": None}, "#/seeds", ""),
        ({"name": "x" * 201}, "#/name", ""),
    ],
)  # fmt: skip
def test_an_invalid_study_is_422_naming_the_field_and_nothing_is_stored(
    api: Api, change: dict[str, Any], pointer: str, words: str
) -> None:
    body = {**GRID, **change}
    if "compare" not in change and body["compare"] not in body["grid"]:
        body["compare"] = None
    problem = assert_problem(api.client.post("/studies", json=body), 422)
    assert problem["errors"][0]["pointer"] == pointer, problem
    assert words in problem["detail"]
    assert api.client.get("/jobs").json()["jobs"] == []
    assert api.client.get("/studies").json()["studies"] == []


def test_a_grid_point_over_the_work_budget_is_422_naming_its_values(sqlite_url: str) -> None:
    settings = Settings(database_url=sqlite_url, robot_steps_budget=1_000_000)
    upgrade(sqlite_url)
    body = {**GRID, "grid": {"robots.count": [1, 5000]}, "compare": None}
    with serve(create_app(settings)) as url, httpx.Client(base_url=url) as client:
        problem = client.post("/studies", json=body).json()
        assert problem["status"] == 422
        assert [e["pointer"] for e in problem["errors"]] == ["#/grid/robots.count/1"]
        assert "robot-steps" in problem["detail"]


def test_a_study_over_the_job_cap_is_422(sqlite_url: str) -> None:
    settings = Settings(database_url=sqlite_url, study_max_jobs=10)
    upgrade(sqlite_url)
    with serve(create_app(settings)) as url, httpx.Client(base_url=url) as client:
        problem = client.post("/studies", json=GRID).json()
        assert problem["status"] == 422
        assert [e["pointer"] for e in problem["errors"]] == ["#/grid", "#/seeds"]
        assert "12 jobs" in problem["detail"] and "10" in problem["detail"]
        huge = {**GRID, "grid": {f"robots.{k}": list(range(1, 101)) for k in ("count", "speed")}}
        huge["compare"] = None
        assert client.post("/studies", json=huge).json()["status"] == 422  # not expanded


def test_an_idempotency_key_returns_the_study_it_made_and_refuses_another(api: Api) -> None:
    first = create(api, GRID, **{"Idempotency-Key": "study-1"})
    again = create(api, GRID, **{"Idempotency-Key": "study-1"})
    assert again["id"] == first["id"]
    assert again["jobs"]["total"] == 12
    other = api.client.post(
        "/studies", json={**GRID, "seeds": [7]}, headers={"Idempotency-Key": "study-1"}
    )
    assert other.status_code == 422
    assert other.json()["errors"][0]["parameter"] == "idempotency-key"
    assert len(api.client.get("/jobs", params={"limit": 100}).json()["jobs"]) == 12


def test_studies_are_listed_newest_first_and_paged(api: Api) -> None:
    ids = [create(api, {**GRID, "name": f"s{i}"})["id"] for i in range(3)]
    page = api.client.get("/studies", params={"limit": 2}).json()
    assert [s["id"] for s in page["studies"]] == ids[::-1][:2]
    assert page["studies"][0]["jobs"]["queued"] == 12
    rest = api.client.get(page["next"]).json()
    assert [s["id"] for s in rest["studies"]] == [ids[0]]
    assert rest["next"] is None


def test_cancel_cancels_the_queued_jobs_and_then_is_409(api: Api) -> None:
    study = create(api, GRID)
    cancelled = api.client.post(f"/studies/{study['id']}/cancel").json()
    assert cancelled["status"] == "cancelled"
    assert cancelled["jobs"]["cancelled"] == 12
    for job in api.client.get("/jobs", params={"study": study["id"]}).json()["jobs"]:
        assert api.store.get(job["id"]).status is JobStatus.CANCELLED
    # cancelling again is harmless; a study that finished on its own cannot be cancelled
    assert api.client.post(f"/studies/{study['id']}/cancel").status_code == 200


def test_a_studys_failed_jobs_are_retried_in_one_request(api: Api) -> None:
    study = create(api, GRID)
    assert_problem(api.client.post(f"/studies/{study['id']}/retry"), 409)  # none failed
    failed = []
    for _ in range(2):
        claim = api.store.claim("test", lease_s=30)
        assert claim is not None
        failed.append(api.store.fail(claim, "the worker's machine ran out of memory").id)
    retried = api.client.post(f"/studies/{study['id']}/retry")
    assert retried.status_code == 200, retried.text
    assert retried.json()["jobs"] == {**retried.json()["jobs"], "failed": 0, "queued": 12}
    for job_id in failed:
        job = api.client.get(f"/jobs/{job_id}").json()
        assert (job["status"], job["attempts"], job["error"]) == ("queued", 0, None)
    problem = assert_problem(api.client.post(f"/studies/{study['id']}/retry"), 409)
    assert problem["type"].endswith("nothing-to-retry") and "nothing to retry" in problem["detail"]
    assert_problem(api.client.post("/studies/99/retry"), 404)


def test_unknown_studies_are_404(api: Api) -> None:
    for path in ("/studies/99", "/studies/99/results.csv", "/studies/99/plots/learning.png"):
        body = assert_problem(api.client.get(path), 404)
        assert body["type"].endswith("study-not-found")
    assert_problem(api.client.post("/studies/99/cancel"), 404)
    problem = assert_problem(api.client.get("/studies/1/plots/nonsense.png"), 422)
    assert problem["errors"][0]["parameter"] == "name"


def test_a_new_study_table_lists_its_jobs_with_empty_metrics(api: Api) -> None:
    study = create(api, GRID)
    text = api.client.get(f"/studies/{study['id']}/results.csv").text
    lines = text.splitlines()
    assert lines[0].startswith("job_id,seed,robots.policy,obstacles.count,status,total_steps")
    assert len(lines) == 13
    assert lines[1].split(",")[4] == "queued"


def test_the_comparisons_table_gives_each_difference_with_its_holm_p_beside_its_own(
    api: Api, api_settings: Settings
) -> None:
    """Two policies against q_learning at two obstacle counts: four comparisons of each metric,
    each a row of the table with the report's numbers, in CSV and in Parquet."""
    body = {
        **GRID,
        "base": {"robots": {"count": 1}, "learning": {"episodes": 1, "max_steps": 40},
                 "evaluation": {"worlds": 1}},
        "grid": {"robots.policy": ["q_learning", "gradient", "random"], "obstacles.count": [0, 5]},
    }  # fmt: skip
    study = create(api, body)
    path = f"/studies/{study['id']}/comparisons.csv"
    assert study["links"]["comparisons_csv"] == path
    while (claim := api.store.claim("test", lease_s=30)) is not None:
        record = run_job(api.store, claim, api_settings, threading.Event())
        assert record is not None and record.status is JobStatus.SUCCEEDED
    found = api.client.get(f"/studies/{study['id']}").json()
    answer = api.client.get(path)
    assert answer.status_code == 200 and answer.headers["content-type"].startswith("text/csv")
    rows = list(csv.DictReader(io.StringIO(answer.text)))
    assert list(rows[0]) == [
        "obstacles.count", "robots.policy", "baseline", "metric", "n", "mean_difference", "sd",
        "ci_low", "ci_high", "p_value", "p_holm", "holm_comparisons", "resolvable",
    ]  # fmt: skip
    expected = [
        (comparison, metric, difference)
        for comparison in found["comparisons"]
        for metric, difference in comparison["metrics"].items()
    ]
    assert len(rows) == len(expected) == 4 * len(found["metrics"])
    for row, (comparison, metric, difference) in zip(rows, expected, strict=True):
        assert row["obstacles.count"] == str(comparison["values"]["obstacles.count"])
        assert (row["robots.policy"], row["baseline"]) == (comparison["method"], "q_learning")
        assert row["metric"] == metric and int(row["n"]) == difference["n"] == 3
        for column in ("mean_difference", "p_value", "p_holm", "resolvable"):
            value = difference[column]
            assert row[column] == ("" if value is None else repr(value)), column
        if difference["p_value"] is not None:
            assert int(row["holm_comparisons"]) == 4
    parquet = api.client.get(path, params={"format": "parquet"})
    table = pq.read_table(io.BytesIO(parquet.content))
    assert str(table.schema.field("n").type) == "int64"
    assert str(table.schema.field("p_holm").type) == "double"
    assert table.column("metric").to_pylist() == [row["metric"] for row in rows]
    # a study that compares nothing has a table of no rows; an unknown one is 404
    plain = create(api, {**body, "compare": None})
    lines = api.client.get(f"/studies/{plain['id']}/comparisons.csv").text.splitlines()
    assert lines == ["robots.policy,obstacles.count,metric,n,mean_difference,sd,ci_low,"
                     "ci_high,p_value,p_holm,holm_comparisons,resolvable"]  # fmt: skip
    assert_problem(api.client.get("/studies/999/comparisons.csv"), 404)


def test_a_study_sweeps_a_field_through_null_and_says_null_everywhere(
    api: Api, api_settings: Settings
) -> None:
    """cells.capacity: [null, 1], compared: queued, run, reported, tabled, drawn and shown."""
    body = {
        "base": {"robots": {"count": 2, "exclusion": True}, "cells": {"count": 2},
                 "learning": {"episodes": 0, "max_steps": 30}, "evaluation": {"worlds": 1}},
        "grid": {"cells.capacity": [None, 1]}, "seeds": [1, 2], "compare": "cells.capacity",
    }  # fmt: skip
    study = create(api, body)
    while (claim := api.store.claim("test", lease_s=30)) is not None:
        record = run_job(api.store, claim, api_settings, threading.Event())
        assert record is not None and record.status is JobStatus.SUCCEEDED
    found = api.client.get(f"/studies/{study['id']}").json()
    assert [p["values"] for p in found["points"]] == [{"cells.capacity": None},
                                                      {"cells.capacity": 1}]  # fmt: skip
    [comparison] = found["comparisons"]
    assert (comparison["baseline"], comparison["method"]) == (None, 1)
    rows = api.client.get(f"/studies/{study['id']}/results.csv").text.splitlines()
    assert sorted(row.split(",")[2] for row in rows[1:]) == ["", "", "1", "1"]
    parquet = api.client.get(f"/studies/{study['id']}/results.csv", params={"format": "parquet"})
    assert parquet.status_code == 200
    column = pq.read_table(io.BytesIO(parquet.content)).column("cells.capacity").to_pylist()
    assert sorted(column, key=str) == [1, 1, None, None]
    page = api.client.get(f"/ui/studies/{study['id']}").text
    assert "<td>null</td>" in page and "1 \u2212 null" in page
    picture = api.client.get(f"/studies/{study['id']}/plots/success_rate.png")
    assert picture.status_code == 200 and picture.content.startswith(b"\x89PNG")
