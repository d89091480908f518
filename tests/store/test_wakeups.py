"""Queueing a job wakes listening workers on PostgreSQL; on SQLite the wait is the poll."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import pytest
from sqlalchemy import text

from nanonav.store import JobStatus, JobStore, StudyJob, StudyStore
from nanonav.store import wakeups as wakeups_module
from nanonav.store.db import make_engine
from nanonav.store.wakeups import CHANNEL_NAME, Wakeups
from tests.conftest import migrated_store, postgres_schema

NEVER = threading.Event()


@pytest.fixture
def wakeups(store: JobStore) -> Iterator[Wakeups]:
    waiter = Wakeups(store.engine)
    waiter.listen()
    yield waiter
    waiter.close()


@pytest.fixture
def pg_store(postgres_url: str) -> Iterator[JobStore]:
    with migrated_store(postgres_url) as job_store:
        yield job_store


@pytest.fixture
def pg_wakeups(pg_store: JobStore) -> Iterator[Wakeups]:
    waiter = Wakeups(pg_store.engine)
    assert waiter.listen()
    yield waiter
    waiter.close()


def woken(wakeups: Wakeups, timeout_s: float = 2.0) -> tuple[bool, float]:
    started = time.monotonic()
    return wakeups.wait(timeout_s, NEVER), time.monotonic() - started


def test_a_queued_job_wakes_a_listener_at_once_on_postgresql_only(
    store: JobStore, wakeups: Wakeups
) -> None:
    store.enqueue({"seed": 1}, robot_steps=1, episodes=1)
    awake, waited = woken(wakeups, 0.5)
    if wakeups.listening:
        assert awake and waited < 0.1
    else:
        assert not awake and waited >= 0.5


def test_jobs_queued_while_a_worker_was_busy_wake_it_without_piling_up(
    store: JobStore, wakeups: Wakeups
) -> None:
    for seed in range(20):
        store.enqueue({"seed": seed}, robot_steps=1, episodes=1)
    assert woken(wakeups, 0.5)[0] is wakeups.listening
    later = [woken(wakeups, 0.3)[0] for _ in range(3)]
    assert later.count(True) <= 1  # one wake serves all that arrived together


def test_a_study_a_released_job_and_a_recovered_job_wake_listeners(
    pg_store: JobStore, pg_wakeups: Wakeups
) -> None:
    store, wakeups = pg_store, pg_wakeups
    jobs = [StudyJob({"seed": s}, robot_steps=1, episodes=1, point=0, seed=s) for s in range(2)]
    StudyStore(store.engine).create(name="s", spec={}, jobs=jobs)
    assert woken(wakeups)[0]

    claim = store.claim("w", lease_s=30)
    assert claim is not None
    assert not woken(wakeups, 0.2)[0]  # a claim queues nothing
    store.release(claim)
    assert woken(wakeups)[0]

    claim = store.claim("w", lease_s=-1)  # already expired: its worker is as good as dead
    assert claim is not None
    assert store.recover_expired(max_attempts=3) == 1
    assert store.get(claim.job.id).status is JobStatus.QUEUED
    assert woken(wakeups)[0]


def test_stores_in_other_schemas_do_not_wake_each_other(
    pg_store: JobStore, pg_wakeups: Wakeups
) -> None:
    with postgres_schema() as elsewhere, migrated_store(elsewhere) as other:
        other.enqueue({"seed": 1}, robot_steps=1, episodes=1)
        assert not woken(pg_wakeups, 0.3)[0]
        pg_store.enqueue({"seed": 1}, robot_steps=1, episodes=1)
        assert woken(pg_wakeups)[0]


def test_a_stop_request_ends_the_wait_promptly(store: JobStore, wakeups: Wakeups) -> None:
    stop = threading.Event()
    threading.Timer(0.2, stop.set).start()
    started = time.monotonic()
    assert not wakeups.wait(30.0, stop)
    assert time.monotonic() - started < 1.5


def test_an_unreachable_server_means_polling_not_failing() -> None:
    engine = make_engine("postgresql+psycopg://postgres@127.0.0.1:1/none?connect_timeout=1")
    waiter = Wakeups(engine)
    assert not waiter.listen()
    started = time.monotonic()
    assert not waiter.wait(0.3, NEVER)
    assert 0.25 < time.monotonic() - started < 1.0
    engine.dispose()


def test_postgresql_writes_wait_for_a_lock_as_long_as_the_busy_timeout(
    postgres_url: str,
) -> None:
    with migrated_store(postgres_url):
        store = JobStore.from_url(postgres_url, busy_timeout_s=0.25)
        with store.engine.connect() as connection:
            assert connection.execute(text("SHOW lock_timeout")).scalar() == "250ms"
        store.close()


def test_a_dropped_listening_connection_is_opened_again(
    pg_store: JobStore, pg_wakeups: Wakeups, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(wakeups_module, "RECONNECT_S", 0.1)
    with pg_store.engine.connect() as connection:
        channel = connection.execute(text(f"SELECT {CHANNEL_NAME}")).scalar()
        killed = connection.execute(
            text("SELECT count(pg_terminate_backend(pid)) FROM pg_stat_activity "
                 "WHERE application_name = 'nanonav-listener' AND query = :listen"),
            {"listen": f'LISTEN "{channel}"'},
        ).scalar()  # fmt: skip
    assert killed == 1
    assert not woken(pg_wakeups, 0.5)[0]  # the loss is noticed; the clock still wakes it
    time.sleep(0.15)
    assert pg_wakeups.listen()  # the next look opens another connection
    pg_store.enqueue({"seed": 1}, robot_steps=1, episodes=1)
    assert woken(pg_wakeups)[0]
