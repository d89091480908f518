"""On PostgreSQL an idle worker starts a queued job at once, however long its poll interval."""

from __future__ import annotations

import time
from pathlib import Path

from nanonav.store import JobStatus
from tests.conftest import migrated_store
from tests.processes import Worker

TINY = {"robots": {"count": 1}, "obstacles": {"count": 0},
        "learning": {"episodes": 1, "max_steps": 20}, "evaluation": {"worlds": 1}}  # fmt: skip


def test_a_queued_job_starts_within_a_second_despite_a_30_s_poll(
    postgres_url: str, tmp_path: Path
) -> None:
    with migrated_store(postgres_url) as store:
        worker = Worker(postgres_url, tmp_path / "worker.log", NANONAV_POLL_INTERVAL_S="30")
        try:
            worker.wait_ready()
            deadline = time.monotonic() + 30
            while "listening for queued jobs" not in worker.text():
                assert time.monotonic() < deadline, worker.text()
                time.sleep(0.05)
            latencies = []
            for seed in range(3):
                time.sleep(0.5)  # the worker is idle, in the middle of its 30 s wait
                job = store.enqueue({**TINY, "seed": seed}, robot_steps=40, episodes=1)
                deadline = time.monotonic() + 10
                while (found := store.get(job.id)).status is JobStatus.QUEUED:
                    assert time.monotonic() < deadline, worker.text()
                    time.sleep(0.01)
                assert found.started_at is not None
                latencies.append((found.started_at - found.created_at).total_seconds())
            print(f"queued -> started on PostgreSQL: {[f'{s * 1000:.0f} ms' for s in latencies]}")
            assert max(latencies) < 1.0, latencies
        finally:
            worker.terminate()
