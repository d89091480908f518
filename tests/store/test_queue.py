from __future__ import annotations

import threading
from datetime import UTC, datetime, timedelta

import numpy as np
import pytest
from sqlalchemy import event, text

from nanonav.store import (
    Claim,
    JobAlreadyFinished,
    JobNotFound,
    JobRecord,
    JobStatus,
    JobStore,
    LeaseLost,
    Outcome,
    ResultsUnavailable,
)

LEASE_S = 30.0


def enqueue(store: JobStore, seed: int = 0) -> JobRecord:
    return store.enqueue({"seed": seed}, robot_steps=100, episodes=2)


def claim(store: JobStore, owner: str = "w1", now: datetime | None = None) -> Claim:
    claimed = store.claim(owner, lease_s=LEASE_S, now=now)
    assert claimed is not None
    return claimed


def outcome(completed: bool = True) -> Outcome:
    return Outcome(
        completed=completed,
        metrics={"summary": {"total_steps": 7}, "robots": [], "episodes": [{"episode": 0}]},
        trajectory={
            "robots": np.arange(24, dtype=np.float64).reshape(4, 2, 3),
            "reached": np.array([True, False]),
        }
        if completed
        else None,
        qtable={
            "states": np.array(["low", "high"]),
            "values": np.ones((2, 3), dtype=np.float64),
            "visits": np.zeros((2, 3), dtype=np.int64),
        },
    )


def test_enqueue_then_get_returns_the_queued_job(store: JobStore) -> None:
    job = enqueue(store, seed=5)
    fetched = store.get(job.id)
    assert fetched == job
    assert fetched.status is JobStatus.QUEUED
    assert fetched.scenario == {"seed": 5}
    assert fetched.attempts == 0
    assert fetched.created_at.tzinfo is UTC
    assert abs(fetched.created_at - datetime.now(UTC)) < timedelta(seconds=10)


def test_get_of_an_unknown_job_raises_not_found(store: JobStore) -> None:
    with pytest.raises(JobNotFound):
        store.get(12345)


def test_claim_takes_the_oldest_queued_job_under_a_new_lease(store: JobStore) -> None:
    first, second = enqueue(store), enqueue(store)
    now = datetime.now(UTC)
    claimed = claim(store, owner="worker-a", now=now)
    assert claimed.job.id == first.id
    assert claimed.job.status is JobStatus.RUNNING
    assert claimed.job.attempts == 1
    assert claimed.job.started_at == now
    assert claim(store).job.id == second.id
    assert store.claim("w", lease_s=LEASE_S) is None


