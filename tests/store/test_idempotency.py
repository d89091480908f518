"""Idempotency keys in the store: a key names one request until it expires."""

from __future__ import annotations

import threading
import time

import pytest

from nanonav.store import (
    Idempotency,
    IdempotencyKeyReused,
    JobRecord,
    JobStore,
    StudyJob,
    StudyStore,
)

DAY = 86400.0


def enqueue(store: JobStore, seed: int, key: Idempotency | None) -> JobRecord:
    return store.enqueue({"seed": seed}, robot_steps=100, episodes=2, idempotency=key)


def test_the_same_request_under_a_key_gets_the_job_it_made(store: JobStore) -> None:
    key = Idempotency("abc", "digest-1", DAY)
    first = enqueue(store, 1, key)
    again = enqueue(store, 1, key)
    assert again.id == first.id
    assert enqueue(store, 1, Idempotency("other", "digest-1", DAY)).id != first.id
    assert len(store.page(status=None, limit=10, before_id=None).jobs) == 2


def test_another_request_under_a_key_is_refused(store: JobStore) -> None:
    first = enqueue(store, 1, Idempotency("abc", "digest-1", DAY))
    with pytest.raises(IdempotencyKeyReused, match=f"job {first.id}"):
        enqueue(store, 2, Idempotency("abc", "digest-2", DAY))
    assert len(store.page(status=None, limit=10, before_id=None).jobs) == 1


def test_an_expired_key_makes_a_new_job_and_the_old_one_forgets_it(store: JobStore) -> None:
    first = enqueue(store, 1, Idempotency("abc", "digest-1", DAY))
    time.sleep(0.05)
    fresh = enqueue(store, 2, Idempotency("abc", "digest-2", 0.01))
    assert fresh.id != first.id
    assert fresh.idempotency_key == "abc"
    assert store.get(first.id).idempotency_key is None
    assert enqueue(store, 2, Idempotency("abc", "digest-2", DAY)).id == fresh.id


def test_a_unicode_key_is_kept_as_given(store: JobStore) -> None:
    key = Idempotency("clé-✓-日本", "d", DAY)
    made = enqueue(store, 1, key)
    assert store.get(made.id).idempotency_key == "clé-✓-日本"
    assert enqueue(store, 1, key).id == made.id


def test_racing_requests_under_one_key_make_one_job(store: JobStore) -> None:
    key = Idempotency("race", "d", DAY)
    made: list[int] = []
    lock = threading.Lock()
    start = threading.Barrier(6)

    def submit() -> None:
        start.wait()
        job = enqueue(store, 1, key)
        with lock:
            made.append(job.id)

    threads = [threading.Thread(target=submit) for _ in range(6)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(made) == 6 and len(set(made)) == 1
    assert len(store.page(status=None, limit=10, before_id=None).jobs) == 1


def test_studies_follow_the_same_rules(store: JobStore) -> None:
    studies = StudyStore(store.engine)
    job = StudyJob(scenario={"seed": 1}, robot_steps=10, episodes=1, point=0, seed=1)

    def create(key: Idempotency) -> int:
        return studies.create(name="s", spec={}, jobs=[job], idempotency=key).id

    first = create(Idempotency("s-1", "d-1", DAY))
    assert create(Idempotency("s-1", "d-1", DAY)) == first
    with pytest.raises(IdempotencyKeyReused, match=f"study {first}"):
        create(Idempotency("s-1", "d-2", DAY))
    time.sleep(0.05)
    assert create(Idempotency("s-1", "d-2", 0.01)) != first
