from __future__ import annotations

from datetime import UTC, datetime, timedelta

from sqlalchemy import event

from nanonav.store import JobStatus, JobStore, Outcome, StudyJob, StudyStore

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