def test_claim_never_runs_a_job_twice(store: JobStore) -> None:
    ids = {enqueue(store, seed=i).id for i in range(40)}
    claimed: list[int] = []
    lock = threading.Lock()

    def drain(owner: str) -> None:
        while (job := store.claim(owner, lease_s=LEASE_S)) is not None:
            with lock:
                claimed.append(job.job.id)

    threads = [threading.Thread(target=drain, args=(f"w{i}",)) for i in range(6)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert sorted(claimed) == sorted(ids)


def test_progress_renews_the_lease_and_reports_a_cancel_request(store: JobStore) -> None:
    enqueue(store)
    claimed = claim(store)
    assert (
        store.report_progress(claimed, episode=1, episodes=2, fraction=0.5, lease_s=LEASE_S)
        is False
    )
    job = store.get(claimed.job.id)
    assert (job.episode, job.episodes, job.fraction) == (1, 2, 0.5)
    cancelled = store.cancel(claimed.job.id)
    assert cancelled.status is JobStatus.RUNNING
    assert cancelled.cancel_requested is True
    assert store.report_progress(claimed, episode=2, episodes=2, fraction=0.9, lease_s=LEASE_S)


def test_renew_extends_the_lease_of_its_own_claim_only(store: JobStore) -> None:
    enqueue(store)
    past = datetime.now(UTC) - timedelta(seconds=2 * LEASE_S)
    claimed = claim(store, now=past)
    store.renew(claimed, lease_s=LEASE_S)
    assert store.recover_expired(max_attempts=3) == 0
    with pytest.raises(LeaseLost):
        store.renew(Claim(job=claimed.job, token="other", owner="w1"), lease_s=LEASE_S)


def test_writes_with_a_stale_lease_token_are_refused(store: JobStore) -> None:
    enqueue(store)
    claimed = claim(store)
    stale = Claim(job=claimed.job, token="not-the-token", owner="w1")
    with pytest.raises(LeaseLost):
        store.report_progress(stale, episode=1, episodes=2, fraction=0.5, lease_s=LEASE_S)
    with pytest.raises(LeaseLost):
        store.finish(stale, outcome())
    with pytest.raises(LeaseLost):
        store.fail(stale, "boom")
    assert store.get(claimed.job.id).status is JobStatus.RUNNING


def test_a_worker_whose_lease_expired_cannot_store_a_result(store: JobStore) -> None:
    enqueue(store)
    past = datetime.now(UTC) - timedelta(seconds=2 * LEASE_S)
    dead = claim(store, owner="dead", now=past)
    assert store.recover_expired(max_attempts=3) == 1
    alive = claim(store, owner="alive")
    assert alive.job.attempts == 2
    with pytest.raises(LeaseLost):
        store.finish(dead, outcome())
    store.finish(alive, outcome())
    assert store.get(alive.job.id).status is JobStatus.SUCCEEDED


def test_an_expired_job_fails_once_its_attempts_are_used(store: JobStore) -> None:
    job = enqueue(store)
    past = datetime.now(UTC) - timedelta(seconds=2 * LEASE_S)
    for _ in range(2):
        claim(store, now=past)
        assert store.recover_expired(max_attempts=2) == 1
    failed = store.get(job.id)
    assert failed.status is JobStatus.FAILED
    assert failed.attempts == 2
    assert failed.error is not None and "given up" in failed.error
    assert failed.finished_at is not None


def test_an_expired_job_with_a_cancel_request_ends_cancelled(store: JobStore) -> None:
    job = enqueue(store)
    claim(store, now=datetime.now(UTC) - timedelta(seconds=2 * LEASE_S))
    store.cancel(job.id)
    assert store.recover_expired(max_attempts=3) == 1
    assert store.get(job.id).status is JobStatus.CANCELLED


def test_a_live_lease_is_not_recovered(store: JobStore) -> None:
    enqueue(store)
    claim(store)
    assert store.recover_expired(max_attempts=3) == 0


def test_finish_stores_metrics_and_arrays_with_dtype_and_shape(store: JobStore) -> None:
    enqueue(store)
    claimed = claim(store)
    with pytest.raises(ResultsUnavailable):
        store.metrics(claimed.job.id)
    done = store.finish(claimed, outcome())
    assert done.status is JobStatus.SUCCEEDED
    assert done.fraction == 1.0
    assert done.finished_at is not None
    assert store.metrics(done.id)["summary"] == {"total_steps": 7}
    trajectory = store.trajectory(done.id)
    assert trajectory["robots"].shape == (4, 2, 3)
    assert trajectory["robots"].dtype == np.float64
    assert trajectory["robots"][3, 1, 2] == 23.0
    assert trajectory["reached"].dtype == np.bool_
    qtable = store.qtable(done.id)
    assert qtable["states"].tolist() == ["low", "high"]
    assert qtable["visits"].dtype == np.int64
    assert store.trajectory_npz(done.id) is not None
    assert store.plot(done.id, "trajectory") is None


def test_a_drawn_picture_is_kept_once(store: JobStore) -> None:
    enqueue(store)
    done = store.finish(claim(store), outcome())
    store.save_plot(done.id, "trajectory", b"\x89PNG first")
    store.save_plot(done.id, "trajectory", b"\x89PNG second")
    assert store.plot(done.id, "trajectory") == b"\x89PNG first"
    assert store.plot(done.id, "learning") is None


def test_a_stopped_run_ends_cancelled_and_keeps_its_episodes(store: JobStore) -> None:
    job = enqueue(store)
    claimed = claim(store)
    store.cancel(job.id)
    ended = store.finish(claimed, outcome(completed=False))
    assert ended.status is JobStatus.CANCELLED
    assert store.partial_result(job.id) == outcome(completed=False).metrics
    with pytest.raises(ResultsUnavailable):
        store.trajectory(job.id)


def test_fail_records_a_readable_error(store: JobStore) -> None:
    enqueue(store)
    claimed = claim(store)
    failed = store.fail(claimed, "ValueError: no robots")
    assert failed.status is JobStatus.FAILED
    assert failed.error == "ValueError: no robots"
    with pytest.raises(ResultsUnavailable) as refused:
        store.plot(failed.id, "trajectory")
    assert refused.value.status is JobStatus.FAILED


def test_release_gives_the_job_back_as_if_never_claimed(store: JobStore) -> None:
    job = enqueue(store)
    claimed = claim(store)
    store.report_progress(claimed, episode=1, episodes=2, fraction=0.4, lease_s=LEASE_S)
    back = store.release(claimed)
    assert back.status is JobStatus.QUEUED
    assert (back.attempts, back.episode, back.fraction, back.started_at) == (0, 0, 0.0, None)
    assert claim(store).job.id == job.id


def test_cancel_of_a_queued_job_is_immediate_and_final(store: JobStore) -> None:
    job = enqueue(store)
    cancelled = store.cancel(job.id)
    assert cancelled.status is JobStatus.CANCELLED
    assert cancelled.finished_at is not None
    assert store.claim("w", lease_s=LEASE_S) is None
    assert store.cancel(job.id).status is JobStatus.CANCELLED


def test_cancel_of_a_finished_job_is_refused(store: JobStore) -> None:
    enqueue(store)
    claimed = claim(store)
    store.finish(claimed, outcome())
    with pytest.raises(JobAlreadyFinished):
        store.cancel(claimed.job.id)
    with pytest.raises(JobNotFound):
        store.cancel(999)


def test_page_lists_newest_first_and_follows_the_cursor(store: JobStore) -> None:
    ids = [enqueue(store, seed=i).id for i in range(5)]
    first = store.page(status=None, limit=2, before_id=None)
    assert [j.id for j in first.jobs] == ids[::-1][:2]
    second = store.page(status=None, limit=2, before_id=first.next_before_id)
    assert [j.id for j in second.jobs] == ids[::-1][2:4]
    last = store.page(status=None, limit=2, before_id=second.next_before_id)
    assert [j.id for j in last.jobs] == [ids[0]]
    assert last.next_before_id is None


def test_page_filters_by_status(store: JobStore) -> None:
    ids = [enqueue(store).id for _ in range(3)]
    store.cancel(ids[1])
    page = store.page(status=JobStatus.CANCELLED, limit=10, before_id=None)
    assert [j.id for j in page.jobs] == [ids[1]]
    queued = store.page(status=JobStatus.QUEUED, limit=10, before_id=None)
    assert [j.id for j in queued.jobs] == [ids[2], ids[0]]


def test_sqlite_runs_in_wal_mode_with_a_busy_timeout(sqlite_store: JobStore) -> None:
    with sqlite_store.engine.connect() as connection:
        assert connection.execute(text("PRAGMA journal_mode")).scalar() == "wal"
        assert connection.execute(text("PRAGMA busy_timeout")).scalar() == 30_000
        assert connection.execute(text("PRAGMA foreign_keys")).scalar() == 1


def test_the_census_counts_waiting_and_running_jobs_and_recent_workers(store: JobStore) -> None:
    now = datetime.now(UTC)
    empty = store.census(seen_within_s=30, now=now)
    assert (empty.queued, empty.running, empty.workers, empty.oldest_queued_at) == (0, 0, 0, None)
    first = enqueue(store)
    enqueue(store, seed=1)
    enqueue(store, seed=2)
    claim(store)
    store.worker_seen("host:1", started_at=now, now=now - timedelta(seconds=40))
    store.worker_seen("host:2", started_at=now, now=now)
    census = store.census(seen_within_s=30, now=now)
    assert (census.queued, census.running, census.workers) == (2, 1, 1)
    assert census.oldest_queued_at is not None
    assert census.oldest_queued_at >= first.created_at
    store.worker_seen("host:1", started_at=now, now=now)
    assert store.census(seen_within_s=30, now=now).workers == 2
    store.worker_gone("host:2")
    assert store.census(seen_within_s=30, now=now).workers == 1
    store.worker_seen("other_host:3", started_at=now, now=now)
    assert store.census(seen_within_s=30, now=now, host="host").workers == 1
    assert store.census(seen_within_s=30, now=now, host="other_host").workers == 1
    assert store.census(seen_within_s=30, now=now, host="other%").workers == 0


def test_the_census_tells_workers_preparing_from_workers_ready(store: JobStore) -> None:
    now = datetime.now(UTC)
    store.worker_seen("host:1", started_at=now, ready=False, now=now)
    census = store.census(seen_within_s=30, now=now)
    assert (census.workers, census.preparing) == (0, 1)
    store.worker_seen("host:2", started_at=now, now=now)
    store.worker_seen("host:1", started_at=now, now=now)  # its engine is ready
    census = store.census(seen_within_s=30, now=now)
    assert (census.workers, census.preparing) == (2, 0)
    later = now + timedelta(seconds=60)
    store.worker_seen("host:1", started_at=now, ready=False, now=later)  # ready it stays
    census = store.census(seen_within_s=30, now=later)
    assert (census.workers, census.preparing) == (1, 0)


def test_jobs_are_listed_by_policy(store: JobStore) -> None:
    for policy in ("gradient", "q_learning", "gradient"):
        store.enqueue({"robots": {"policy": policy}}, robot_steps=1, episodes=1)
    found = store.page(status=None, limit=10, before_id=None, policy="gradient").jobs
    assert [j.scenario["robots"]["policy"] for j in found] == ["gradient", "gradient"]
    assert store.page(status=None, limit=10, before_id=None, policy="rule").jobs == []


def test_get_many_reads_the_jobs_that_exist_in_one_query(store: JobStore) -> None:
    first, second = enqueue(store, seed=1), enqueue(store, seed=2)
    claimed = claim(store)
    store.report_progress(claimed, episode=1, episodes=2, fraction=0.5, lease_s=LEASE_S)
    statements: list[str] = []
    listen = ("before_cursor_execute", lambda *args: statements.append(args[2]))
    event.listen(store.engine, *listen)
    try:
        found = store.get_many([second.id, first.id, 10_000])
    finally:
        event.remove(store.engine, *listen)
    assert set(found) == {first.id, second.id}
    assert found[first.id].status is JobStatus.RUNNING
    assert found[first.id].fraction == 0.5
    assert found[second.id] == store.get(second.id)
    assert sum(s.lstrip().upper().startswith("SELECT") for s in statements) == 1
    assert store.get_many([]) == {}
