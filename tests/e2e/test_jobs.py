"""End to end: the API in-process over a real SQLite file, and real ``python -m worker`` processes.

The first job of a fresh worker may wait for numba to compile (or load its cache) the engine's
kernels; the timeouts allow for it.
"""

from __future__ import annotations

import csv
import io
import re
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import matplotlib.image
import numpy as np
import pytest

from nanonav.settings import Settings
from nanonav.store import JobStore
from nanonav.store.migrate import upgrade
from service.app import create_app
from tests.conftest import Api, serve
from tests.processes import FIRST_JOB_S, Worker

TINY: dict[str, Any] = {"robots": {"count": 2}, "learning": {"episodes": 2, "max_steps": 60}}
# Random walkers in a big cube rarely reach the cell, so every episode uses all its steps:
# about a fifth of a second each, for minutes in all.
LONG: dict[str, Any] = {
    "space": {"size": 1000},
    "robots": {"count": 50, "policy": "random"},
    "learning": {"episodes": 900, "max_steps": 20_000},
}
PICTURES = ("heatmap_xy", "heatmap_xz", "heatmap_yz", "heatmap_all")

pytestmark = pytest.mark.timeout(240)


def submit(api: Api, scenario: dict[str, Any]) -> int:
    response = api.client.post("/jobs", json=scenario)
    assert response.status_code == 202, response.text
    job_id: int = response.json()["id"]
    return job_id


def wait_for(
    api: Api, job_id: int, until: Callable[[dict[str, Any]], bool], timeout: float
) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """Poll the job until ``until`` holds; returns it and every state seen on the way."""
    seen: list[dict[str, Any]] = []
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        job: dict[str, Any] = api.client.get(f"/jobs/{job_id}").json()
        seen.append(job)
        if until(job):
            return job, seen
        time.sleep(0.05)
    raise AssertionError(f"job {job_id} never got there; last seen {seen[-1]}")


def finished(job: dict[str, Any]) -> bool:
    return job["status"] in {"succeeded", "failed", "cancelled"}


def decode_png(data: bytes) -> np.ndarray[Any, Any]:
    assert data.startswith(b"\x89PNG\r\n\x1a\n")
    image: np.ndarray[Any, Any] = matplotlib.image.imread(io.BytesIO(data), format="png")
    assert image.ndim == 3 and image.shape[0] > 100 and image.shape[1] > 100
    assert image.std() > 0
    return image


