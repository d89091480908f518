"""The webhook outbox: a delivery waits for its job or study to end, is due with a summary
fixed then, is held by one sender at a time, and ends delivered or given up."""

from __future__ import annotations

import threading
from datetime import timedelta

from nanonav.store import JobStore, StudyJob, StudyStore
from nanonav.store.deliveries import Backlog, DeliveryStore
from nanonav.store.models import DeliveryState
from nanonav.store.queue import utcnow
from tests.store.test_queue import LEASE_S, claim, outcome

URL = "http://localhost:9000/hook"


def submit(store: JobStore, url: str | None = URL) -> int:
    job = store.enqueue({"seed": 1}, robot_steps=10, episodes=1, callback_url=url)
    return job.id


def test_a_job_with_a_callback_waits_until_it_ends_then_is_due_with_its_summary(
    store: JobStore,
) -> None:
    deliveries = DeliveryStore(store.engine)
    job_id = submit(store)
    assert submit(store, None) and deliveries.for_job(job_id + 1) is None
    waiting = deliveries.for_job(job_id)
    assert waiting is not None and waiting.state is DeliveryState.WAITING and waiting.url == URL
    assert deliveries.promote() == 0  # queued
    held = claim(store)
    assert deliveries.promote() == 0  # running
    store.finish(held, outcome())
    assert deliveries.promote() == 1
    due = deliveries.for_job(job_id)
    assert due is not None and due.state is DeliveryState.DUE and due.event == "job.succeeded"
    sent = deliveries.claim(lease_s=LEASE_S)
    assert sent is not None and sent.event == "job.succeeded" and sent.attempts == 0
    assert sent.payload["id"] == due.id and sent.payload["event"] == "job.succeeded"
    job = sent.payload["job"]
    assert job["id"] == job_id and job["status"] == "succeeded" and job["url"] == f"/jobs/{job_id}"
    assert job["summary"] == {"total_steps": 7}
    assert deliveries.claim(lease_s=LEASE_S) is None  # held: nobody else sends it


def test_cancelled_and_failed_jobs_send_their_own_events(store: JobStore) -> None:
    deliveries = DeliveryStore(store.engine)
    cancelled = submit(store)
    store.cancel(cancelled)
    failed = submit(store)
    store.fail(claim(store), "the scenario raised")
    assert deliveries.promote() == 2
    events = {deliveries.for_job(i).event for i in (cancelled, failed)}  # type: ignore[union-attr]
    assert events == {"job.cancelled", "job.failed"}


def test_a_failed_try_is_due_again_after_its_backoff_and_then_given_up(store: JobStore) -> None:
    deliveries = DeliveryStore(store.engine)
    job_id = submit(store)
    store.cancel(job_id)
    deliveries.promote()
    now = utcnow()
    first = deliveries.claim(lease_s=LEASE_S, now=now)
    assert first is not None
    assert deliveries.settle(first, status=500, error="HTTP 500", retry_in_s=60, now=now)
    record = deliveries.for_job(job_id)
    assert record is not None and record.state is DeliveryState.DUE and record.attempts == 1
    assert record.next_attempt_at == now + timedelta(seconds=60)
    assert record.last_status == 500 and record.last_error == "HTTP 500"
    assert deliveries.claim(lease_s=LEASE_S, now=now + timedelta(seconds=59)) is None
    second = deliveries.claim(lease_s=LEASE_S, now=now + timedelta(seconds=61))
    assert second is not None and second.attempts == 1
    assert deliveries.settle(second, status=None, error="timed out", retry_in_s=None)
    record = deliveries.for_job(job_id)
    assert record is not None and record.state is DeliveryState.FAILED and record.attempts == 2
    assert record.next_attempt_at is None
    assert deliveries.claim(lease_s=LEASE_S, now=now + timedelta(days=1)) is None


