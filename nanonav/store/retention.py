"""Deleting what has ended, so that the store does not only grow: a job or a study on request,
and, with a retention, everything that ended longer ago than it.

A job goes with its results and pictures, a study with its jobs, its report and its pictures;
their webhooks are detached first (:func:`nanonav.store.deliveries.detach`), so one not sent yet
is still sent. Only what has ended can go: a worker may still write a queued or running job,
and a worker that lost its lease finds no row to write to (its fenced writes match nothing), so
a deleted job never comes back. A job of a study goes only with its study, so that a study's
report never loses a job. Retention works in batches of about :data:`RETENTION_BATCH` jobs, one
transaction each, so that it never holds the write lock long.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime

from sqlalchemy import Engine, Select, delete, exists, func, or_, select
from sqlalchemy.orm import Session

from nanonav.store.db import make_sessionmaker, unit_of_work
from nanonav.store.deliveries import detach, settled_orphans
from nanonav.store.errors import (
    JobInStudy,
    JobNotFinished,
    JobNotFound,
    StudyNotFinished,
    StudyNotFound,
)
from nanonav.store.models import (
    ENDED,
    Delivery,
    Job,
    JobPlot,
    JobResult,
    JobStatus,
    Study,
    StudyPlot,
)

RETENTION_BATCH = 100


@dataclass(frozen=True)
class Expired:
    """What one retention batch deleted."""

    jobs: int  # jobs of their own and jobs of the studies deleted
    studies: int
    deliveries: int  # settled webhooks whose job or study had been deleted before

    @property
    def any(self) -> bool:
        return bool(self.jobs or self.studies or self.deliveries)


def delete_job(session: Session, job_id: int, *, now: datetime) -> None:
    """Delete a finished job that belongs to no study, with all it has."""
    query = select(Job.status, Job.study_id).where(Job.id == job_id).with_for_update()
    row = session.execute(query).one_or_none()
    if row is None:
        raise JobNotFound(job_id)
    status, study_id = JobStatus(row.status), row.study_id
    if not status.finished:
        raise JobNotFinished(job_id, status)
    if study_id is not None:
        raise JobInStudy(job_id, study_id)
    _delete_jobs(session, [job_id], now=now)


def delete_study(session: Session, study_id: int, *, now: datetime) -> None:
    """Delete a study whose jobs have all ended, with its jobs and all they have."""
    query = select(Study).where(Study.id == study_id).with_for_update()
    if session.scalars(query).one_or_none() is None:
        raise StudyNotFound(study_id)
    unfinished = session.scalar(
        select(func.count()).where(Job.study_id == study_id, Job.status.not_in(ENDED))
    )
    if unfinished:
        raise StudyNotFinished(study_id, int(unfinished))
    _delete_studies(session, [study_id], now=now)


class RetentionStore:
    """Deletes, batch by batch, what ended before a moment, on the job store's database."""

    def __init__(self, engine: Engine) -> None:
        self._sessions = make_sessionmaker(engine)

    def expire(
        self, *, before: datetime, batch: int = RETENTION_BATCH, now: datetime | None = None
    ) -> Expired:
        """One batch, in one transaction: up to ``batch`` finished jobs of no study that
        finished before ``before``, then, as far as the batch has room, ended studies whose
        every job finished before it (a study larger than a batch goes alone, whole), then
        settled webhooks left by deleted jobs and studies. Call it until nothing is left."""
        now = now or datetime.now(UTC)
        jobs_query = (
            select(Job.id)
            .where(Job.study_id.is_(None), Job.status.in_(ENDED), Job.finished_at < before)
            .order_by(Job.id)
            .limit(batch)
            .with_for_update(skip_locked=True)
        )
        still_recent = exists().where(
            Job.study_id == Study.id,
            or_(Job.status.not_in(ENDED), Job.finished_at.is_(None), Job.finished_at >= before),
        )
        has_jobs = exists().where(Job.study_id == Study.id)
        studies_query = (
            select(Study.id, Study.jobs)
            .where(~still_recent, or_(has_jobs, Study.created_at < before))
            .order_by(Study.id)
            .with_for_update(skip_locked=True)
        )
        with unit_of_work(self._sessions, write=True) as session:
            job_ids = list(session.scalars(jobs_query))
            _delete_jobs(session, job_ids, now=now)
            room = batch - len(job_ids)
            study_ids: list[int] = []
            study_jobs = 0
            if room > 0:
                for study_id, jobs in session.execute(studies_query.limit(room)):
                    fits = study_jobs + jobs <= room
                    if not fits and (study_ids or job_ids):
                        break  # a study larger than the room left waits for a batch of its own
                    study_ids.append(study_id)
                    study_jobs += jobs
                    if not fits:
                        break
            _delete_studies(session, study_ids, now=now)
            orphans = (
                select(Delivery.id)
                .where(settled_orphans(before))
                .limit(batch)
                .with_for_update(skip_locked=True)
            )
            deliveries = session.scalars(
                delete(Delivery)
                .where(Delivery.id.in_(orphans.scalar_subquery()))
                .returning(Delivery.id)
                .execution_options(synchronize_session=False)
            ).all()
        return Expired(jobs=len(job_ids) + study_jobs, studies=len(study_ids),
                       deliveries=len(deliveries))  # fmt: skip


def _delete_jobs(session: Session, job_ids: Sequence[int] | Select[int], *, now: datetime) -> None:
    """Delete these jobs (a list of ids, or a query of them) with their results and pictures,
    children first: nothing is left that points at them, whatever the foreign keys do."""
    if isinstance(job_ids, Sequence) and not job_ids:
        return
    detach(session, Delivery.job_id.in_(job_ids), now=now)
    for table in (JobPlot, JobResult):
        session.execute(
            delete(table)
            .where(table.job_id.in_(job_ids))
            .execution_options(synchronize_session=False)
        )
    session.execute(
        delete(Job).where(Job.id.in_(job_ids)).execution_options(synchronize_session=False)
    )


def _delete_studies(session: Session, study_ids: Sequence[int], *, now: datetime) -> None:
    if not study_ids:
        return
    detach(session, Delivery.study_id.in_(study_ids), now=now)
    _delete_jobs(session, select(Job.id).where(Job.study_id.in_(study_ids)), now=now)
    session.execute(
        delete(StudyPlot)
        .where(StudyPlot.study_id.in_(study_ids))
        .execution_options(synchronize_session=False)
    )
    session.execute(
        delete(Study).where(Study.id.in_(study_ids)).execution_options(synchronize_session=False)
    )
