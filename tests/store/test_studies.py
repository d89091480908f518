from __future__ import annotations

from datetime import UTC, datetime, timedelta

import pytest
from sqlalchemy import event

from nanonav.store import JobStatus, JobStore, Outcome, StudyJob, StudyStore
from nanonav.store.errors import QuotaExceeded
from nanonav.store.quotas import Quota

LEASE_S = 30.0


def study(studies: StudyStore, jobs: int) -> int:
    made = [
        StudyJob({"seed": seed}, robot_steps=1, episodes=1, point=0, seed=seed)
        for seed in range(jobs)
    ]
    return studies.create(name="s", spec={}, jobs=made).id


def test_progress_sums_up_many_studies_in_one_query(store: JobStore) -> None:
    studies = StudyStore(store.engine)
    first, second = study(studies, 4), study(studies, 2)
    t0 = datetime(2030, 1, 1, tzinfo=UTC)
    running = store.claim("w", lease_s=LEASE_S)
    succeeded = store.claim("w", lease_s=LEASE_S)
    failed = store.claim("w", lease_s=LEASE_S)
    assert running and succeeded and failed
    store.report_progress(running, episode=1, episodes=2, fraction=0.4, lease_s=LEASE_S)
    store.finish(succeeded, Outcome(True, {}, None, None), now=t0 + timedelta(seconds=2))
    store.fail(failed, "boom", now=t0 + timedelta(seconds=1))
    studies.cancel(second)

    statements: list[str] = []
    listen = ("before_cursor_execute", lambda *args: statements.append(args[2]))
    event.listen(store.engine, *listen)
    try:
        found = studies.progress([second, first, 10_000])
    finally:
        event.remove(store.engine, *listen)

    assert sum(s.lstrip().upper().startswith("SELECT") for s in statements) == 1
    assert set(found) == {first, second}
    one = found[first]
    assert one.jobs == {
        JobStatus.QUEUED: 1,
        JobStatus.RUNNING: 1,
        JobStatus.SUCCEEDED: 1,
        JobStatus.FAILED: 1,
    }
    assert one.work_done == 0.4 + 1 + 1
    assert one.last_finished_at == t0 + timedelta(seconds=2)
    assert not one.cancel_requested
    two = found[second]
    assert two.jobs == {JobStatus.CANCELLED: 2}
    assert two.work_done == 2.0
    assert two.cancel_requested
    assert two.last_finished_at is not None and two.last_finished_at.tzinfo is not None
    assert studies.progress([]) == {}


def test_a_studys_failed_jobs_are_queued_again_as_new_and_its_report_dropped(
    store: JobStore,
) -> None:
    studies = StudyStore(store.engine)
    made = study(studies, 3)
    claims = [store.claim("w", lease_s=LEASE_S) for _ in range(3)]
    assert all(claims)
    first, second, third = claims
    assert first and second and third
    store.finish(first, Outcome(True, {"summary": {}}, None, None))
    store.report_progress(second, episode=1, episodes=1, fraction=0.7, lease_s=LEASE_S)
    store.fail(second, "boom")
    store.fail(third, "bang")
    studies.keep_report(made, {"metrics": ["kept"]})
    studies.keep_plot(made, "learning", b"png")
    assert studies.retry_failed(made) == [second.job.id, third.job.id]
    for claim in (second, third):
        job = store.get(claim.job.id)
        assert (job.status, job.attempts, job.error, job.fraction) == (
            JobStatus.QUEUED, 0, None, 0.0
        )  # fmt: skip
        assert job.started_at is None and job.finished_at is None
    assert store.get(first.job.id).status is JobStatus.SUCCEEDED  # a success is kept
    assert studies.get(made).report is None and studies.plot(made, "learning") is None
    # they run again, claimed as any queued job; nothing failed is left to retry
    again = store.claim("w", lease_s=LEASE_S)
    assert again is not None and again.job.id == second.job.id and again.job.attempts == 1
    assert studies.retry_failed(made) == []


def test_retrying_a_studys_jobs_counts_against_the_quota(store: JobStore) -> None:
    studies = StudyStore(store.engine)
    made = study(studies, 2)
    for _ in range(2):
        claim = store.claim("w", lease_s=LEASE_S)
        assert claim is not None
        store.fail(claim, "boom")
    store.enqueue({"seed": 9}, robot_steps=1, episodes=1)  # one active job of the key ''
    with pytest.raises(QuotaExceeded):
        studies.retry_failed(made, quota=Quota("", active_jobs=2, robot_steps=0))
    assert studies.job_states(made)[0].status is JobStatus.FAILED  # nothing was queued
    assert len(studies.retry_failed(made, quota=Quota("", active_jobs=3, robot_steps=0))) == 2
