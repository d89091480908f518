"""What a queued job waits for when no running worker can take it: a job that trains a network
is claimed only by a worker that trains (``nanonav worker --train``)."""

from __future__ import annotations

from nanonav.store import JobRecord, JobStatus, JobStore
from nanonav.store.queue import PRESENCE_WINDOW_S

NO_TRAINER = (
    "a worker that trains networks: none is running (start one with `nanonav worker --train`, "
    "or `make run TRAIN=1`)"
)


def waiting_for(job: JobRecord, store: JobStore) -> str | None:
    """What ``job`` waits for, in words, or None when a worker that can run it is there (or
    it is not queued)."""
    if job.status is not JobStatus.QUEUED or not job.trains:
        return None
    census = store.census(seen_within_s=PRESENCE_WINDOW_S)
    return None if census.trainers else NO_TRAINER
