"""A policy is never deleted under a job that evaluates it, on SQLite and PostgreSQL: queueing a
job (or a study's) keeps its policy until the job is stored, so a delete either finds the job and
refuses, or comes first and the job is not queued."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from typing import Any

import pytest

from nanonav.store import JobStore, PolicyNotFound, StudyJob, StudyStore, policy_name
from nanonav.store.errors import PolicyInUse
from nanonav.store.wakeups import announce
from tests.store.test_policies import add

WAIT_S = 10.0


def evaluating(policy_id: int) -> dict[str, Any]:
    return {"policy_from": policy_name(policy_id), "learning": {"episodes": 0}}


def test_no_job_is_queued_for_a_policy_deleted_after_the_check(store: JobStore) -> None:
    policy_id = add(store)
    store.policies.delete(policy_id)
    with pytest.raises(PolicyNotFound) as gone:
        store.enqueue(evaluating(policy_id), robot_steps=1, episodes=0)
    assert gone.value.policy_id == policy_id
    assert store.page(status=None, limit=10, before_id=None).jobs == []


def test_no_study_is_queued_when_one_of_its_policies_was_deleted(store: JobStore) -> None:
    kept, deleted = add(store), add(store)
    store.policies.delete(deleted)
    studies = StudyStore(store.engine)
    jobs = [StudyJob(evaluating(p), 1, 0, point, 0) for point, p in enumerate((kept, deleted))]
    with pytest.raises(PolicyNotFound) as gone:
        studies.create(name="both", spec={}, jobs=jobs)
    assert gone.value.policy_id == deleted
    assert studies.page(limit=10, before_id=None).studies == []
    assert store.page(status=None, limit=10, before_id=None).jobs == []


def test_a_job_for_a_job_s_table_needs_no_policy(store: JobStore) -> None:
    job = store.enqueue({"policy_from": 12345}, robot_steps=1, episodes=0)
    assert store.get(job.id).scenario["policy_from"] == 12345


@pytest.fixture
def paused_enqueue(
    monkeypatch: pytest.MonkeyPatch,
) -> Iterator[tuple[threading.Event, threading.Event]]:
    """An enqueue that, once its job row is written and before it commits, says so and waits."""
    inside, release = threading.Event(), threading.Event()

    def announce_then_wait(session: Any) -> None:
        announce(session)
        inside.set()
        assert release.wait(WAIT_S)

    monkeypatch.setattr("nanonav.store.queue.announce", announce_then_wait)
    yield inside, release
    release.set()


def test_a_delete_during_the_queueing_waits_for_the_job_and_refuses(
    store: JobStore, paused_enqueue: tuple[threading.Event, threading.Event]
) -> None:
    inside, release = paused_enqueue
    policy_id = add(store)
    queued: list[int] = []
    submit = threading.Thread(
        target=lambda: queued.append(
            store.enqueue(evaluating(policy_id), robot_steps=1, episodes=0).id
        )
    )
    submit.start()
    assert inside.wait(WAIT_S)
    outcome: list[BaseException | None] = []

    def delete() -> None:
        try:
            store.policies.delete(policy_id)
            outcome.append(None)
        except BaseException as error:
            outcome.append(error)

    deleting = threading.Thread(target=delete)
    deleting.start()
    deleting.join(0.5)
    assert deleting.is_alive(), "the delete did not wait for the job being queued"
    release.set()
    submit.join(WAIT_S)
    deleting.join(WAIT_S)
    assert len(queued) == 1 and len(outcome) == 1
    assert isinstance(outcome[0], PolicyInUse), outcome
    assert outcome[0].job_ids == [queued[0]]
    assert store.policies.get(policy_id).id == policy_id