def test_a_submitted_job_runs_and_every_result_comes_back(
    api: Api, start_worker: Callable[..., Worker]
) -> None:
    start_worker()
    job_id = submit(api, TINY)
    job, seen = wait_for(api, job_id, finished, FIRST_JOB_S)
    assert job["status"] == "succeeded", job
    assert job["progress"] == {
        "episode": 2 + 20, "episodes": 2 + 20, "training_episodes": 2, "evaluation_worlds": 20,
        "fraction": 1.0, "decisions": None, "training_decisions": None, "training_curve": None,
    }  # fmt: skip
    assert job["attempts"] == 1
    assert job["started_at"] is not None and job["finished_at"] >= job["started_at"]
    fractions = [s["progress"]["fraction"] for s in seen]
    assert fractions == sorted(fractions)
    assert {s["status"] for s in seen} <= {"queued", "running", "succeeded"}

    metrics = api.client.get(f"/jobs/{job_id}/metrics").json()
    summary = metrics["summary"]
    for key in ("total_steps", "final_distance", "average_distance", "success_rate", "collisions"):
        assert key in summary, key
    assert len(metrics["robots"]) == 2
    assert len(metrics["episodes"]) == 2
    assert len(metrics["worlds"]) == 20 and metrics["uncertainty"]["success_rate"]["n"] == 20
    assert metrics["scenario"] == job["scenario"]

    full = api.client.get(f"/jobs/{job_id}/trajectory").json()
    length = full["length"]
    assert 1 <= length <= 60
    assert length == metrics["worlds"][0]["episode_steps"]
    assert full["step"] == list(range(length + 1))
    assert np.asarray(full["robots"]).shape == (length + 1, 2, 3)
    assert np.asarray(full["cells"]).shape == (length + 1, 1, 3)
    assert np.asarray(full["concentration"]).shape == (length + 1, 2)
    assert np.asarray(full["distance"]).shape == (length + 1, 2)
    assert len(full["reached"]) == 2

    strided = api.client.get(f"/jobs/{job_id}/trajectory", params={"stride": 7}).json()
    expected_steps = sorted({*range(0, length + 1, 7), length})
    assert strided["step"] == expected_steps
    assert strided["robots"] == [full["robots"][s] for s in expected_steps]

    npz = api.client.get(f"/jobs/{job_id}/trajectory", params={"format": "npz", "stride": 7})
    assert npz.headers["content-type"] == "application/octet-stream"
    with np.load(io.BytesIO(npz.content), allow_pickle=False) as arrays:
        assert arrays["robots"].dtype == np.float64
        assert arrays["robots"].shape == (len(expected_steps), 2, 3)
        assert arrays["step"].tolist() == expected_steps
        np.testing.assert_array_equal(arrays["robots"], np.asarray(strided["robots"]))

    table = api.client.get(f"/jobs/{job_id}/trajectory", params={"format": "csv"})
    assert table.headers["content-type"].startswith("text/csv")
    rows = list(csv.DictReader(io.StringIO(table.text)))
    robot_rows = [r for r in rows if r["kind"] == "robot"]
    assert len(robot_rows) == (length + 1) * 2
    assert float(robot_rows[-1]["x"]) == pytest.approx(full["robots"][-1][1][0])

    qtable = api.client.get(f"/jobs/{job_id}/qtable").json()
    values = np.asarray(qtable["values"])
    assert values.shape == (len(qtable["states"]), len(qtable["actions"]))
    assert np.asarray(qtable["visits"]).sum() > 0

    for plane in ("xy", "xz", "yz", "all"):
        response = api.client.get(f"/jobs/{job_id}/heatmap.png", params={"plane": plane})
        assert response.headers["content-type"] == "image/png"
        decode_png(response.content)
    for name in ("trajectory", "concentration", "learning"):
        response = api.client.get(f"/jobs/{job_id}/plots/{name}.png")
        assert response.headers["content-type"] == "image/png"
        decode_png(response.content)

    listed = api.client.get("/jobs", params={"status": "succeeded"}).json()
    assert [j["id"] for j in listed["jobs"]] == [job_id]


def test_cancel_stops_a_queued_job_at_once_and_a_running_one_within_a_second(
    api: Api, start_worker: Callable[..., Worker]
) -> None:
    worker = start_worker()
    running = submit(api, LONG)
    queued = submit(api, TINY)
    wait_for(api, running, lambda j: j["progress"]["episode"] >= 2, FIRST_JOB_S)

    cancelled = api.client.post(f"/jobs/{queued}/cancel").json()
    assert cancelled["status"] == "cancelled"

    asked = time.monotonic()
    response = api.client.post(f"/jobs/{running}/cancel")
    assert response.json()["cancel_requested"] is True
    job, _ = wait_for(api, running, finished, 10)
    took = time.monotonic() - asked
    assert job["status"] == "cancelled"
    assert took < 2.0, took
    assert job["progress"]["episode"] >= 2
    kept = api.store.partial_result(running)
    assert kept is not None and kept["completed"] is False
    assert len(kept["episodes"]) >= 2
    # what it kept is advertised and served; what it never made is neither
    links = job["links"]
    assert links["metrics"] and set(links["plots"]) == {"learning"}  # random walkers learn none
    assert links["trajectory"] is None and links["heatmap"] is None and links["qtable"] is None
    metrics = api.client.get(links["metrics"]).json()
    assert metrics["completed"] is False and len(metrics["episodes"]) >= 2
    decode_png(api.client.get(links["plots"]["learning"]).content)
    refused = api.client.get(f"/jobs/{running}/trajectory")
    assert refused.status_code == 409 and "cancelled before its evaluation" in refused.text
    assert api.client.get(f"/jobs/{queued}/metrics").status_code == 409  # it never started

    after = submit(api, TINY)
    job, _ = wait_for(api, after, finished, 60)
    assert job["status"] == "succeeded"
    assert api.store.get(queued).started_at is None
    assert worker.process.poll() is None


def test_a_failing_job_is_failed_with_a_readable_error_and_the_worker_lives_on(
    api: Api, start_worker: Callable[..., Worker]
) -> None:
    worker = start_worker()
    broken = api.store.enqueue({"robots": {"count": -1}}, robot_steps=1, episodes=1)
    job, _ = wait_for(api, broken.id, finished, FIRST_JOB_S)
    assert job["status"] == "failed"
    assert "robots.count" in job["error"]
    assert api.client.get(f"/jobs/{broken.id}/metrics").status_code == 409
    good = submit(api, TINY)
    assert wait_for(api, good, finished, 60)[0]["status"] == "succeeded"
    assert worker.process.poll() is None