def test_a_delivered_webhook_is_never_sent_again_and_a_lost_lease_cannot_settle(
    store: JobStore,
) -> None:
    deliveries = DeliveryStore(store.engine)
    job_id = submit(store)
    store.cancel(job_id)
    deliveries.promote()
    now = utcnow()
    stalled = deliveries.claim(lease_s=5, now=now)
    assert stalled is not None
    taken_over = deliveries.claim(lease_s=5, now=now + timedelta(seconds=6))  # lease ran out
    assert taken_over is not None and taken_over.id == stalled.id
    assert not deliveries.settle(stalled, status=200, error=None, retry_in_s=None)
    assert deliveries.settle(taken_over, status=204, error=None, retry_in_s=None)
    record = deliveries.for_job(job_id)
    assert record is not None and record.state is DeliveryState.DELIVERED
    assert record.delivered_at is not None and record.attempts == 1
    assert deliveries.claim(lease_s=5, now=now + timedelta(days=1)) is None


def test_a_study_webhook_is_due_only_when_its_last_job_ends(store: JobStore) -> None:
    studies = StudyStore(store.engine)
    deliveries = DeliveryStore(store.engine)
    jobs = [StudyJob(scenario={"seed": s}, robot_steps=1, episodes=1, point=0, seed=s)
            for s in (1, 2)]  # fmt: skip
    study = studies.create(name="s", spec={}, jobs=jobs, callback_url=URL)
    store.finish(claim(store), outcome())
    assert deliveries.promote() == 0
    store.fail(claim(store), "boom")
    assert deliveries.promote() == 1
    sent = deliveries.claim(lease_s=LEASE_S)
    assert sent is not None and sent.event == "study.failed"
    assert sent.payload["study"]["jobs"]["succeeded"] == 1
    assert sent.payload["study"]["jobs"]["failed"] == 1
    assert sent.payload["study"]["url"] == f"/studies/{study.id}"


def test_promoters_in_parallel_make_each_delivery_due_once(store: JobStore) -> None:
    for _ in range(20):
        store.cancel(submit(store))
    promoters = [DeliveryStore(store.engine) for _ in range(4)]
    counts: list[int] = []
    threads = [threading.Thread(target=lambda p=p: counts.append(p.promote())) for p in promoters]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert sum(counts) == 20
    assert promoters[0].pending() == 20


def test_the_backlog_counts_what_is_due_since_when_and_when_a_sender_last_passed(
    store: JobStore,
) -> None:
    deliveries = DeliveryStore(store.engine)
    assert deliveries.backlog() == Backlog(due=0, retrying=0, oldest_due_at=None,
                                           last_pass_at=None)  # fmt: skip
    studies = StudyStore(store.engine)
    jobs = [StudyJob(scenario={"seed": s}, robot_steps=1, episodes=1, point=0, seed=s)
            for s in (1, 2)]  # fmt: skip
    studies.create(name="s", spec={}, jobs=jobs, callback_url=URL)
    store.finish(claim(store), outcome())  # the study goes on: its webhook is not due
    job_id = submit(store)
    store.cancel(job_id)  # ended: due, though no sender has made it so yet
    ended_at = store.get(job_id).finished_at
    backlog = deliveries.backlog()
    assert (backlog.due, backlog.retrying, backlog.oldest_due_at) == (1, 0, ended_at)
    now = utcnow()
    assert deliveries.promote(now=now) == 1
    assert deliveries.backlog(now=now).oldest_due_at == now
    held = deliveries.claim(lease_s=LEASE_S, now=now)
    assert held is not None
    deliveries.settle(held, status=500, error="HTTP 500", retry_in_s=60, now=now)
    backlog = deliveries.backlog(now=now + timedelta(seconds=1))
    assert (backlog.due, backlog.retrying, backlog.oldest_due_at) == (0, 1, None)
    backlog = deliveries.backlog(now=now + timedelta(seconds=61))
    assert (backlog.due, backlog.retrying) == (1, 0)
    assert backlog.oldest_due_at == now + timedelta(seconds=60)
    for name in ("host:1", "host:2"):
        store.worker_seen(name, started_at=now)
    deliveries.sender_passed("host:1", now=now + timedelta(seconds=2))
    deliveries.sender_passed("host:2", now=now + timedelta(seconds=3))
    deliveries.sender_passed("host:1", now=now + timedelta(seconds=1))
    assert deliveries.backlog().last_pass_at == now + timedelta(seconds=3)
