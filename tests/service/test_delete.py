"""DELETE of jobs and studies over a real server, on SQLite and on PostgreSQL: 204 for what has
ended, and then 404 for it and everything it had; 409 for what has not, or for a study's job."""

from __future__ import annotations

import threading
import time
from typing import Any

import pytest

from nanonav.settings import Settings
from nanonav.store import Outcome
from tests.conftest import Api
from tests.service.conftest import TINY, ran
from tests.service.test_api import assert_problem
from tests.service.test_event_streams import STUDY, Reader, claim, finish
from worker.job import run_job

pytestmark = pytest.mark.timeout(120)
POLL_S = 1.0


@pytest.fixture
def api_settings(database_url: str) -> Settings:
    return Settings(database_url=database_url, max_body_bytes=64 * 1024, events_poll_s=POLL_S)


def submitted(api: Api, scenario: dict[str, Any] = TINY) -> int:
    response = api.client.post("/jobs", json=scenario)
    assert response.status_code == 202
    job_id: int = response.json()["id"]
    return job_id


def run_all(api: Api, settings: Settings) -> None:
    """Run every queued job to its end in this process, as a worker would."""
    while (claimed := api.store.claim("test", lease_s=30)) is not None:
        assert run_job(api.store, claimed, settings, threading.Event()) is not None


def test_a_finished_job_is_deleted_with_its_results_and_pictures(
    api: Api, api_settings: Settings
) -> None:
    job_id = ran(api.store, api_settings, TINY)
    kept = ran(api.store, api_settings, TINY)
    assert api.client.get(f"/jobs/{job_id}/plots/learning.png").status_code == 200
    response = api.client.delete(f"/jobs/{job_id}")
    assert response.status_code == 204 and response.content == b""
    for path in ("", "/metrics", "/trajectory", "/qtable", "/plots/learning.png", "/callback"):
        problem = assert_problem(api.client.get(f"/jobs/{job_id}{path}"), 404)
        assert problem["detail"] == f"there is no job {job_id}"
    again = assert_problem(api.client.delete(f"/jobs/{job_id}"), 404)
    assert again["type"].endswith("job-not-found")
    assert [j["id"] for j in api.client.get("/jobs").json()["jobs"]] == [kept]
    assert api.client.get(f"/jobs/{kept}/metrics").status_code == 200


def test_a_queued_or_running_job_is_409_until_it_has_ended(api: Api) -> None:
    running = submitted(api)
    claimed = claim(api)
    queued = submitted(api)
    for job_id, status in ((queued, "queued"), (running, "running")):
        problem = assert_problem(api.client.delete(f"/jobs/{job_id}"), 409)
        assert problem["type"].endswith("job-not-finished")
        assert problem["detail"].startswith(f"job {job_id} is {status}: cancel it first")
    assert api.client.post(f"/jobs/{queued}/cancel").json()["status"] == "cancelled"
    assert api.client.delete(f"/jobs/{queued}").status_code == 204
    finish(api, claimed)
    assert api.client.delete(f"/jobs/{running}").status_code == 204
    assert api.client.get("/jobs").json()["jobs"] == []


def test_an_ended_study_is_deleted_with_its_jobs_report_and_pictures(
    api: Api, api_settings: Settings
) -> None:
    created = api.client.post("/studies", json=STUDY)
    assert created.status_code == 202
    study_id = created.json()["id"]
    jobs = [j["id"] for j in api.client.get(f"/jobs?study={study_id}").json()["jobs"]]
    assert len(jobs) == 2
    problem = assert_problem(api.client.delete(f"/studies/{study_id}"), 409)
    assert problem["type"].endswith("study-not-finished")
    assert "2 job(s) queued or running: cancel it first" in problem["detail"]

    run_all(api, api_settings)
    assert api.client.get(f"/studies/{study_id}").json()["status"] == "succeeded"
    assert api.client.get(f"/studies/{study_id}/plots/learning.png").status_code == 200
    problem = assert_problem(api.client.delete(f"/jobs/{jobs[0]}"), 409)
    assert problem["type"].endswith("job-in-study")
    assert f"delete the study instead (DELETE /studies/{study_id})" in problem["detail"]

    assert api.client.delete(f"/studies/{study_id}").status_code == 204
    for path in ("", "/results.csv", "/plots/learning.png", "/callback"):
        assert_problem(api.client.get(f"/studies/{study_id}{path}"), 404)
    for job_id in jobs:
        assert_problem(api.client.get(f"/jobs/{job_id}"), 404)
    gone = assert_problem(api.client.get(f"/jobs?study={study_id}"), 404)
    assert gone["detail"] == f"there is no study {study_id}"
    assert api.client.get("/studies").json()["studies"] == []
    assert_problem(api.client.delete(f"/studies/{study_id}"), 404)


def test_a_cancelled_study_can_be_deleted_once_its_running_job_stops(api: Api) -> None:
    study_id = api.client.post("/studies", json=STUDY).json()["id"]
    running = claim(api)
    assert api.client.post(f"/studies/{study_id}/cancel").status_code == 200
    problem = assert_problem(api.client.delete(f"/studies/{study_id}"), 409)
    assert "1 job(s) queued or running" in problem["detail"]
    api.store.finish(running, Outcome(completed=False, metrics={}, trajectory=None, qtable=None))
    assert api.client.delete(f"/studies/{study_id}").status_code == 204


@pytest.mark.parametrize(
    ("path", "name"),
    [("/jobs/0", "job_id"), ("/jobs/x", "job_id"), ("/studies/0", "study_id"),
     ("/studies/-1", "study_id")],
)  # fmt: skip
def test_an_id_that_cannot_exist_is_a_422_naming_it(api: Api, path: str, name: str) -> None:
    problem = assert_problem(api.client.delete(path), 422)
    assert [e["parameter"] for e in problem["errors"]] == [name]


def test_the_delete_routes_document_their_answers(api: Api) -> None:
    paths = api.client.get("/openapi.json").json()["paths"]
    for path in ("/jobs/{job_id}", "/studies/{study_id}"):
        answers = paths[path]["delete"]["responses"]
        assert set(answers) == {"204", "403", "404", "409", "415", "422"}
        assert "content" not in answers["204"]


def test_the_event_stream_of_a_job_deleted_under_it_ends(api: Api) -> None:
    job_id = submitted(api)
    claimed = claim(api)
    stream = Reader(api.url, f"/jobs/{job_id}/events")
    first = stream.event()
    assert first is not None and first.json()["status"] == "running"
    time.sleep(POLL_S / 4)  # watched now; the next read comes after the job is gone
    finish(api, claimed)
    assert api.client.delete(f"/jobs/{job_id}").status_code == 204
    assert stream.event() is None and stream.ended()
    assert_problem(api.client.get(f"/jobs/{job_id}/events"), 404)
    assert api.store.get_many([job_id]) == {}
