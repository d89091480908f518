"""Every query about the networks jobs train: which jobs train one, and the checkpoint of a
training under way, kept by the worker that holds the job's lease and read by the next one
when that worker died. A checkpoint lives as long as its job runs or waits to run again: it
goes when the job ends, whichever way (``drop_checkpoints``, called by the queue's ends)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import Engine, delete, select, update
from sqlalchemy.orm import Session

from nanonav.scenario import TRAINED_POLICIES
from nanonav.store.db import make_sessionmaker, unit_of_work
from nanonav.store.errors import LeaseLost
from nanonav.store.models import Job, JobCheckpoint, JobStatus


def trains_network(scenario: Mapping[str, Any]) -> bool:
    """Whether a stored (resolved) scenario trains a network: only a worker that trains
    claims it."""
    robots = scenario.get("robots")
    return isinstance(robots, Mapping) and robots.get("policy") in TRAINED_POLICIES


def _held(job_id: int, token: str) -> Any:
    """The job, while ``token`` holds its lease."""
    return (Job.id == job_id) & (Job.lease_token == token) & (Job.status == JobStatus.RUNNING)


def drop_checkpoints(session: Session, job_ids: Sequence[int]) -> None:
    """Forget the checkpoints of jobs that ended."""
    if job_ids:
        session.execute(delete(JobCheckpoint).where(JobCheckpoint.job_id.in_(list(job_ids))))


@dataclass(frozen=True)
class StoredCheckpoint:
    """A job's last checkpoint: the trainer's state at ``decisions`` and its curve so far."""

    job_id: int
    decisions: int
    data: bytes
    curve: list[dict[str, Any]]
    written_at: datetime


class TrainingStore:
    """The checkpoints of trainings under way, on one database. Writes are fenced by the
    job's lease, as the queue's are: a worker that lost its job writes nothing."""

    def __init__(self, engine: Engine) -> None:
        self._sessions = make_sessionmaker(engine)

    def keep(
        self,
        job_id: int,
        token: str,
        *,
        decisions: int,
        data: bytes,
        curve: list[dict[str, Any]],
        now: datetime | None = None,
    ) -> None:
        """Replace the job's checkpoint with this one, if ``token`` still holds its lease
        (``LeaseLost`` if not), and say in the job how many decisions are done and its curve."""
        now = now or datetime.now(UTC)
        with unit_of_work(self._sessions, write=True) as session:
            row = session.scalars(select(Job).where(_held(job_id, token)).with_for_update()).first()
            if row is None:
                raise LeaseLost(job_id)
            row.decisions, row.training_curve = decisions, curve
            kept = session.get(JobCheckpoint, job_id)
            if kept is None:
                kept = JobCheckpoint(job_id=job_id)
                session.add(kept)
            kept.decisions, kept.data, kept.curve, kept.written_at = decisions, data, curve, now

    def last(self, job_id: int) -> StoredCheckpoint | None:
        """The job's last checkpoint, or None."""
        with unit_of_work(self._sessions) as session:
            row = session.get(JobCheckpoint, job_id)
            if row is None:
                return None
            return StoredCheckpoint(
                job_id, row.decisions, bytes(row.data), list(row.curve), row.written_at
            )

    def resumed(self, job_id: int, token: str, decisions: int, curve: list[dict[str, Any]]) -> None:
        """Say in the job that its training was taken up at ``decisions``, its ``curve`` as
        the checkpoint kept it (rows a dead worker wrote after it are dropped)."""
        with unit_of_work(self._sessions) as session:
            found = session.execute(
                update(Job)
                .where(_held(job_id, token))
                .values(resumed_from_decisions=decisions, decisions=decisions, training_curve=curve)
                .returning(Job.id)
                .execution_options(synchronize_session=False)
            ).first()
            if found is None:
                raise LeaseLost(job_id)
