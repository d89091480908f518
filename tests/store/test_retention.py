"""Deleting jobs and studies, on request and by retention: only what has ended, all of it, and
nothing a late worker could bring back."""

from __future__ import annotations

import threading
from datetime import UTC, datetime, timedelta

import pytest
from sqlalchemy import text

from nanonav.store import (
    JobInStudy,
    JobNotFinished,
    JobNotFound,
    JobStatus,
    JobStore,
    LeaseLost,
    RetentionStore,
    StudyNotFinished,
    StudyNotFound,
    StudyStore,
)
from nanonav.store.deliveries import DeliveryStore
from tests.store.test_deliveries import URL, submit
from tests.store.test_queue import LEASE_S, claim, enqueue, outcome
from tests.store.test_studies import study

T0 = datetime(2030, 1, 1, tzinfo=UTC)
TABLES = ("jobs", "job_results", "job_plots", "studies", "study_plots", "deliveries")


def rows(store: JobStore) -> dict[str, int]:
    """How many rows each table holds."""
    with store.engine.connect() as connection:
        return {t: connection.scalar(text(f"SELECT count(*) FROM {t}")) or 0 for t in TABLES}


def succeeded(store: JobStore, at: datetime = T0) -> int:
    """A job that ran and succeeded at ``at``, with a picture drawn."""
    job = enqueue(store)
    held = claim(store, now=at - timedelta(seconds=1))
    assert held.job.id == job.id
    store.finish(held, outcome(), now=at)
    store.save_plot(job.id, "trajectory", b"png")
    return job.id


def finish_study(store: JobStore, studies: StudyStore, jobs: int, at: datetime = T0) -> int:
    """A study whose jobs all succeeded at ``at``, with its report and a picture kept."""
    study_id = study(studies, jobs)
    for _ in range(jobs):
        store.finish(claim(store, now=at - timedelta(seconds=1)), outcome(), now=at)
    studies.keep_report(study_id, {"points": []})
    studies.keep_plot(study_id, "learning", b"png")
    return study_id


def test_deleting_a_finished_job_removes_it_and_all_it_has(store: JobStore) -> None:
    kept = succeeded(store)
    gone = succeeded(store)
    assert rows(store)["job_results"] == 2 and rows(store)["job_plots"] == 2
    store.delete(gone)
    with pytest.raises(JobNotFound):
        store.get(gone)
    with pytest.raises(JobNotFound):
        store.delete(gone)
    assert rows(store) == {
        "jobs": 1, "job_results": 1, "job_plots": 1, "studies": 0, "study_plots": 0,
        "deliveries": 0,
    }  # fmt: skip
    assert store.metrics(kept)["summary"] == {"total_steps": 7}


def test_the_id_of_a_deleted_job_or_study_is_never_given_again(store: JobStore) -> None:
    # SQLite would hand the newest row's id to the next row once it is deleted, and a client,
    # a browser cache or a webhook receiver holding that id would take one for the other.
    studies = StudyStore(store.engine)
    study_id = finish_study(store, studies, 1)
    studies.delete(study_id)
    newest = succeeded(store)
    store.delete(newest)
    assert enqueue(store).id > newest
    assert study(studies, 1) > study_id


def test_failed_and_cancelled_jobs_can_be_deleted(store: JobStore) -> None:
    failed = enqueue(store)
    store.fail(claim(store), "the scenario raised")
    cancelled = enqueue(store)
    store.cancel(cancelled.id)
    store.delete(failed.id)
    store.delete(cancelled.id)
    assert rows(store)["jobs"] == 0


def test_a_queued_or_running_job_is_not_deleted(store: JobStore) -> None:
    running = enqueue(store)
    held = claim(store)
    queued = enqueue(store)
    for job_id, status in ((queued.id, JobStatus.QUEUED), (running.id, JobStatus.RUNNING)):
        with pytest.raises(JobNotFinished, match="cancel it first") as refused:
            store.delete(job_id)
        assert refused.value.status is status
    store.finish(held, outcome())
    store.delete(running.id)
    assert store.get(queued.id).status is JobStatus.QUEUED


