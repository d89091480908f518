"""Store faults are not simulation faults: a transient one (the write lock held past the busy
timeout) is waited out and the job goes on; a permanent one (a result the database will never
take) fails the job at once with its reason; neither says SQL, parameters or tokens."""

from __future__ import annotations

import logging
import sqlite3
import threading
import time
from pathlib import Path
from typing import Any

import pytest
from sqlalchemy.exc import DataError, OperationalError

from nanonav.settings import Settings
from nanonav.store import JobStatus, JobStore, Outcome
from nanonav.store.faults import is_permanent, is_transient, reason
from nanonav.store.migrate import upgrade
from worker.job import run_job

# About two seconds of simulation, with progress written every 0.1 s.
BUSY: dict[str, Any] = {"preset": "paper-swarm", "learning": {"episodes": 1500},
                        "evaluation": {"worlds": 2}}  # fmt: skip
TINY: dict[str, Any] = {"learning": {"episodes": 1, "max_steps": 30}, "evaluation": {"worlds": 1}}


def locked(message: str) -> OperationalError:
    return OperationalError("UPDATE jobs SET lease_token=?", {"token": "s3cret"},
                            sqlite3.OperationalError(message))  # fmt: skip


def too_big() -> DataError:
    return DataError("INSERT INTO job_results VALUES (?)", {"lease_token": "s3cret"},
                     sqlite3.DataError("string or blob too big"))  # fmt: skip


def test_faults_are_told_apart_and_described_without_sql() -> None:
    assert is_transient(locked("database is locked")) and not is_permanent(locked("x"))
    assert is_permanent(too_big()) and not is_transient(too_big())
    assert reason(too_big()) == "string or blob too big"
    assert "s3cret" not in reason(locked("database is locked"))


@pytest.fixture
def file_store(tmp_path: Path) -> tuple[JobStore, Settings, Path]:
    path = tmp_path / "nanonav.db"
    url = f"sqlite:///{path}"
    upgrade(url)
    settings = Settings(database_url=url, store_busy_timeout_s=0.1, progress_interval_s=0.1,
                        lease_s=15.0)  # fmt: skip
    return JobStore.from_url(url, busy_timeout_s=0.1), settings, path


def test_a_write_lock_held_past_the_busy_timeout_does_not_fail_the_job(
    file_store: tuple[JobStore, Settings, Path], caplog: pytest.LogCaptureFixture
) -> None:
    store, settings, path = file_store
    job = store.enqueue(BUSY, robot_steps=1, episodes=1502)
    claim = store.claim("test", lease_s=settings.lease_s)
    assert claim is not None
    holder = sqlite3.connect(path, isolation_level=None, timeout=5, check_same_thread=False)
    taken = threading.Event()

    def hold_the_lock() -> None:
        # once the run writes progress (after any compiling, however loaded the machine)
        waited = time.monotonic() + 120.0
        while time.monotonic() < waited:
            row = holder.execute("SELECT episode FROM jobs WHERE id = ?", (job.id,)).fetchone()
            if row is not None and row[0]:
                break
            time.sleep(0.02)
        holder.execute("BEGIN IMMEDIATE")
        taken.set()
        time.sleep(1.0)  # several progress writes, each waiting 0.1 s and giving up
        holder.execute("ROLLBACK")

    locker = threading.Thread(target=hold_the_lock)
    locker.start()
    with caplog.at_level(logging.WARNING):
        record = run_job(store, claim, settings, threading.Event())
    locker.join()
    holder.close()
    assert taken.is_set()
    assert record is not None and record.status is JobStatus.SUCCEEDED
    assert store.get(job.id).error is None and store.get(job.id).attempts == 1
    assert "progress not written (database is locked)" in caplog.text
    store.close()


def test_a_result_the_database_refuses_fails_the_job_at_once_with_the_reason(
    file_store: tuple[JobStore, Settings, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    store, settings, _ = file_store
    job = store.enqueue(TINY, robot_steps=1, episodes=2)
    claim = store.claim("test", lease_s=settings.lease_s)
    assert claim is not None
    tries: list[int] = []

    def refuse(*args: Any, **kwargs: Any) -> None:
        tries.append(1)
        raise too_big()

    monkeypatch.setattr(store, "finish", refuse)
    started = time.monotonic()
    record = run_job(store, claim, settings, threading.Event())
    assert time.monotonic() - started < 5  # not retried, not left for the lease to expire
    assert tries == [1]
    assert record is not None and record.status is JobStatus.FAILED
    error = store.get(job.id).error
    assert error == "its result could not be stored: string or blob too big"
    store.close()


def test_a_result_write_refused_for_a_moment_is_tried_again(
    file_store: tuple[JobStore, Settings, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    store, settings, _ = file_store
    store.enqueue(TINY, robot_steps=1, episodes=2)
    claim = store.claim("test", lease_s=settings.lease_s)
    assert claim is not None
    real = store.finish
    refusals = [locked("database is locked"), locked("database is locked")]

    def flaky(*args: Any, **kwargs: Any) -> Any:
        if refusals:
            raise refusals.pop()
        return real(*args, **kwargs)

    monkeypatch.setattr(store, "finish", flaky)
    record = run_job(store, claim, settings, threading.Event())
    assert record is not None and record.status is JobStatus.SUCCEEDED and not refusals
    store.close()


def test_a_connection_left_read_only_is_replaced(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'nanonav.db'}"
    upgrade(url)
    store = JobStore.from_url(url)
    with store.engine.connect() as connection:  # the pool keeps this connection, read-only
        connection.exec_driver_sql("PRAGMA query_only = 1")
    with pytest.raises(OperationalError, match="readonly"):
        store.enqueue({}, robot_steps=1, episodes=1)
    assert store.enqueue({}, robot_steps=1, episodes=1).id == 1  # a fresh connection
    assert store.writable()
    store.close()


def test_outcomes_are_plain_data() -> None:
    # what a worker hands the store can be pickled and compared (it crosses no process)
    outcome = Outcome(completed=True, metrics={}, trajectory=None, qtable=None)
    assert outcome == Outcome(completed=True, metrics={}, trajectory=None, qtable=None)
