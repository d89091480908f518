"""Trajectory answers are bounded: large JSON is refused with the stride that fits, the .npz
is the stored file, and CSV streams."""

from __future__ import annotations

import csv
import io
import threading

import httpx
import numpy as np

from nanonav.settings import Settings
from nanonav.store import JobStatus, JobStore
from nanonav.store.arrays import unpack
from nanonav.store.migrate import upgrade
from service.app import create_app
from tests.conftest import serve
from worker.job import run_job

SCENARIO = {"robots": {"count": 4}, "learning": {"episodes": 0, "max_steps": 60}}


def test_trajectory_answers_are_bounded_and_say_how_to_get_the_rest(sqlite_url: str) -> None:
    settings = Settings(database_url=sqlite_url, trajectory_json_values=1000)
    upgrade(sqlite_url)
    store = JobStore.from_url(sqlite_url)
    job = store.enqueue(SCENARIO, robot_steps=1, episodes=1)
    claim = store.claim("test", lease_s=30)
    assert claim is not None
    record = run_job(store, claim, settings, threading.Event())
    assert record is not None and record.status is JobStatus.SUCCEEDED
    stored = store.trajectory(job.id)
    rows = stored["step"].shape[0]
    with serve(create_app(settings)) as url, httpx.Client(base_url=url, timeout=30) as client:
        refused = client.get(f"/jobs/{job.id}/trajectory")
        assert refused.status_code == 422
        problem = refused.json()
        assert problem["errors"][0]["parameter"] == "stride"
        assert "?stride=2 or more" in problem["detail"] and "format=npz" in problem["detail"]

        fits = client.get(f"/jobs/{job.id}/trajectory", params={"stride": 2})
        assert fits.status_code == 200, fits.text
        body = fits.json()
        assert body["step"][:3] == [0, 2, 4] and body["step"][-1] == int(stored["step"][-1])
        assert len(body["obstacles"]) == 1  # they stand still: recorded once
        assert len(body["robots"]) == len(body["step"])

        npz = client.get(f"/jobs/{job.id}/trajectory", params={"format": "npz"})
        assert npz.content == store.trajectory_npz(job.id)
        assert np.array_equal(unpack(npz.content)["robots"], stored["robots"])

        text = client.get(f"/jobs/{job.id}/trajectory", params={"format": "csv"}).text
        table = list(csv.DictReader(io.StringIO(text)))
        robots = [r for r in table if r["kind"] == "robot"]
        assert len(robots) == 4 * rows
        assert float(robots[-1]["x"]) == stored["robots"][-1, 3, 0]
        obstacles = [r for r in table if r["kind"] == "obstacle"]
        assert len(obstacles) == 10 and {r["step"] for r in obstacles} == {"0"}
    store.close()
