"""Owners and quotas in the store, on SQLite and PostgreSQL: listings and idempotency keys are
per owner, and a quota holds against concurrent submits."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import pytest

from nanonav.store import Idempotency, JobStatus, JobStore, StudyJob, StudyStore
from nanonav.store.errors import QuotaExceeded
from nanonav.store.quotas import Quota

ALICE = "a" * 64
BRUNO = "b" * 64
DAY = 86400.0


def test_jobs_and_studies_remember_their_owner_and_list_by_it(store: JobStore) -> None:
    studies = StudyStore(store.engine)
    mine = store.enqueue({}, robot_steps=1, episodes=1, owner=ALICE)
    theirs = store.enqueue({}, robot_steps=1, episodes=1, owner=BRUNO)
    anonymous = store.enqueue({}, robot_steps=1, episodes=1)
    study = studies.create(
        name="s", spec={}, jobs=[StudyJob({}, 1, 1, 0, 0), StudyJob({}, 1, 1, 0, 1)], owner=BRUNO
    )
    assert store.owner_of(mine.id) == ALICE and store.get(mine.id).owner == ALICE
    assert store.owner_of(anonymous.id) == "" and store.owner_of(999) is None
    assert studies.owner_of(study.id) == BRUNO and studies.owner_of(999) is None
    listed = store.page(status=None, limit=10, before_id=None, owner=BRUNO).jobs
    assert [j.id for j in listed][-1] == theirs.id and {j.owner for j in listed} == {BRUNO}
    assert len(listed) == 3  # its job and the study's two
    assert [j.id for j in store.page(status=None, limit=10, before_id=None, owner=ALICE).jobs] == [
        mine.id
    ]
    assert len(store.page(status=None, limit=10, before_id=None).jobs) == 5
    assert [s.id for s in studies.page(limit=10, before_id=None, owner=BRUNO).studies] == [study.id]
    assert studies.page(limit=10, before_id=None, owner=ALICE).studies == []


def test_the_same_idempotency_key_of_two_owners_makes_two_jobs(store: JobStore) -> None:
    key = Idempotency("nightly", "digest", DAY)
    first = store.enqueue({}, robot_steps=1, episodes=1, idempotency=key, owner=ALICE)
    again = store.enqueue({}, robot_steps=1, episodes=1, idempotency=key, owner=ALICE)
    other = store.enqueue({}, robot_steps=1, episodes=1, idempotency=key, owner=BRUNO)
    assert again.id == first.id and other.id != first.id
    studies = StudyStore(store.engine)
    made = [StudyJob({}, 1, 1, 0, 0)]
    a = studies.create(name="s", spec={}, jobs=made, idempotency=key, owner=ALICE)
    b = studies.create(name="s", spec={}, jobs=made, idempotency=key, owner=BRUNO)
    assert a.id != b.id
    assert studies.create(name="s", spec={}, jobs=made, idempotency=key, owner=BRUNO).id == b.id


def test_a_quota_counts_queued_and_running_jobs_and_their_robot_steps(store: JobStore) -> None:
    quota = Quota(ALICE, active_jobs=2, robot_steps=0)
    first = store.enqueue({}, robot_steps=10, episodes=1, owner=ALICE, quota=quota)
    store.enqueue({}, robot_steps=10, episodes=1, owner=ALICE, quota=quota)
    with pytest.raises(QuotaExceeded) as refused:
        store.enqueue({}, robot_steps=10, episodes=1, owner=ALICE, quota=quota)
    assert refused.value.name == "active_jobs" and refused.value.limit == 2
    store.enqueue({}, robot_steps=10, episodes=1, owner=BRUNO, quota=Quota(BRUNO, 2, 0))
    assert store.claim("w", lease_s=30) is not None  # running still counts
    with pytest.raises(QuotaExceeded):
        store.enqueue({}, robot_steps=10, episodes=1, owner=ALICE, quota=quota)
    store.cancel(first.id)
    store.cancel(first.id + 1)
    store.enqueue({}, robot_steps=10, episodes=1, owner=ALICE, quota=quota)
    steps = Quota(ALICE, active_jobs=0, robot_steps=25)
    with pytest.raises(QuotaExceeded) as refused:
        store.enqueue({}, robot_steps=20, episodes=1, owner=ALICE, quota=steps)
    assert refused.value.name == "robot_steps"
    studies = StudyStore(store.engine)
    with pytest.raises(QuotaExceeded):
        studies.create(
            name="s", spec={}, jobs=[StudyJob({}, 10, 1, 0, s) for s in range(2)], quota=quota
        )
    assert store.get(first.id + 1).status is JobStatus.CANCELLED


def test_concurrent_submits_never_pass_a_quota_together(store: JobStore) -> None:
    quota = Quota("203.0.113.9", active_jobs=4, robot_steps=0)

    def submit(_: int) -> bool:
        try:
            store.enqueue({}, robot_steps=1, episodes=1, quota=quota)
        except QuotaExceeded:
            return False
        return True

    with ThreadPoolExecutor(max_workers=8) as pool:
        accepted = list(pool.map(submit, range(24)))
    assert accepted.count(True) == 4
    assert len(store.page(status=None, limit=100, before_id=None).jobs) == 4
