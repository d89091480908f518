"""A job's or study's callback_url through the API: refused with 422 naming it unless the
server may call it, and its delivery readable at /callback."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from nanonav.settings import Settings
from nanonav.store import JobStore
from nanonav.store.deliveries import DeliveryStore
from nanonav.store.migrate import upgrade
from service.app import create_app
from tests.conftest import Api, serve, sqlite_url_in
from tests.service.test_api import assert_problem

SECRET = "kq3N9vTz0bX7mR2sW5yC8dF1gH4jL6pA"
HOOK = "https://hooks.example.org/nanonav"
STUDY = {
    "base": {"learning": {"episodes": 1, "max_steps": 10}},
    "grid": {"robots.count": [1, 2]},
    "seeds": [1],
}


@pytest.fixture
def api_settings(tmp_path: Path) -> Settings:
    return Settings(
        database_url=sqlite_url_in(tmp_path),
        webhook_hosts=("hooks.example.org",),
        webhook_secret=SECRET,
    )


def test_a_job_with_an_allowed_callback_has_a_waiting_delivery(api: Api) -> None:
    response = api.client.post("/jobs", params={"callback_url": HOOK}, json={})
    assert response.status_code == 202, response.text
    job_id = response.json()["id"]
    callback = api.client.get(f"/jobs/{job_id}/callback").json()
    assert callback["url"] == HOOK and callback["state"] == "waiting"
    assert callback["event"] is None and callback["attempts"] == 0
    api.client.post(f"/jobs/{job_id}/cancel")
    DeliveryStore(api.store.engine).promote()
    callback = api.client.get(f"/jobs/{job_id}/callback").json()
    assert callback["state"] == "due" and callback["event"] == "job.cancelled"
    assert callback["next_attempt_at"] is not None


@pytest.mark.parametrize(
    ("url", "why"),
    [
        ("https://attacker.example.com/x", "not among the hosts"),
        ("file:///etc/passwd", "not an http"),
        ("https://user:pw@hooks.example.org/", "user name or password"),
        ("https://hooks.example.org/" + "a" * 2100, "at most 2048 characters"),
        ("https://hooks.example.org../x", "empty label"),
        ("https://hooks.example.org/tab\there", "control character or space"),
        ("https://hooks.example.org:0/x", "not a port"),
    ],
)
def test_a_refused_callback_is_a_422_naming_it_and_stores_nothing(
    api: Api, url: str, why: str
) -> None:
    for path, body in (("/jobs", {}), ("/studies", STUDY)):
        problem = assert_problem(
            api.client.post(path, params={"callback_url": url}, json=body), 422
        )
        assert problem["errors"][0]["loc"] == ["query", "callback_url"]
        assert why in str(problem)
    assert api.client.get("/jobs").json()["jobs"] == []
    assert api.client.get("/studies").json()["studies"] == []


def test_a_callback_url_is_stored_and_answered_as_the_sender_will_send_it(api: Api) -> None:
    written = "https://HOOKS.Example.org:0443/a/../nanonav?@127.0.0.1"
    sent = "https://hooks.example.org/nanonav?@127.0.0.1"
    job = api.client.post("/jobs", params={"callback_url": written}, json={})
    study = api.client.post("/studies", params={"callback_url": written}, json=STUDY)
    assert job.status_code == study.status_code == 202, (job.text, study.text)
    assert api.client.get(f"/jobs/{job.json()['id']}/callback").json()["url"] == sent
    assert api.client.get(f"/studies/{study.json()['id']}/callback").json()["url"] == sent


def test_a_study_callback_is_read_at_the_study(api: Api) -> None:
    response = api.client.post("/studies", params={"callback_url": HOOK}, json=STUDY)
    assert response.status_code == 202, response.text
    study_id = response.json()["id"]
    callback = api.client.get(f"/studies/{study_id}/callback").json()
    assert callback["url"] == HOOK and callback["state"] == "waiting"


def test_without_a_callback_the_callback_route_is_404_saying_so(api: Api) -> None:
    job_id = api.client.post("/jobs", json={}).json()["id"]
    body = assert_problem(api.client.get(f"/jobs/{job_id}/callback"), 404)
    assert body["type"].endswith("no-callback") and "without a callback_url" in body["detail"]
    assert assert_problem(api.client.get("/jobs/999/callback"), 404)["type"].endswith(
        "job-not-found"
    )
    study_id = api.client.post("/studies", json=STUDY).json()["id"]
    assert_problem(api.client.get(f"/studies/{study_id}/callback"), 404)
    assert_problem(api.client.get("/studies/999/callback"), 404)


@pytest.fixture
def plain_api(sqlite_url: str) -> Iterator[Api]:
    settings = Settings(database_url=sqlite_url)
    upgrade(sqlite_url)
    store = JobStore.from_url(sqlite_url)
    with serve(create_app(settings)) as url, httpx.Client(base_url=url) as client:
        yield Api(url=url, client=client, database_url=sqlite_url, store=store)
    store.close()


def test_a_server_without_webhook_hosts_refuses_every_callback(plain_api: Api) -> None:
    problem = assert_problem(
        plain_api.client.post("/jobs", params={"callback_url": HOOK}, json={}), 422
    )
    assert "sends no webhooks" in problem["detail"]
