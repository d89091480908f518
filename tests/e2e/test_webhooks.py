"""Webhooks end to end: the API takes a callback_url, a real worker process runs the job and
POSTs the signed summary to a real receiver, for a job and for a study; one webhook it cannot
send is a failed try and the others still go; /healthz shows the sender at work."""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from urllib.parse import urlsplit

import pytest
from sqlalchemy import update

from nanonav.settings import Settings
from nanonav.store.models import Delivery
from nanonav.webhooks import verify
from tests.conftest import Api, sqlite_url_in
from tests.processes import Worker
from tests.receiver import Receiver, receiving

SECRET = "kq3N9vTz0bX7mR2sW5yC8dF1gH4jL6pA"
TINY = {"robots": {"count": 1}, "learning": {"episodes": 1, "max_steps": 30}}
LOCAL = "127.0.0.0/8,::1"  # the receiver listens on this machine


@pytest.fixture
def receiver() -> Iterator[Receiver]:
    with receiving() as running:
        yield running


@pytest.fixture
def api_settings(tmp_path: Path, receiver: Receiver) -> Settings:
    return Settings(
        database_url=sqlite_url_in(tmp_path),
        webhook_hosts=(urlsplit(receiver.url).netloc,),
        webhook_secret=SECRET,
        webhook_addresses=LOCAL,
    )


def sending_worker(start_worker: Callable[..., Worker], receiver: Receiver) -> Worker:
    return start_worker(
        NANONAV_WEBHOOK_HOSTS=urlsplit(receiver.url).netloc,
        NANONAV_WEBHOOK_SECRET=SECRET,
        NANONAV_WEBHOOK_ADDRESSES=LOCAL,
    )


def test_a_worker_posts_signed_summaries_when_a_job_and_a_study_end(
    api: Api, receiver: Receiver, start_worker: Callable[..., Worker]
) -> None:
    worker = sending_worker(start_worker, receiver)
    job = api.client.post("/jobs", params={"callback_url": receiver.url + "?job"}, json=TINY)
    study = api.client.post(
        "/studies",
        params={"callback_url": receiver.url + "?study"},
        json={"base": TINY, "grid": {"robots.count": [1, 2]}, "seeds": [1]},
    )
    assert job.status_code == 202 and study.status_code == 202, (job.text, study.text)
    worker.wait_ready()
    got = receiver.wait_for(2, timeout_s=60)
    by_path = {g.path: g for g in got}
    assert set(by_path) == {"/hook?job", "/hook?study"}
    for g in got:
        assert abs(verify(SECRET, g.headers["nanonav-signature"], g.body) - time.time()) < 60
    job_body = json.loads(by_path["/hook?job"].body)
    assert job_body["event"] == "job.succeeded" and job_body["job"]["id"] == job.json()["id"]
    assert job_body["job"]["summary"]["robots"] == 1
    study_body = json.loads(by_path["/hook?study"].body)
    assert study_body["event"] == "study.succeeded"
    assert study_body["study"]["jobs"]["succeeded"] == 2
    callback = api.client.get(f"/jobs/{job.json()['id']}/callback").json()
    assert callback["state"] == "delivered" and callback["last_status"] == 200


def test_a_worker_goes_on_sending_webhooks_after_one_it_cannot_send(
    api: Api, receiver: Receiver, start_worker: Callable[..., Worker]
) -> None:
    stuck = api.store.enqueue({}, robot_steps=1, episodes=1, callback_url=receiver.url)
    api.store.cancel(stuck.id)
    with api.store.engine.begin() as connection:  # as a check before today's let it through
        connection.execute(
            update(Delivery)
            .where(Delivery.job_id == stuck.id)
            .values(url=f"http://localhost..:{receiver.port}/hook")
        )
    worker = sending_worker(start_worker, receiver)
    job = api.client.post("/jobs", params={"callback_url": receiver.url + "?after"}, json=TINY)
    assert job.status_code == 202, job.text
    worker.wait_ready()
    (got,) = receiver.wait_for(1, timeout_s=60)
    assert got.path == "/hook?after"
    callback = api.client.get(f"/jobs/{stuck.id}/callback").json()
    assert callback["state"] == "failed" and callback["attempts"] == 1
    assert "empty label" in callback["last_error"]
    deadline = time.monotonic() + 30
    while (webhooks := api.client.get("/healthz").json()["webhooks"])["last_pass_at"] is None:
        assert time.monotonic() < deadline, worker.text()
        time.sleep(0.1)
    assert webhooks["due"] == 0 and webhooks["retrying"] == 0
    assert "Traceback" not in worker.text()
