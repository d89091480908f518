"""Sending webhooks to a real HTTP receiver on this machine: signed, retried after failures,
given up after the last attempt, and refused when the allow-list no longer permits them."""

from __future__ import annotations

import json
import time
from urllib.parse import urlsplit

import httpx

from nanonav.settings import Settings
from nanonav.store import JobStore
from nanonav.store.deliveries import DeliveryStore
from nanonav.store.models import DeliveryState
from nanonav.webhooks import verify
from tests.receiver import receiving
from worker.deliveries import deliver_due

SECRET = "kq3N9vTz0bX7mR2sW5yC8dF1gH4jL6pA"


def settings_for(url: str, **changes: object) -> Settings:
    host = urlsplit(url).netloc
    return Settings(webhook_hosts=(host,), webhook_secret=SECRET, **changes)  # type: ignore[arg-type]


def ended_job(store: JobStore, url: str) -> int:
    job = store.enqueue({"seed": 3}, robot_steps=1, episodes=1, callback_url=url)
    store.cancel(job.id)
    return job.id


def test_a_webhook_is_posted_signed_with_its_event_and_summary(store: JobStore) -> None:
    deliveries = DeliveryStore(store.engine)
    with receiving() as receiver, httpx.Client() as client:
        job_id = ended_job(store, receiver.url + "?who=me")
        assert deliver_due(deliveries, settings_for(receiver.url), client) == 1
        (got,) = receiver.wait_for(1)
    assert got.path == "/hook?who=me"
    assert got.headers["content-type"] == "application/json"
    assert got.headers["nanonav-event"] == "job.cancelled"
    verify(SECRET, got.headers["nanonav-signature"], got.body, now=time.time())
    body = json.loads(got.body)
    record = deliveries.for_job(job_id)
    assert record is not None and record.state is DeliveryState.DELIVERED
    assert body["id"] == record.id == int(got.headers["nanonav-delivery"])
    assert body["event"] == "job.cancelled" and body["job"]["id"] == job_id
    assert record.last_status == 200 and record.attempts == 1


def test_a_receiver_that_fails_gets_the_same_body_again_after_a_backoff(
    store: JobStore,
) -> None:
    deliveries = DeliveryStore(store.engine)
    with receiving(statuses=[503, 500, 204]) as receiver, httpx.Client() as client:
        job_id = ended_job(store, receiver.url)
        settings = settings_for(receiver.url, webhook_retry_s=0.2)
        assert deliver_due(deliveries, settings, client) == 1
        record = deliveries.for_job(job_id)
        assert record is not None and record.state is DeliveryState.DUE
        assert record.last_error == "the receiver answered HTTP 503"
        assert deliver_due(deliveries, settings, client) == 0  # not before its backoff
        deadline = time.monotonic() + 10
        while len(receiver.got) < 3 and time.monotonic() < deadline:
            deliver_due(deliveries, settings, client)
            time.sleep(0.05)
        got = receiver.wait_for(3)
    assert got[0].body == got[1].body == got[2].body
    assert len({g.headers["nanonav-delivery"] for g in got}) == 1
    record = deliveries.for_job(job_id)
    assert record is not None and record.state is DeliveryState.DELIVERED
    assert record.attempts == 3 and record.last_status == 204 and record.last_error is None


def test_a_webhook_is_given_up_after_its_last_attempt(store: JobStore) -> None:
    deliveries = DeliveryStore(store.engine)
    with receiving(statuses=[500]) as receiver, httpx.Client() as client:
        job_id = ended_job(store, receiver.url)
        settings = settings_for(receiver.url, webhook_retry_s=0.01, webhook_attempts=2)
        deadline = time.monotonic() + 10
        while len(receiver.got) < 2 and time.monotonic() < deadline:
            deliver_due(deliveries, settings, client)
            time.sleep(0.02)
        deliver_due(deliveries, settings, client)
    assert len(receiver.got) == 2
    record = deliveries.for_job(job_id)
    assert record is not None and record.state is DeliveryState.FAILED and record.attempts == 2


def test_a_silent_receiver_times_out_and_a_closed_port_fails_without_blocking(
    store: JobStore,
) -> None:
    deliveries = DeliveryStore(store.engine)
    with receiving(delay_s=2.0) as slow, httpx.Client(timeout=0.3) as client:
        slow_job = ended_job(store, slow.url)
        started = time.monotonic()
        deliver_due(deliveries, settings_for(slow.url, webhook_timeout_s=0.3), client)
        assert time.monotonic() - started < 1.5
    record = deliveries.for_job(slow_job)
    assert record is not None and record.state is DeliveryState.DUE
    assert record.last_error is not None and "no answer within" in record.last_error
    closed = slow.url  # the receiver has stopped: nothing listens there now
    with httpx.Client(timeout=1) as client:
        job_id = ended_job(store, closed.replace("/hook", "/other"))
        deliver_due(deliveries, settings_for(closed, webhook_retry_s=3600), client)
    record = deliveries.for_job(job_id)
    assert record is not None and record.last_error is not None
    assert record.last_error.startswith("could not connect")


def test_a_host_taken_off_the_allow_list_is_never_called(store: JobStore) -> None:
    deliveries = DeliveryStore(store.engine)
    with receiving() as receiver, httpx.Client() as client:
        job_id = ended_job(store, receiver.url)
        deliver_due(deliveries, settings_for("http://hooks.example.org"), client)
    assert receiver.got == []
    record = deliveries.for_job(job_id)
    assert record is not None and record.state is DeliveryState.FAILED
    assert record.last_error is not None and "not among the hosts" in record.last_error
