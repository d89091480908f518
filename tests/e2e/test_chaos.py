"""Chaos, as an operator meets it: 100 jobs through 3 real workers that are SIGKILLed at random
(mostly in the middle of a job) and restarted, while the store's write lock is once held past
the workers' busy timeout. Every job must end succeeded, exactly once, none lost, none failed."""

from __future__ import annotations

import random
import signal
import sqlite3
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from itertools import islice
from pathlib import Path
from typing import Any

from sqlalchemy import create_engine, func, select, text
from sqlalchemy.engine import make_url
from sqlalchemy.exc import SQLAlchemyError

from nanonav.store import JobStatus, JobStore
from nanonav.store.faults import is_transient, reason
from nanonav.store.models import Job, JobResult
from tests.conftest import migrated_store
from tests.processes import Worker

JOBS = 100
WORKERS = 3
KILLS = 4
LOCK_HELD_S = 2.0  # four times the workers' busy timeout
WORKER_SETTINGS = {
    "NANONAV_LEASE_S": "4",  # a killed worker's job runs again within about 4 + 3 s
    "NANONAV_STORE_BUSY_TIMEOUT_S": "0.5",
    "NANONAV_MAX_ATTEMPTS": "20",  # kills are what this test is about: none may fail a job
    "NANONAV_PROGRESS_INTERVAL_S": "0.1",
    "NANONAV_POLL_INTERVAL_S": "0.1",
}
# About a tenth of a second of simulation each on an idle core, writing progress as it goes.
JOB: dict[str, Any] = {"preset": "paper-swarm", "learning": {"episodes": 150},
                       "evaluation": {"worlds": 2}}  # fmt: skip
TIME_LIMIT_S = 120.0  # 15 s a database on a quiet machine, 35-65 s on a busy one


@contextmanager
def write_lock_held(database_url: str) -> Iterator[None]:
    """The store's write lock, taken by another connection for as long as the block runs:
    SQLite's with BEGIN IMMEDIATE, PostgreSQL's as an exclusive lock on the jobs table."""
    url = make_url(database_url)
    if url.get_backend_name() == "sqlite":
        holder = sqlite3.connect(str(url.database), isolation_level=None, timeout=10)
        holder.execute("BEGIN IMMEDIATE")
        try:
            yield
        finally:
            holder.execute("ROLLBACK")
            holder.close()
        return
    engine = create_engine(url)
    try:
        with engine.begin() as connection:
            connection.execute(text("LOCK TABLE jobs IN ACCESS EXCLUSIVE MODE"))
            yield
    finally:
        engine.dispose()


def running_owners(store: JobStore) -> set[str]:
    with store.engine.connect() as connection:
        query = select(Job.lease_owner).where(Job.status == JobStatus.RUNNING)
        return {owner for (owner,) in connection.execute(query) if owner}


def test_killed_workers_and_a_held_write_lock_lose_and_fail_nothing(
    database_url: str, tmp_path: Path
) -> None:
    rng = random.Random(20261201)
    started = time.monotonic()
    with migrated_store(database_url) as store:
        serial = iter(range(1000))

        def start() -> Worker:
            log = tmp_path / f"worker-{next(serial)}.log"
            return Worker(database_url, log, **WORKER_SETTINGS)

        workers = [start() for _ in range(WORKERS)]
        try:
            for worker in workers:
                worker.wait_ready()
            # Jobs are fed as the chaos needs them, so that a fast machine cannot finish the
            # queue before every kill is made: half at first, more whenever it runs low.
            seeds = iter(range(JOBS))
            jobs: list[int] = []

            def feed(count: int) -> None:
                for seed in islice(seeds, count):
                    jobs.append(store.enqueue({**JOB, "seed": seed}, robot_steps=1,
                                              episodes=152).id)  # fmt: skip

            feed(JOBS // 2)
            kills = 0
            locked = False
            while kills < KILLS:
                time.sleep(rng.uniform(0.1, 0.6))
                queued = store.census(seen_within_s=60).queued
                if queued < WORKERS * 2 and len(jobs) < JOBS:
                    # jobs of a tenth of a second each: fed only once the queue ran dry, a
                    # quiet machine finished them all between looks before four kills
                    feed(WORKERS * 3)
                    continue
                owners = running_owners(store)
                busy = [w for w in workers if any(o.endswith(f":{w.process.pid}") for o in owners)]
                if not busy:
                    if queued == 0 and len(jobs) == JOBS:
                        break  # every job ran before every kill was made
                    continue
                victim = rng.choice(busy)
                victim.process.send_signal(signal.SIGKILL)
                victim.process.wait()
                victim.terminate()
                workers[workers.index(victim)] = start()
                kills += 1
                if not locked:  # while the other workers are at work
                    with write_lock_held(database_url):
                        time.sleep(LOCK_HELD_S)
                    locked = True
            feed(JOBS)
            assert kills == KILLS and locked, "the jobs ran out before the chaos was made"

            deadline = started + TIME_LIMIT_S
            while True:
                states = {job.id: job for job in store.page(status=None, limit=JOBS,
                                                            before_id=None).jobs}  # fmt: skip
                done = [j for j in states.values() if j.status not in
                        (JobStatus.QUEUED, JobStatus.RUNNING)]  # fmt: skip
                if len(done) == JOBS:
                    break
                assert time.monotonic() < deadline, f"{len(done)} of {JOBS} jobs ended in time"
                time.sleep(0.2)
            elapsed = time.monotonic() - started
        finally:
            for worker in workers:
                worker.terminate()
        logs = "".join(path.read_text() for path in tmp_path.glob("worker-*.log"))

        assert sorted(states) == sorted(jobs)
        assert [j.id for j in states.values() if j.status is not JobStatus.SUCCEEDED] == []
        assert [j.error for j in states.values() if j.error is not None] == []
        with store.engine.connect() as connection:
            rows = connection.execute(
                select(JobResult.job_id, func.count()).group_by(JobResult.job_id)
            ).all()
        assert sorted(job_id for job_id, _ in rows) == sorted(jobs)  # none lost
        assert {n for _, n in rows} == {1}  # none written twice
        attempts = [j.attempts for j in states.values()]
        assert min(attempts) >= 1
        # Each kill costs at most the one job its worker held; the held lock costs nothing.
        assert sum(a - 1 for a in attempts) <= kills, attempts
        assert "database is locked" in logs or "lock timeout" in logs  # the lock was felt
        print(f"\n{make_url(database_url).get_backend_name()}: {JOBS} jobs, {kills} kills, "
              f"{sum(a - 1 for a in attempts)} runs again, lock held {LOCK_HELD_S} s: "
              f"all succeeded in {elapsed:.1f} s")  # fmt: skip
        assert elapsed < TIME_LIMIT_S


def test_the_lock_holder_blocks_writes_past_the_busy_timeout(database_url: str) -> None:
    """The chaos test's lock really is the write lock the workers wait for."""
    with migrated_store(database_url):
        store = JobStore.from_url(database_url, busy_timeout_s=0.2)
        faults: list[SQLAlchemyError] = []

        def write() -> None:
            try:
                store.enqueue({"seed": 0}, robot_steps=1, episodes=1)
            except SQLAlchemyError as error:
                faults.append(error)

        with write_lock_held(database_url):
            writer = threading.Thread(target=write)
            writer.start()
            writer.join(timeout=5)
        store.close()
        assert len(faults) == 1 and is_transient(faults[0])
        assert "lock" in reason(faults[0])
