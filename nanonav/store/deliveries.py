"""Every query about webhooks. Each public method of :class:`DeliveryStore` is one transaction.

A job or study that names a callback URL gets a ``waiting`` delivery in the transaction that
stores it. Once it has ended, ``promote`` fixes the summary it will send and makes it ``due``;
whoever sends it first ``claim``s it under a lease (as a worker claims a job), so that two
senders never send it at once, and ``settle``s it: ``delivered``, or due again after a
backoff, or ``failed`` once its attempts ran out. A sender that dies leaves a lease that runs
out, and the delivery is claimed again: a receiver may get one twice, never none.

A delivery keeps its URL in the form the sender sends it (``nanonav.webhooks.normalised``),
so what a client reads back at ``/callback`` is where the webhook goes. Each sender records on
its worker's row when it last made progress (``sender_passed``); ``backlog`` tells /healthz
what is due, since when, and when a sender was last seen sending.
"""

from __future__ import annotations

import secrets
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from typing import Any

from sqlalchemy import Engine, and_, delete, exists, func, or_, select, update
from sqlalchemy.orm import Session

from nanonav.store.db import make_sessionmaker, unit_of_work
from nanonav.store.models import (
    ENDED,
    Delivery,
    DeliveryState,
    Job,
    JobResult,
    JobStatus,
    Study,
    Worker,
)
from nanonav.studies.report import status_of
from nanonav.webhooks import normalised

PROMOTE_BATCH = 100
ERROR_LENGTH = 500


@dataclass(frozen=True)
class DeliveryRecord:
    """A delivery as a client may see it: where it goes and how it went, not what it sends."""

    id: int
    url: str
    state: DeliveryState
    event: str | None
    attempts: int
    created_at: datetime
    next_attempt_at: datetime | None
    last_attempt_at: datetime | None
    delivered_at: datetime | None
    last_status: int | None
    last_error: str | None

    @classmethod
    def of(cls, row: Delivery) -> DeliveryRecord:
        return cls(
            id=row.id,
            url=row.url,
            state=DeliveryState(row.state),
            event=row.event,
            attempts=row.attempts,
            created_at=row.created_at,
            next_attempt_at=row.next_attempt_at if row.state == DeliveryState.DUE else None,
            last_attempt_at=row.last_attempt_at,
            delivered_at=row.delivered_at,
            last_status=row.last_status,
            last_error=row.last_error,
        )


@dataclass(frozen=True)
class DeliveryClaim:
    """A due delivery a sender holds; ``token`` fences the write that settles it."""

    id: int
    url: str
    event: str
    payload: dict[str, Any]
    attempts: int  # tries before this one
    token: str


@dataclass(frozen=True)
class Backlog:
    """How the webhooks to send stand, for /healthz."""

    due: int  # to send now: their next try's time has come, or their job or study has ended
    retrying: int  # due again once the backoff after a failed try has passed
    oldest_due_at: datetime | None  # since when the longest-waiting of the ``due`` could go
    last_pass_at: datetime | None  # the latest progress a worker's sender recorded


def add_waiting(session: Session, url: str, *, job_id: int | None = None,
                study_id: int | None = None) -> None:  # fmt: skip
    """In the transaction that stores a job or a study, the webhook its end will send, to
    ``url`` as the sender will send it (``Refused``, a ValueError, if it never could be)."""
    session.add(
        Delivery(
            job_id=job_id,
            study_id=study_id,
            url=normalised(url),
            state=DeliveryState.WAITING,
            created_at=utcnow(),
            attempts=0,
        )
    )