def test_a_job_of_a_study_goes_only_with_its_study(store: JobStore) -> None:
    studies = StudyStore(store.engine)
    study_id = finish_study(store, studies, 2)
    job_id = store.page(status=None, limit=1, before_id=None, study_id=study_id).jobs[0].id
    with pytest.raises(JobInStudy, match=f"delete the study instead.*/studies/{study_id}"):
        store.delete(job_id)
    assert rows(store)["jobs"] == 2


def test_a_worker_that_lost_its_job_cannot_write_it_back_once_deleted(store: JobStore) -> None:
    job = enqueue(store)
    held = claim(store, now=T0)
    store.cancel(job.id)  # asked to stop; its worker then stopped answering
    store.recover_expired(max_attempts=3, now=T0 + timedelta(seconds=LEASE_S + 1))
    assert store.get(job.id).status is JobStatus.CANCELLED
    store.delete(job.id)
    with pytest.raises(LeaseLost):
        store.report_progress(held, episode=1, episodes=2, fraction=0.5, lease_s=LEASE_S)
    with pytest.raises(LeaseLost):
        store.renew(held, lease_s=LEASE_S)
    with pytest.raises(LeaseLost):
        store.finish(held, outcome())
    with pytest.raises(LeaseLost):
        store.fail(held, "too late")
    assert rows(store)["jobs"] == 0 and rows(store)["job_results"] == 0


def test_a_picture_drawn_while_its_job_was_deleted_is_not_kept(store: JobStore) -> None:
    job_id = succeeded(store)
    store.delete(job_id)
    with pytest.raises(JobNotFound):
        store.save_plot(job_id, "learning", b"png")
    assert rows(store)["job_plots"] == 0


def test_a_webhook_not_yet_sent_outlives_its_deleted_job_and_a_sent_one_goes(
    store: JobStore,
) -> None:
    deliveries = DeliveryStore(store.engine)
    sent = submit(store)
    store.cancel(sent)
    deliveries.promote()
    held = deliveries.claim(lease_s=LEASE_S)
    assert held is not None
    assert deliveries.settle(held, status=204, error=None, retry_in_s=None)
    unsent = submit(store)
    store.cancel(unsent)  # ended, but no sender has made its webhook due yet
    store.delete(sent)
    store.delete(unsent)
    assert rows(store)["deliveries"] == 1
    due = deliveries.claim(lease_s=LEASE_S)
    assert due is not None and due.url == URL and due.event == "job.cancelled"
    assert due.payload["job"]["id"] == unsent and due.payload["job"]["status"] == "cancelled"


def test_an_ended_study_is_deleted_with_its_jobs_results_report_and_pictures(
    store: JobStore,
) -> None:
    studies = StudyStore(store.engine)
    gone = finish_study(store, studies, 3)
    kept = finish_study(store, studies, 2)
    own = succeeded(store)
    studies.delete(gone)
    with pytest.raises(StudyNotFound):
        studies.get(gone)
    with pytest.raises(StudyNotFound):
        studies.delete(gone)
    assert rows(store) == {"jobs": 3, "job_results": 3, "job_plots": 1, "studies": 1,
                           "study_plots": 1, "deliveries": 0}  # fmt: skip
    assert len(studies.job_states(kept)) == 2 and store.get(own).status is JobStatus.SUCCEEDED


def test_a_study_with_unfinished_jobs_is_not_deleted(store: JobStore) -> None:
    studies = StudyStore(store.engine)
    study_id = study(studies, 3)
    held = claim(store)
    store.finish(claim(store), outcome())
    with pytest.raises(StudyNotFinished, match="2 job") as refused:
        studies.delete(study_id)
    assert refused.value.unfinished == 2
    studies.cancel(study_id)  # the queued job ends now, the running one when it stops
    with pytest.raises(StudyNotFinished, match="1 job"):
        studies.delete(study_id)
    store.finish(held, outcome(completed=False))
    studies.delete(study_id)
    assert rows(store)["jobs"] == 0 and rows(store)["studies"] == 0


