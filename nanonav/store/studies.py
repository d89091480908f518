"""Every query about studies. Each public method of :class:`StudyStore` is one transaction.

A study is created with all its jobs in one transaction, so a client never sees half a study;
its jobs are ordinary queued jobs that carry ``study_id``, their grid point and their seed.
Cancelling a study cancels its queued jobs at once and asks its running ones to stop.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from dataclasses import dataclass
from datetime import datetime
from itertools import groupby
from typing import Any

from sqlalchemy import JSON, Engine, delete, func, insert, literal, select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from nanonav.store.db import add_once, make_sessionmaker, unit_of_work
from nanonav.store.deliveries import add_waiting
from nanonav.store.errors import StudyNotFound
from nanonav.store.idempotency import Idempotency, insert_once
from nanonav.store.models import Job, JobPlot, JobResult, JobStatus, Study, StudyPlot
from nanonav.store.policies import evaluated_policies, hold_policies
from nanonav.store.queue import aware, utcnow
from nanonav.store.quotas import Quota, check_quota
from nanonav.store.retention import delete_study
from nanonav.store.training import drop_checkpoints, trains_network
from nanonav.store.wakeups import announce


@dataclass(frozen=True)
class StudyJob:
    """A job a study is made of, before it is stored."""

    scenario: dict[str, Any]
    robot_steps: int
    episodes: int
    point: int
    seed: int


@dataclass(frozen=True)
class StudyRecord:
    id: int
    name: str
    spec: dict[str, Any]
    jobs: int
    created_at: datetime
    cancel_requested: bool
    report: dict[str, Any] | None
    owner: str = ""

    @classmethod
    def of(cls, row: Study) -> StudyRecord:
        return cls(
            id=row.id,
            name=row.name,
            spec=row.spec,
            jobs=row.jobs,
            created_at=row.created_at,
            cancel_requested=row.cancel_requested,
            report=row.report,
            owner=row.owner,
        )


@dataclass(frozen=True)
class StudyJobState:
    """Where one of a study's jobs is, and what a study reads of it once it succeeded."""

    job_id: int
    point: int
    seed: int
    status: JobStatus
    fraction: float
    finished_at: datetime | None
    metrics: dict[str, Any] | None
    curve: dict[str, Any] | None


@dataclass(frozen=True)
class StudyProgress:
    """How far a study's jobs have got, summed up without reading any job's metrics."""

    study_id: int
    cancel_requested: bool
    jobs: dict[JobStatus, int]  # jobs per status; a status no job has is absent
    # (point, status, jobs) in order: with the metrics of its finished jobs, which never
    # change, all the study's report depends on
    by_point: tuple[tuple[int, str, int], ...]
    work_done: float  # 1 per finished job plus the fraction done of every other job
    last_finished_at: datetime | None  # when its latest finished job finished


@dataclass(frozen=True)
class StudyPage:
    studies: list[StudyRecord]
    next_before_id: int | None