class DeliveryStore:
    """The webhook outbox on the job store's database."""

    def __init__(self, engine: Engine) -> None:
        self._sessions = make_sessionmaker(engine)

    def for_job(self, job_id: int) -> DeliveryRecord | None:
        return self._one(Delivery.job_id == job_id)

    def for_study(self, study_id: int) -> DeliveryRecord | None:
        return self._one(Delivery.study_id == study_id)

    def _one(self, where: Any) -> DeliveryRecord | None:
        with unit_of_work(self._sessions) as session:
            row = session.scalars(select(Delivery).where(where)).one_or_none()
            return None if row is None else DeliveryRecord.of(row)

    def promote(self, *, now: datetime | None = None) -> int:
        """Make due the waiting deliveries whose job or study has ended, each with the summary
        it will send; returns how many."""
        now = now or utcnow()
        query = (
            select(Delivery)
            .where(Delivery.state == DeliveryState.WAITING, _ended())
            .order_by(Delivery.id)
            .limit(PROMOTE_BATCH)
            .with_for_update(skip_locked=True, of=Delivery)
        )
        with unit_of_work(self._sessions, write=True) as session:
            rows = session.scalars(query).all()
            for row in rows:
                _make_due(session, row, now)
            return len(rows)

    def claim(self, *, lease_s: float, now: datetime | None = None) -> DeliveryClaim | None:
        """The due delivery that has waited longest, held for ``lease_s``, or None."""
        now = now or utcnow()
        token = secrets.token_hex(16)
        oldest = (
            select(Delivery.id)
            .where(
                Delivery.state == DeliveryState.DUE,
                Delivery.next_attempt_at <= now,
                or_(Delivery.lease_expires_at.is_(None), Delivery.lease_expires_at < now),
            )
            .order_by(Delivery.next_attempt_at, Delivery.id)
            .limit(1)
            .with_for_update(skip_locked=True)
            .scalar_subquery()
        )
        statement = (
            update(Delivery)
            .where(Delivery.id == oldest, Delivery.state == DeliveryState.DUE)
            .values(lease_token=token, lease_expires_at=now + timedelta(seconds=lease_s))
            .returning(Delivery)
            .execution_options(synchronize_session=False)
        )
        with unit_of_work(self._sessions, write=True) as session:
            row = session.scalars(statement).one_or_none()
            if row is None or row.event is None or row.payload is None:
                return None
            return DeliveryClaim(
                id=row.id,
                url=row.url,
                event=row.event,
                payload=row.payload,
                attempts=row.attempts,
                token=token,
            )

    def settle(
        self,
        claim: DeliveryClaim,
        *,
        status: int | None,
        error: str | None,
        retry_in_s: float | None,
        now: datetime | None = None,
    ) -> bool:
        """Record one try: delivered when ``error`` is None, else due again in ``retry_in_s``
        (None: given up). False if the claim's lease was lost (another sender has it now)."""
        now = now or utcnow()
        values: dict[str, Any] = {
            "attempts": Delivery.attempts + 1,
            "last_attempt_at": now,
            "last_status": status,
            "last_error": None if error is None else error[:ERROR_LENGTH],
            "lease_token": None,
            "lease_expires_at": None,
        }
        if error is None:
            values.update(state=DeliveryState.DELIVERED, delivered_at=now)
        elif retry_in_s is None:
            values.update(state=DeliveryState.FAILED)
        else:
            values.update(next_attempt_at=now + timedelta(seconds=retry_in_s))
        statement = (
            update(Delivery)
            .where(
                Delivery.id == claim.id,
                Delivery.lease_token == claim.token,
                Delivery.state == DeliveryState.DUE,
            )
            .values(**values)
            .returning(Delivery.id)
            .execution_options(synchronize_session=False)
        )
        with unit_of_work(self._sessions, write=True) as session:
            return session.scalars(statement).one_or_none() is not None

    def sender_passed(self, worker: str, *, now: datetime | None = None) -> None:
        """Record on the row of the worker ``worker`` that its sender made progress now."""
        statement = (
            update(Worker)
            .where(Worker.name == worker)
            .values(webhooks_passed_at=now or utcnow())
            .execution_options(synchronize_session=False)
        )
        with unit_of_work(self._sessions, write=True) as session:
            session.execute(statement)

    def backlog(self, *, now: datetime | None = None) -> Backlog:
        """What is due and since when, and when a sender last made progress."""
        now = now or utcnow()
        due = Delivery.state == DeliveryState.DUE
        # A waiting delivery whose job or study has ended is due as soon as a sender passes:
        # without one it would never look due. It could go since its last job ended.
        ended_at = (
            select(func.max(Job.finished_at))
            .where(or_(Job.id == Delivery.job_id, Job.study_id == Delivery.study_id))
            .correlate(Delivery)
            .scalar_subquery()
        )
        ended = (
            select(func.coalesce(ended_at, Delivery.created_at).label("at"))
            .where(Delivery.state == DeliveryState.WAITING, _ended())
            .subquery()
        )
        with unit_of_work(self._sessions) as session:
            ready, ready_since = session.execute(
                select(func.count(), func.min(Delivery.next_attempt_at)).where(
                    due, Delivery.next_attempt_at <= now
                )
            ).one()
            retrying = session.scalar(
                select(func.count()).where(due, Delivery.next_attempt_at > now)
            )
            waiting, waiting_since = session.execute(
                select(func.count(), func.min(ended.c.at))
            ).one()
            last_pass = session.scalar(select(func.max(Worker.webhooks_passed_at)))
        since = [_aware(at) for at in (ready_since, waiting_since) if at is not None]
        return Backlog(
            due=int(ready) + int(waiting),
            retrying=int(retrying or 0),
            oldest_due_at=min(since, default=None),
            last_pass_at=None if last_pass is None else _aware(last_pass),
        )

    def pending(self) -> int:
        """Deliveries that are due (to be sent now or after a backoff)."""
        query = select(func.count()).where(Delivery.state == DeliveryState.DUE)
        with unit_of_work(self._sessions) as session:
            return int(session.scalar(query) or 0)