def test_a_job_past_its_time_limit_is_failed_with_that_reason(
    api: Api, start_worker: Callable[..., Worker]
) -> None:
    start_worker(NANONAV_JOB_TIME_LIMIT_S="1.5")
    job_id = submit(api, LONG)
    job, _ = wait_for(api, job_id, finished, FIRST_JOB_S)
    assert job["status"] == "failed"
    assert "time limit of 1.5 s" in job["error"]
    assert job["finished_at"] is not None


def test_sigterm_gives_the_running_job_back_and_the_worker_exits(
    api: Api, start_worker: Callable[..., Worker]
) -> None:
    worker = start_worker()
    job_id = submit(api, LONG)
    wait_for(api, job_id, lambda j: j["progress"]["episode"] >= 1, FIRST_JOB_S)
    asked = time.monotonic()
    assert worker.terminate(timeout=15) == 0
    assert time.monotonic() - asked < 5
    job = api.client.get(f"/jobs/{job_id}").json()
    assert job["status"] == "queued"
    assert job["attempts"] == 0
    assert job["progress"]["fraction"] == 0.0
    api.client.post(f"/jobs/{job_id}/cancel")


def test_two_workers_run_fifty_jobs_each_exactly_once(
    api: Api, start_worker: Callable[..., Worker]
) -> None:
    workers = [start_worker(), start_worker()]
    for worker in workers:  # jobs take milliseconds: a late worker would find none left
        worker.wait_ready()
    ids = [
        submit(api, {"seed": i, "learning": {"episodes": i % 2, "max_steps": 50}})
        for i in range(50)
    ]
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline:
        page = api.client.get("/jobs", params={"status": "succeeded", "limit": 100}).json()
        if len(page["jobs"]) == len(ids):
            break
        assert all(w.process.poll() is None for w in workers)
        time.sleep(0.25)
    jobs = [api.client.get(f"/jobs/{i}").json() for i in ids]
    assert [j["status"] for j in jobs] == ["succeeded"] * 50
    assert [j["attempts"] for j in jobs] == [1] * 50
    for worker in workers:
        assert worker.terminate() == 0
    claims = [int(m) for w in workers for m in re.findall(r"job (\d+): claimed", w.text())]
    assert sorted(claims) == ids
    assert all(re.search(r"job \d+: claimed", w.text()) for w in workers)


def test_two_workers_share_one_postgresql_and_run_each_job_once(
    postgres_url: str, tmp_path: Path
) -> None:
    upgrade(postgres_url)
    store = JobStore.from_url(postgres_url)
    settings = Settings(database_url=postgres_url)
    workers: list[Worker] = []
    try:
        with (
            serve(create_app(settings)) as url,
            httpx.Client(base_url=url, timeout=30) as client,
        ):
            api = Api(url=url, client=client, database_url=postgres_url, store=store)
            workers = [Worker(postgres_url, tmp_path / f"pg-{i}.log") for i in range(2)]
            ids = [
                submit(api, {"seed": i, "learning": {"episodes": 0, "max_steps": 50}})
                for i in range(12)
            ]
            for job_id in ids:
                job, _ = wait_for(api, job_id, finished, FIRST_JOB_S)
                assert (job["status"], job["attempts"]) == ("succeeded", 1)
            decode_png(client.get(f"/jobs/{ids[-1]}/heatmap.png").content)
    finally:
        codes = [worker.terminate() for worker in workers]
        store.close()
    assert codes == [0, 0]
    claims = [int(m) for w in workers for m in re.findall(r"job (\d+): claimed", w.text())]
    assert sorted(claims) == ids


def test_healthz_counts_a_running_worker_and_forgets_it_when_it_stops(
    api: Api, start_worker: Callable[..., Worker]
) -> None:
    worker = start_worker()
    worker.wait_ready()
    deadline = time.monotonic() + 10
    while api.client.get("/healthz").json()["workers"]["seen"] != 1:
        assert time.monotonic() < deadline, worker.text()
        time.sleep(0.1)
    assert worker.terminate() == 0
    assert api.client.get("/healthz").json()["workers"]["seen"] == 0
