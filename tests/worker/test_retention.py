"""A worker with a retention deletes, from its sweeper thread, what ended before it: whether it
runs a job or waits, and never what has not ended."""

from __future__ import annotations

import threading
import time
from datetime import UTC, datetime, timedelta

import pytest

from nanonav.store import JobNotFound, JobStatus, JobStore, RetentionStore, StudyStore
from tests.store.test_queue import claim, enqueue
from tests.store.test_retention import finish_study, rows, succeeded
from tests.worker.test_job import settings_for
from worker import loop

LONG_AGO = datetime.now(UTC) - timedelta(days=10)


def test_the_sweeper_deletes_what_ended_longer_ago_than_the_retention(
    store: JobStore, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(loop, "RECOVERY_INTERVAL_S", 0.05)
    studies = StudyStore(store.engine)
    old = succeeded(store, at=LONG_AGO)
    old_study = finish_study(store, studies, 2, at=LONG_AGO)
    recent = succeeded(store, at=datetime.now(UTC) - timedelta(hours=1))
    running = enqueue(store)
    claim(store, now=datetime.now(UTC))  # a running job of another worker, long started
    settings = settings_for(store, retention_days=2, poll_interval_s=0.05)
    shutdown = threading.Event()
    worker = threading.Thread(target=loop.work, args=(settings, shutdown))
    worker.start()
    try:
        deadline = time.monotonic() + 20
        while rows(store)["studies"] and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        shutdown.set()
        worker.join(timeout=30)
    with pytest.raises(JobNotFound):
        store.get(old)
    assert rows(store)["studies"] == 0, f"study {old_study} was kept"
    assert store.get(recent).status is JobStatus.SUCCEEDED
    assert store.get(running.id).status is JobStatus.RUNNING
    assert rows(store)["job_results"] == 1


def test_a_pass_takes_a_bounded_number_of_batches_and_the_next_goes_on(
    store: JobStore, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(loop, "RETENTION_BATCH", 2)
    monkeypatch.setattr(loop, "RETENTION_BATCHES", 2)
    # the count of batches is what is checked, not the pass's time (one batch on PostgreSQL
    # took over the pass's second once while the suite compiled)
    monkeypatch.setattr(loop, "RETENTION_PASS_S", 600.0)
    for _ in range(5):
        succeeded(store, at=LONG_AGO)
    settings = settings_for(store, retention_days=1)
    retention = RetentionStore(store.engine)
    passes = [loop.expire(retention, settings, threading.Event()) for _ in range(3)]
    assert passes == [(4, False), (1, True), (0, True)]
    assert rows(store)["jobs"] == 0


def test_a_pass_over_its_time_stops_after_the_batch_under_way(
    store: JobStore, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(loop, "RETENTION_BATCH", 2)
    monkeypatch.setattr(loop, "RETENTION_PASS_S", 0.0)
    for _ in range(3):
        succeeded(store, at=LONG_AGO)
    settings = settings_for(store, retention_days=1)
    retention = RetentionStore(store.engine)
    passes = [loop.expire(retention, settings, threading.Event()) for _ in range(3)]
    assert passes == [(2, False), (1, False), (0, True)]


def test_without_a_retention_nothing_is_deleted(
    store: JobStore, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(loop, "RECOVERY_INTERVAL_S", 0.05)
    old = succeeded(store, at=LONG_AGO)
    shutdown = threading.Event()
    worker = threading.Thread(
        target=loop.work, args=(settings_for(store, poll_interval_s=0.05), shutdown)
    )
    worker.start()
    time.sleep(0.5)  # about ten sweeps
    shutdown.set()
    worker.join(timeout=30)
    assert store.get(old).status is JobStatus.SUCCEEDED