def test_retention_deletes_what_ended_before_the_cutoff_and_nothing_else(
    store: JobStore,
) -> None:
    studies = StudyStore(store.engine)
    retention = RetentionStore(store.engine)
    old = succeeded(store, at=T0)
    recent = succeeded(store, at=T0 + timedelta(days=2))
    old_study = finish_study(store, studies, 2, at=T0)
    recent_study = finish_study(store, studies, 2, at=T0 + timedelta(days=2))
    unfinished_study = study(studies, 2)
    store.finish(claim(store, now=T0), outcome(), now=T0)  # one of its two jobs ended
    running = claim(store, now=T0).job  # the other runs
    queued = enqueue(store)

    expired = retention.expire(before=T0 + timedelta(days=1))
    assert (expired.jobs, expired.studies) == (3, 1)
    assert not retention.expire(before=T0 + timedelta(days=1)).any
    with pytest.raises(JobNotFound):
        store.get(old)
    with pytest.raises(StudyNotFound):
        studies.get(old_study)
    assert store.get(recent).status is JobStatus.SUCCEEDED
    assert {s.id for s in studies.page(limit=10, before_id=None).studies} == {
        recent_study, unfinished_study,
    }  # fmt: skip
    assert store.get(running.id).status is JobStatus.RUNNING
    assert store.get(queued.id).status is JobStatus.QUEUED
    assert len(studies.job_states(unfinished_study)) == 2


def test_retention_works_in_bounded_batches(store: JobStore) -> None:
    retention = RetentionStore(store.engine)
    for _ in range(5):
        succeeded(store)
    before = T0 + timedelta(seconds=1)
    batches = [retention.expire(before=before, batch=2).jobs for _ in range(4)]
    assert batches == [2, 2, 1, 0]
    assert rows(store)["jobs"] == 0 and rows(store)["job_results"] == 0


def test_a_study_larger_than_a_batch_goes_alone_and_whole(store: JobStore) -> None:
    studies = StudyStore(store.engine)
    retention = RetentionStore(store.engine)
    own = succeeded(store)
    large = finish_study(store, studies, 5)
    small = finish_study(store, studies, 1)
    before = T0 + timedelta(seconds=1)
    first = retention.expire(before=before, batch=3)
    assert (first.jobs, first.studies) == (1, 0)  # the job, then no room for 5 more
    second = retention.expire(before=before, batch=3)
    assert (second.jobs, second.studies) == (5, 1)
    third = retention.expire(before=before, batch=3)
    assert (third.jobs, third.studies) == (1, 1)
    assert rows(store) == dict.fromkeys(TABLES, 0)
    for gone in (large, small):
        with pytest.raises(StudyNotFound):
            studies.get(gone)
    with pytest.raises(JobNotFound):
        store.get(own)


def test_retention_forgets_settled_webhooks_of_deleted_jobs(store: JobStore) -> None:
    deliveries = DeliveryStore(store.engine)
    retention = RetentionStore(store.engine)
    job_id = submit(store)
    store.cancel(job_id)
    store.delete(job_id)  # its webhook, not sent yet, stays to be sent
    assert not retention.expire(before=datetime.now(UTC) + timedelta(days=1)).any
    held = deliveries.claim(lease_s=LEASE_S)
    assert held is not None
    deliveries.settle(held, status=None, error="refused", retry_in_s=None, now=T0)
    assert rows(store)["deliveries"] == 1
    assert retention.expire(before=T0).deliveries == 0  # settled at T0: not before it
    assert retention.expire(before=T0 + timedelta(seconds=1)).deliveries == 1
    assert rows(store)["deliveries"] == 0


def test_workers_expiring_at_once_delete_each_job_once(store: JobStore) -> None:
    for _ in range(40):
        succeeded(store)
    before = T0 + timedelta(seconds=1)
    deleted: list[int] = []
    errors: list[BaseException] = []

    def sweep() -> None:
        retention = RetentionStore(store.engine)
        try:
            while (batch := retention.expire(before=before, batch=3)).any:
                deleted.append(batch.jobs)
        except BaseException as error:
            errors.append(error)

    sweepers = [threading.Thread(target=sweep) for _ in range(3)]
    for sweeper in sweepers:
        sweeper.start()
    for sweeper in sweepers:
        sweeper.join(timeout=60)
    assert errors == []
    assert sum(deleted) == 40
    assert rows(store) == dict.fromkeys(TABLES, 0)