class StudyStore:
    """Studies and their jobs on the job store's database."""

    def __init__(self, engine: Engine) -> None:
        self._sessions = make_sessionmaker(engine)

    def create(
        self,
        *,
        name: str,
        spec: dict[str, Any],
        jobs: Sequence[StudyJob],
        idempotency: Idempotency | None = None,
        callback_url: str | None = None,
        owner: str = "",
        quota: Quota | None = None,
    ) -> StudyRecord:
        """The study of ``owner`` and every one of its jobs, queued in one transaction; with a
        key of ``owner`` that still holds, the study that key made instead
        (``IdempotencyKeyReused`` if that was made by another request). Past ``quota`` (which
        counts every job of the study), ``QuotaExceeded``; ``PolicyNotFound`` if a policy
        that a job evaluates is gone."""
        quota_key = owner if quota is None else quota.key
        policies = evaluated_policies(job.scenario.get("policy_from") for job in jobs)

        def make(session: Session, now: datetime) -> Study:
            hold_policies(session, policies)
            steps = sum(job.robot_steps for job in jobs)
            check_quota(session, quota, jobs=len(jobs), robot_steps=steps)
            study = Study(
                name=name,
                spec=spec,
                jobs=len(jobs),
                owner=owner,
                idempotency_key=None if idempotency is None else idempotency.key,
                request_digest=None if idempotency is None else idempotency.digest,
                created_at=now,
                cancel_requested=False,
            )
            session.add(study)
            session.flush()
            session.execute(
                insert(Job),
                [
                    {
                        "status": JobStatus.QUEUED,
                        "scenario": job.scenario,
                        "robot_steps": job.robot_steps,
                        "owner": owner,
                        "quota_key": quota_key,
                        "created_at": now,
                        "episode": 0,
                        "episodes": job.episodes,
                        "fraction": 0.0,
                        "cancel_requested": False,
                        "attempts": 0,
                        "study_id": study.id,
                        "study_point": job.point,
                        "study_seed": job.seed,
                        "trains": trains_network(job.scenario),
                    }
                    for job in jobs
                ],
            )
            if callback_url is not None:
                add_waiting(session, callback_url, study_id=study.id)
            announce(session)
            return study

        reads_first = not (quota is None or quota.unlimited) or bool(policies)
        study = insert_once(
            self._sessions, Study, idempotency, make, owner=owner, reads_first=reads_first
        )
        return StudyRecord.of(study)

    def get(self, study_id: int) -> StudyRecord:
        with unit_of_work(self._sessions) as session:
            return StudyRecord.of(_study(session, study_id))

    def owner_of(self, study_id: int) -> str | None:
        """The owner of the study ('' for none), or None if there is no such study."""
        with unit_of_work(self._sessions) as session:
            owner: str | None = session.scalar(select(Study.owner).where(Study.id == study_id))
            return owner

    def page(self, *, limit: int, before_id: int | None, owner: str | None = None) -> StudyPage:
        """Up to ``limit`` studies, newest first, older than ``before_id`` when given; only
        those of ``owner`` when given."""
        query = select(Study).order_by(Study.id.desc()).limit(limit + 1)
        if owner is not None:
            query = query.where(Study.owner == owner)
        if before_id is not None:
            query = query.where(Study.id < before_id)
        with unit_of_work(self._sessions) as session:
            rows = [StudyRecord.of(row) for row in session.scalars(query)]
        more = len(rows) > limit
        rows = rows[:limit]
        return StudyPage(studies=rows, next_before_id=rows[-1].id if more else None)

    def job_states(self, study_id: int, *, curves: bool = False) -> list[StudyJobState]:
        """Every job of the study, in id order, with the metrics of those that succeeded (and
        their learning curves if ``curves``: larger, and only pictures need them)."""
        curve = JobResult.curve if curves else literal(None, JSON)
        query = (
            select(
                Job.id,
                Job.study_point,
                Job.study_seed,
                Job.status,
                Job.fraction,
                Job.finished_at,
                JobResult.study_metrics,
                curve,
            )
            .outerjoin(
                JobResult, (JobResult.job_id == Job.id) & (Job.status == JobStatus.SUCCEEDED)
            )
            .where(Job.study_id == study_id)
            .order_by(Job.id)
        )
        with unit_of_work(self._sessions) as session:
            _study(session, study_id)
            return [
                StudyJobState(
                    job_id=job_id,
                    point=point,
                    seed=seed,
                    status=JobStatus(status),
                    fraction=fraction,
                    finished_at=finished_at,
                    metrics=metrics,
                    curve=learning,
                )
                for job_id, point, seed, status, fraction, finished_at, metrics, learning in (
                    session.execute(query)
                )
            ]

    def counts(self, study_ids: Sequence[int]) -> dict[int, dict[JobStatus, int]]:
        """Jobs per status of each study, for lists of studies."""
        query = (
            select(Job.study_id, Job.status, func.count())
            .where(Job.study_id.in_(study_ids))
            .group_by(Job.study_id, Job.status)
        )
        found: dict[int, dict[JobStatus, int]] = {i: {} for i in study_ids}
        with unit_of_work(self._sessions) as session:
            for study_id, status, n in session.execute(query):
                if study_id is not None:
                    found[study_id][JobStatus(status)] = n
        return found

    def progress(self, study_ids: Collection[int]) -> dict[int, StudyProgress]:
        """Where each of these studies stands (those that exist), in one query: what an API
        process watching many studies for their clients reads every tick."""
        if not study_ids:
            return {}
        query = (
            select(
                Study.id,
                Study.cancel_requested,
                Job.study_point,
                Job.status,
                func.count(Job.id),
                func.sum(Job.fraction),
                func.max(Job.finished_at),
            )
            .outerjoin(Job, Job.study_id == Study.id)
            .where(Study.id.in_(sorted(study_ids)))
            .group_by(Study.id, Study.cancel_requested, Job.study_point, Job.status)
        )
        with unit_of_work(self._sessions) as session:
            rows = session.execute(query.order_by(Study.id, Job.study_point, Job.status)).all()
        found: dict[int, StudyProgress] = {}
        for study_id, group in groupby(rows, key=lambda row: int(row[0])):
            parts = list(group)
            cancel_requested = bool(parts[0][1])
            jobs: dict[JobStatus, int] = {}
            by_point: list[tuple[int, str, int]] = []
            work_done = 0.0
            ends: list[datetime] = []
            for _, _, point, status, n, fractions, finished_at in parts:
                if status is None:  # the one row of a study without jobs
                    continue
                status = JobStatus(status)
                jobs[status] = jobs.get(status, 0) + int(n)
                by_point.append((int(point or 0), status.value, int(n)))
                work_done += float(n) if status.finished else float(fractions or 0.0)
                if finished_at is not None:
                    ends.append(aware(finished_at))
            found[study_id] = StudyProgress(
                study_id, cancel_requested, jobs, tuple(by_point), work_done,
                max(ends, default=None),
            )  # fmt: skip
        return found

    def cancel(self, study_id: int) -> StudyRecord:
        """Its queued jobs are cancelled now, its running ones asked to stop."""
        now = utcnow()
        with unit_of_work(self._sessions, write=True) as session:
            study = _study(session, study_id)
            study.cancel_requested = True
            session.execute(
                update(Job)
                .where(Job.study_id == study_id, Job.status == JobStatus.QUEUED)
                .values(status=JobStatus.CANCELLED, finished_at=now)
                .execution_options(synchronize_session=False)
            )
            session.execute(
                update(Job)
                .where(Job.study_id == study_id, Job.status == JobStatus.RUNNING)
                .values(cancel_requested=True)
                .execution_options(synchronize_session=False)
            )
            session.flush()
            return StudyRecord.of(study)

    def retry_failed(self, study_id: int, *, quota: Quota | None = None) -> list[int]:
        """Queue the study's failed jobs again as if new (no attempts, error, progress or
        result), and drop its kept report and pictures, which no longer hold; the ids queued.
        Past ``quota`` (which counts the jobs queued again), ``QuotaExceeded``."""
        with unit_of_work(self._sessions, write=True) as session:
            study = _study(session, study_id)
            failed = session.execute(
                select(Job.id, Job.robot_steps)
                .where(Job.study_id == study_id, Job.status == JobStatus.FAILED)
                .order_by(Job.id)
            ).all()
            ids = [row.id for row in failed]
            if not ids:
                return []
            check_quota(
                session, quota, jobs=len(ids), robot_steps=sum(r.robot_steps for r in failed)
            )
            session.execute(delete(JobResult).where(JobResult.job_id.in_(ids)))
            session.execute(delete(JobPlot).where(JobPlot.job_id.in_(ids)))
            drop_checkpoints(session, ids)
            session.execute(
                update(Job)
                .where(Job.id.in_(ids))
                .values(
                    status=JobStatus.QUEUED, started_at=None, finished_at=None, episode=0,
                    fraction=0.0, error=None, attempts=0, cancel_requested=False,
                    lease_token=None, lease_owner=None, lease_expires_at=None, decisions=None,
                    resumed_from_decisions=None, training_curve=None, trained_policy_id=None,
                )
                .execution_options(synchronize_session=False)
            )  # fmt: skip
            study.report = None
            session.execute(delete(StudyPlot).where(StudyPlot.study_id == study_id))
            announce(session)
            return ids

    def delete(self, study_id: int, *, now: datetime | None = None) -> None:
        """Delete a study whose jobs have all ended, with its jobs, their results, its report
        and pictures."""
        with unit_of_work(self._sessions, write=True) as session:
            delete_study(session, study_id, now=now or utcnow())

    def keep_report(self, study_id: int, report: dict[str, Any]) -> None:
        """Keep the report of a finished study: its jobs will not change again."""
        with unit_of_work(self._sessions) as session:
            session.execute(update(Study).where(Study.id == study_id).values(report=report))

    def plot(self, study_id: int, name: str) -> bytes | None:
        with unit_of_work(self._sessions) as session:
            _study(session, study_id)
            return session.scalars(
                select(StudyPlot.png).where(StudyPlot.study_id == study_id, StudyPlot.name == name)
            ).one_or_none()

    def keep_plot(self, study_id: int, name: str, png: bytes) -> None:
        """Keep a picture of a finished study; one kept first by another process stays.
        StudyNotFound if the study was deleted while it was drawn."""
        try:
            add_once(self._sessions, StudyPlot(study_id=study_id, name=name, png=png))
        except IntegrityError:
            self.get(study_id)
            raise


def _study(session: Any, study_id: int) -> Study:
    row = session.get(Study, study_id)
    if row is None:
        raise StudyNotFound(study_id)
    assert isinstance(row, Study)
    return row