def detach(session: Session, where: Any, *, now: datetime) -> None:
    """In the transaction that deletes the jobs or studies ``where`` selects deliveries of:
    a webhook not sent yet gets its summary now and outlives them, detached, to be sent as
    promised; one already delivered or given up goes with them."""
    waiting = (
        select(Delivery)
        .where(where, Delivery.state == DeliveryState.WAITING)
        .order_by(Delivery.id)
        .with_for_update(of=Delivery)
    )
    for row in session.scalars(waiting).all():
        _make_due(session, row, now)
    session.execute(
        delete(Delivery)
        .where(where, Delivery.state.in_([DeliveryState.DELIVERED, DeliveryState.FAILED]))
        .execution_options(synchronize_session=False)
    )
    session.flush()


def settled_orphans(before: datetime) -> Any:
    """Deliveries whose job or study was deleted, settled before ``before``: nothing reads
    them any more."""
    return and_(
        Delivery.job_id.is_(None),
        Delivery.study_id.is_(None),
        Delivery.state.in_([DeliveryState.DELIVERED, DeliveryState.FAILED]),
        func.coalesce(Delivery.last_attempt_at, Delivery.created_at) < before,
    )


def _ended() -> Any:
    """Deliveries whose job or study has ended (or was deleted): theirs is to be sent."""
    job_ended = and_(
        Delivery.job_id.is_not(None),
        exists().where(Job.id == Delivery.job_id, Job.status.in_(ENDED)),
    )
    study_ended = and_(
        Delivery.study_id.is_not(None),
        ~exists().where(Job.study_id == Delivery.study_id, Job.status.not_in(ENDED)),
    )
    orphaned = and_(Delivery.job_id.is_(None), Delivery.study_id.is_(None))
    return or_(job_ended, study_ended, orphaned)


def _aware(value: datetime) -> datetime:
    """Aggregates bypass the column type: SQLite and PostgreSQL give naive UTC back."""
    return value if value.tzinfo is not None else value.replace(tzinfo=UTC)


def _make_due(session: Session, row: Delivery, now: datetime) -> None:
    """Fix the summary a waiting delivery sends, from its ended job or study, and make it due."""
    if row.job_id is not None:
        row.event, payload = _job_summary(session, row.job_id)
    elif row.study_id is not None:
        row.event, payload = _study_summary(session, row.study_id)
    else:
        row.state = DeliveryState.FAILED
        row.last_error = "its job or study was deleted before it ended"
        return
    row.payload = {"id": row.id, "event": row.event, "created_at": _iso(now), **payload}
    row.state = DeliveryState.DUE
    row.next_attempt_at = now


def utcnow() -> datetime:
    return datetime.now(UTC)


def _iso(moment: datetime | None) -> str | None:
    return None if moment is None else moment.isoformat()


def _job_summary(session: Session, job_id: int) -> tuple[str, dict[str, Any]]:
    job = session.get_one(Job, job_id)
    metrics = session.scalar(select(JobResult.metrics).where(JobResult.job_id == job_id))
    summary = (metrics or {}).get("summary")
    return f"job.{job.status}", {
        "job": {
            "id": job.id,
            "status": str(job.status),
            "error": job.error,
            "created_at": _iso(job.created_at),
            "started_at": _iso(job.started_at),
            "finished_at": _iso(job.finished_at),
            "attempts": job.attempts,
            "study_id": job.study_id,
            "summary": summary if job.status != JobStatus.FAILED else None,
            "url": f"/jobs/{job.id}",
        }
    }


def _study_summary(session: Session, study_id: int) -> tuple[str, dict[str, Any]]:
    study = session.get_one(Study, study_id)
    counted = select(Job.status, func.count()).where(Job.study_id == study_id).group_by(Job.status)
    counts = {str(status): int(n) for status, n in session.execute(counted).all()}
    status = status_of(counts, study.cancel_requested)
    return f"study.{status}", {
        "study": {
            "id": study.id,
            "name": study.name,
            "status": status,
            "jobs": {str(s): counts.get(str(s), 0) for s in JobStatus},
            "created_at": _iso(study.created_at),
            "url": f"/studies/{study.id}",
        }
    }
