"""Every query of the job queue. Each public method of :class:`JobStore` is one transaction.

The life of a job: ``enqueue`` -> ``claim`` (a lease with a fresh token) -> ``report_progress``
(renews the lease, says whether a cancel was asked) -> ``finish`` / ``fail`` / ``release``; all
three are fenced by the lease token. ``recover_expired`` hands back the jobs of dead workers.
"""

from __future__ import annotations

import secrets
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from typing import Any

from numpy.typing import NDArray
from sqlalchemy import (
    Engine,
    Row,
    Select,
    bindparam,
    case,
    delete,
    func,
    literal,
    select,
    text,
    update,
)
from sqlalchemy.exc import IntegrityError, SQLAlchemyError
from sqlalchemy.orm import Session

from nanonav.store.arrays import pack, unpack
from nanonav.store.db import (
    BUSY_TIMEOUT_S,
    WRITE_LOCK,
    add_once,
    make_engine,
    make_sessionmaker,
    unit_of_work,
)
from nanonav.store.deliveries import add_waiting
from nanonav.store.errors import JobAlreadyFinished, JobNotFound, LeaseLost, ResultsUnavailable
from nanonav.store.idempotency import Idempotency, insert_once
from nanonav.store.models import Job, JobPlot, JobResult, JobStatus, UTCDateTime, Worker
from nanonav.store.policies import (
    Network,
    PolicySource,
    PolicyStore,
    evaluated_policies,
    hold_policies,
    policy_number,
)
from nanonav.store.quotas import Quota, check_quota
from nanonav.store.retention import delete_job
from nanonav.store.training import TrainingStore, drop_checkpoints, trains_network
from nanonav.store.wakeups import announce

# A worker says it is alive this often; it counts as present for PRESENCE_WINDOW_S after.
PRESENCE_INTERVAL_S = 5.0
PRESENCE_WINDOW_S = 30.0


def utcnow() -> datetime:
    return datetime.now(UTC)


@dataclass(frozen=True)
class JobRecord:
    """A job as its row says, detached from any session."""

    id: int
    status: JobStatus
    scenario: dict[str, Any]
    robot_steps: int
    idempotency_key: str | None
    created_at: datetime
    started_at: datetime | None
    finished_at: datetime | None
    episode: int
    episodes: int
    fraction: float
    cancel_requested: bool
    error: str | None
    attempts: int
    study_id: int | None = None
    owner: str = ""
    trains: bool = False  # it trains a network: only a worker that trains claims it
    decisions: int | None = None  # while it trains, the decisions done
    training_curve: list[dict[str, Any]] | None = None  # and its training curve so far
    resumed_from_decisions: int | None = None  # the checkpoint it was taken up from
    trained_policy_id: int | None = None  # the policy its trained network was kept as
    # Whether the store keeps a Q-table for the job (its run ended with one): read with the
    # record by :data:`_RECORDS`; a record of an ORM row says False.
    has_qtable: bool = False

    @classmethod
    def of(cls, row: Job | Row[Any]) -> JobRecord:
        """The record of an ORM row, or of a row of :data:`_RECORDS`."""
        return cls(
            id=row.id,
            status=JobStatus(row.status),
            scenario=row.scenario,
            robot_steps=row.robot_steps,
            idempotency_key=row.idempotency_key,
            created_at=row.created_at,
            started_at=row.started_at,
            finished_at=row.finished_at,
            episode=row.episode,
            episodes=row.episodes,
            fraction=row.fraction,
            cancel_requested=row.cancel_requested,
            error=row.error,
            attempts=row.attempts,
            study_id=row.study_id,
            owner=row.owner,
            trains=bool(row.trains),
            decisions=row.decisions,
            training_curve=row.training_curve,
            resumed_from_decisions=row.resumed_from_decisions,
            trained_policy_id=row.trained_policy_id,
            has_qtable=isinstance(row, Row) and bool(row.has_qtable),
        )


# The columns a JobRecord is made of, and the read of one job by id, built once.
RECORD_COLUMNS = tuple(
    Job.__table__.c[name] for name in JobRecord.__dataclass_fields__ if name != "has_qtable"
)
_HAS_QTABLE = (
    select(JobResult.job_id)
    .where(JobResult.job_id == Job.id, JobResult.qtable.is_not(None))
    .exists()
    .label("has_qtable")
)
_RECORDS: Select[Any] = select(*RECORD_COLUMNS, _HAS_QTABLE)
_RECORD_BY_ID = _RECORDS.where(Job.id == bindparam("job_id"))
# Whether anything waits: read without a lock before a claim takes one.
_ANY_QUEUED = select(Job.id).where(Job.status == JobStatus.QUEUED).limit(1)
_ANY_QUEUED_UNTRAINED = _ANY_QUEUED.where(Job.trains.is_(False))


@dataclass(frozen=True)
class Claim:
    """A job a worker holds; ``token`` fences every write the worker makes about it."""

    job: JobRecord
    token: str
    owner: str


@dataclass(frozen=True)
class Page:
    jobs: list[JobRecord]
    next_before_id: int | None


@dataclass(frozen=True)
class Outcome:
    """What a run produced, as the worker hands it to the store."""

    completed: bool
    metrics: dict[str, Any]
    trajectory: Mapping[str, NDArray[Any]] | None
    qtable: Mapping[str, NDArray[Any]] | None
    study_metrics: dict[str, Any] | None = None  # what a study reads of the job
    curve: dict[str, Any] | None = None  # its learning curve, binned, for a study's pictures
    trained: Network | None = None  # the network it trained, kept as a policy of its owner


@dataclass(frozen=True)
class Census:
    """How busy the queue is and who works it."""

    queued: int
    running: int
    workers: int  # worker processes seen within the window asked for, ready for jobs
    oldest_queued_at: datetime | None
    preparing: int = 0  # and those seen that still prepare the engine
    trainers: int = 0  # of the ready ones, those that train networks (``worker --train``)


class JobStore:
    """The job queue and its results on one database."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine
        self._sessions = make_sessionmaker(engine)
        self.policies = PolicyStore(engine)
        self.training = TrainingStore(engine)

    @classmethod
    def from_url(cls, url: str, *, busy_timeout_s: float = BUSY_TIMEOUT_S) -> JobStore:
        return cls(make_engine(url, busy_timeout_s=busy_timeout_s))

    def close(self) -> None:
        self.engine.dispose()

    # -- the client's side ------------------------------------------------------------------

    def enqueue(
        self,
        scenario: dict[str, Any],
        *,
        robot_steps: int,
        episodes: int,
        idempotency: Idempotency | None = None,
        callback_url: str | None = None,
        owner: str = "",
        quota: Quota | None = None,
    ) -> JobRecord:
        """A new queued job of ``owner`` (with the webhook its end sends to ``callback_url``);
        with a key of ``owner`` that still holds, the job that key made instead
        (``IdempotencyKeyReused`` if that was made by another request). Past ``quota``,
        ``QuotaExceeded``; ``PolicyNotFound`` if the policy it evaluates is gone."""
        policies = evaluated_policies([scenario.get("policy_from")])

        def make(session: Session, now: datetime) -> Job:
            hold_policies(session, policies)
            check_quota(session, quota, jobs=1, robot_steps=robot_steps)
            row = Job(
                status=JobStatus.QUEUED,
                scenario=scenario,
                robot_steps=robot_steps,
                owner=owner,
                quota_key=owner if quota is None else quota.key,
                idempotency_key=None if idempotency is None else idempotency.key,
                request_digest=None if idempotency is None else idempotency.digest,
                created_at=now,
                episode=0,
                episodes=episodes,
                fraction=0.0,
                cancel_requested=False,
                attempts=0,
                trains=trains_network(scenario),
            )
            session.add(row)
            session.flush()
            if callback_url is not None:
                add_waiting(session, callback_url, job_id=row.id)
            announce(session)
            return row

        reads_first = not (quota is None or quota.unlimited) or bool(policies)
        row = insert_once(
            self._sessions, Job, idempotency, make, owner=owner, reads_first=reads_first
        )
        return JobRecord.of(row)

    def get(self, job_id: int) -> JobRecord:
        """The job; what clients poll most, so read with one cached statement on a connection,
        without the ORM's session and identity map, which cost twice the query itself."""
        with self.engine.connect() as connection:
            row = connection.execute(_RECORD_BY_ID, {"job_id": job_id}).one_or_none()
        if row is None:
            raise JobNotFound(job_id)
        return JobRecord.of(row)

    def owner_of(self, job_id: PolicySource) -> str | None:
        """The owner of the job (its key's digest, '' for none), or None if there is no job;
        given a policy's name (``policy-<id>``, as a ``policy_from`` names it), the policy's."""
        if isinstance(job_id, str):
            return self.policies.owner_of(policy_number(job_id))
        with unit_of_work(self._sessions) as session:
            owner: str | None = session.scalar(select(Job.owner).where(Job.id == job_id))
            return owner

    def get_many(self, job_ids: Collection[int]) -> dict[int, JobRecord]:
        """The jobs among ``job_ids`` that exist, by id, in one query: what an API process
        watching many jobs for their clients reads every tick."""
        if not job_ids:
            return {}
        query = _RECORDS.where(Job.id.in_(sorted(job_ids)))
        with self.engine.connect() as connection:
            return {row.id: JobRecord.of(row) for row in connection.execute(query)}

    def page(
        self,
        *,
        status: JobStatus | None,
        limit: int,
        before_id: int | None,
        study_id: int | None = None,
        policy: str | None = None,
        owner: str | None = None,
        standalone: bool = False,
    ) -> Page:
        """Up to ``limit`` jobs, newest first, older than ``before_id`` when given; only those
        in ``status``, of ``study_id``, whose robots follow ``policy``, or of ``owner``, when
        given; only those of no study if ``standalone``."""
        query = _RECORDS.order_by(Job.id.desc()).limit(limit + 1)
        if owner is not None:
            query = query.where(Job.owner == owner)
        if status is not None:
            query = query.where(Job.status == status)
        if study_id is not None:
            query = query.where(Job.study_id == study_id)
        if standalone:
            query = query.where(Job.study_id.is_(None))
        if policy is not None:
            query = query.where(Job.scenario[("robots", "policy")].as_string() == policy)
        if before_id is not None:
            query = query.where(Job.id < before_id)
        with unit_of_work(self._sessions) as session:
            rows = [JobRecord.of(row) for row in session.execute(query)]
        more = len(rows) > limit
        rows = rows[:limit]
        return Page(jobs=rows, next_before_id=rows[-1].id if more else None)

    def cancel(self, job_id: int) -> JobRecord:
        """A queued job is cancelled now; a running one is asked to stop."""
        now = utcnow()
        with unit_of_work(self._sessions, write=True) as session:
            row = _job(session, job_id)
            if row.status == JobStatus.QUEUED:
                row.status = JobStatus.CANCELLED
                row.finished_at = now
                drop_checkpoints(session, [job_id])
            elif row.status == JobStatus.RUNNING:
                row.cancel_requested = True
            elif row.status != JobStatus.CANCELLED:
                raise JobAlreadyFinished(job_id, JobStatus(row.status))
            session.flush()
            # read back as get() reads it: a job cancelled before may keep its Q-table
            return JobRecord.of(session.execute(_RECORD_BY_ID, {"job_id": job_id}).one())

    def delete(self, job_id: int, *, now: datetime | None = None) -> None:
        """Delete a finished job of no study with its results, pictures and settled webhook
        (one not sent yet is still sent)."""
        with unit_of_work(self._sessions, write=True) as session:
            delete_job(session, job_id, now=now or utcnow())

    def metrics(self, job_id: int) -> dict[str, Any]:
        """A succeeded job's metrics, or what a cancelled one kept (its finished episodes)."""
        with unit_of_work(self._sessions) as session:
            metrics: dict[str, Any] = _result_column(session, job_id, JobResult.metrics, kept=True)
            return metrics

    def headlines(self, job_ids: Sequence[int]) -> dict[int, dict[str, Any]]:
        """What a list of jobs shows of each succeeded one's results (its study metrics: success
        rate, steps...), in one query for the whole list."""
        if not job_ids:
            return {}
        with unit_of_work(self._sessions) as session:
            rows = session.execute(
                select(JobResult.job_id, JobResult.study_metrics).where(
                    JobResult.job_id.in_(list(job_ids)), JobResult.study_metrics.is_not(None)
                )
            ).all()
            return {int(job_id): dict(found) for job_id, found in rows if found}

    def trajectory(self, job_id: int) -> dict[str, NDArray[Any]]:
        blob = self.trajectory_npz(job_id)
        arrays = unpack(blob) if blob is not None else {}
        if "steps" in arrays and "robot_steps" not in arrays:
            arrays["robot_steps"] = arrays.pop("steps")  # recorded before the rename
        return arrays

    def trajectory_npz(self, job_id: int) -> bytes | None:
        """The trajectory as the ``.npz`` bytes it is stored as, without decoding it."""
        with unit_of_work(self._sessions) as session:
            blob: bytes | None = _result_column(session, job_id, JobResult.trajectory)
            return blob

    def qtable(self, job_id: PolicySource) -> dict[str, NDArray[Any]]:
        """A succeeded job's Q-table, or the one a cancelled job learned until it stopped; given
        a policy's name (``policy-<id>``), the table sent as that policy."""
        if isinstance(job_id, str):
            return self.policies.table(policy_number(job_id))
        with unit_of_work(self._sessions) as session:
            blob: bytes | None = _result_column(session, job_id, JobResult.qtable, kept=True)
        return unpack(blob) if blob is not None else {}

    def qtables(self, job_ids: Sequence[int]) -> dict[int, dict[str, NDArray[Any]]]:
        """The Q-tables of a list of jobs, in one query for the whole list: those that kept one
        (a study's learning points, say); a job without one is left out."""
        if not job_ids:
            return {}
        with unit_of_work(self._sessions) as session:
            rows = session.execute(
                select(JobResult.job_id, JobResult.qtable).where(
                    JobResult.job_id.in_(list(job_ids)), JobResult.qtable.is_not(None)
                )
            ).all()
        return {int(job_id): unpack(blob) for job_id, blob in rows if blob is not None}

    def plot(self, job_id: int, name: str, *, kept: bool = False) -> bytes | None:
        """The PNG ``name`` of a succeeded job (or, if ``kept``, of a cancelled job that kept
        its episodes) if it has been drawn, else None."""
        with unit_of_work(self._sessions) as session:
            _with_results(session, job_id, kept=kept)
            return session.scalars(
                select(JobPlot.png).where(JobPlot.job_id == job_id, JobPlot.name == name)
            ).one_or_none()

    def save_plot(self, job_id: int, name: str, png: bytes) -> None:
        """Keep a picture drawn for a succeeded job; one kept first by another process stays.
        JobNotFound if the job was deleted while it was drawn."""
        try:
            add_once(self._sessions, JobPlot(job_id=job_id, name=name, png=png))
        except IntegrityError:
            self.get(job_id)
            raise

    def partial_result(self, job_id: int) -> dict[str, Any] | None:
        """The metrics a job stored whatever its status (a cancelled job keeps its episodes)."""
        with unit_of_work(self._sessions) as session:
            _job(session, job_id)
            metrics: dict[str, Any] | None = session.scalars(
                select(JobResult.metrics).where(JobResult.job_id == job_id)
            ).one_or_none()
            return metrics

    def writable(self) -> bool:
        """Whether the store takes a write now: a no-op update, rolled back."""
        try:
            connection = self.engine.connect().execution_options(**{WRITE_LOCK: True})
            with connection, connection.begin() as transaction:
                connection.execute(text("UPDATE alembic_version SET version_num = version_num"))
                transaction.rollback()
        except SQLAlchemyError:
            return False
        return True

    def census(
        self, *, seen_within_s: float, now: datetime | None = None, host: str | None = None
    ) -> Census:
        """Jobs waiting and running, and the workers seen in the last ``seen_within_s`` (only
        those on the machine ``host``, when given)."""
        now = now or utcnow()
        counts = (
            select(Job.status, func.count(), func.min(Job.created_at))
            .where(Job.status.in_([JobStatus.QUEUED, JobStatus.RUNNING]))
            .group_by(Job.status)
        )
        seen = (
            select(Worker.ready_at.is_not(None), Worker.trains, func.count())
            .where(Worker.seen_at >= now - timedelta(seconds=seen_within_s))
            .group_by(Worker.ready_at.is_not(None), Worker.trains)
        )
        if host is not None:  # a worker is named host:pid
            seen = seen.where(Worker.name.startswith(f"{host}:", autoescape=True))
        with unit_of_work(self._sessions) as session:
            found = {
                JobStatus(status): (n, oldest) for status, n, oldest in session.execute(counts)
            }
            ready: dict[tuple[bool, bool], int] = {
                (bool(is_ready), bool(trains)): n for is_ready, trains, n in session.execute(seen)
            }
        queued, oldest_queued = found.get(JobStatus.QUEUED, (0, None))
        running, _ = found.get(JobStatus.RUNNING, (0, None))
        return Census(
            queued=queued,
            running=running,
            workers=ready.get((True, False), 0) + ready.get((True, True), 0),
            oldest_queued_at=None if oldest_queued is None else aware(oldest_queued),
            preparing=ready.get((False, False), 0) + ready.get((False, True), 0),
            trainers=ready.get((True, True), 0),
        )

    # -- the worker's side ------------------------------------------------------------------

    def worker_seen(
        self,
        name: str,
        *,
        started_at: datetime,
        ready: bool = True,
        trains: bool = False,
        now: datetime | None = None,
    ) -> None:
        """Record that the worker ``name`` is alive (it calls this every few seconds), whether
        it is ready for jobs or still prepares the engine, and whether it trains networks."""
        now = now or utcnow()
        with unit_of_work(self._sessions, write=True) as session:
            row = session.get(Worker, name)
            if row is None:
                row = Worker(name=name, started_at=started_at, seen_at=now)
                session.add(row)
            row.seen_at = now
            row.trains = trains
            if ready and row.ready_at is None:
                row.ready_at = now

    def worker_gone(self, name: str) -> None:
        """Forget a worker that stopped cleanly."""
        with unit_of_work(self._sessions) as session:
            session.execute(delete(Worker).where(Worker.name == name))

    def claim(
        self, owner: str, *, lease_s: float, trains: bool = False, now: datetime | None = None
    ) -> Claim | None:
        """The oldest queued job, now running under a new lease, or None if nothing waits;
        a job that trains a network only if the worker ``trains``."""
        # An idle worker polls often: it looks first, so that it takes SQLite's write lock only
        # when there is a job to claim (a worker frozen while it holds it stalls every write).
        with self.engine.connect() as connection:
            if connection.execute(_ANY_QUEUED if trains else _ANY_QUEUED_UNTRAINED).first() is None:
                return None
        now = now or utcnow()
        token = secrets.token_hex(16)
        queued = Job.status == JobStatus.QUEUED
        oldest = (
            select(Job.id)
            .where(queued if trains else queued & Job.trains.is_(False))
            .order_by(Job.id)
            .limit(1)
            .with_for_update(skip_locked=True)
            .scalar_subquery()
        )
        claim = (
            update(Job)
            .where(Job.id == oldest, Job.status == JobStatus.QUEUED)
            .values(
                status=JobStatus.RUNNING,
                lease_token=token,
                lease_owner=owner,
                lease_expires_at=now + timedelta(seconds=lease_s),
                attempts=Job.attempts + 1,
                started_at=now,
                error=None,
            )
            .returning(Job)
            .execution_options(synchronize_session=False)
        )
        with unit_of_work(self._sessions, write=True) as session:
            row = session.scalars(claim).one_or_none()
            if row is None:
                return None
            return Claim(job=JobRecord.of(row), token=token, owner=owner)

    def report_progress(
        self,
        claim: Claim,
        *,
        episode: int,
        episodes: int,
        fraction: float,
        lease_s: float,
        decisions: int | None = None,
        curve: list[dict[str, Any]] | None = None,
        now: datetime | None = None,
    ) -> bool:
        """Write the progress (and a training's ``decisions`` done and its ``curve`` so far,
        when given), renew the lease; True if a client asked to cancel the job."""
        now = now or utcnow()
        values: dict[str, Any] = {} if decisions is None else {"decisions": decisions}
        if curve is not None:
            values["training_curve"] = curve
        statement = (
            _fenced(claim)
            .values(
                episode=episode,
                episodes=episodes,
                fraction=min(max(fraction, 0.0), 1.0),
                lease_expires_at=now + timedelta(seconds=lease_s),
                **values,
            )
            .returning(Job.cancel_requested)
        )
        with unit_of_work(self._sessions) as session:
            cancel = session.scalars(statement).one_or_none()
        if cancel is None:
            raise LeaseLost(claim.job.id)
        return bool(cancel)

    def renew(self, claim: Claim, *, lease_s: float, now: datetime | None = None) -> None:
        """Extend the lease without touching the progress (a heartbeat)."""
        now = now or utcnow()
        statement = (
            _fenced(claim)
            .values(lease_expires_at=now + timedelta(seconds=lease_s))
            .returning(Job.id)
        )
        with unit_of_work(self._sessions) as session:
            if session.scalars(statement).one_or_none() is None:
                raise LeaseLost(claim.job.id)

    def finish(self, claim: Claim, outcome: Outcome, *, now: datetime | None = None) -> JobRecord:
        """Store what the run produced; the job ends succeeded, or cancelled if it was stopped."""
        now = now or utcnow()
        status = JobStatus.SUCCEEDED if outcome.completed else JobStatus.CANCELLED
        values: dict[str, Any] = {"status": status, "finished_at": now, **_lease_cleared()}
        if outcome.completed:
            values.update(fraction=1.0, episode=Job.episodes)
        if "training_curve" in outcome.metrics:  # whole, the rows written while it ran or not
            values["training_curve"] = outcome.metrics["training_curve"]
        # Compressed before the write lock is taken, which is held for the writes alone.
        result = JobResult(
            job_id=claim.job.id,
            completed=outcome.completed,
            metrics=outcome.metrics,
            trajectory=None if outcome.trajectory is None else pack(outcome.trajectory),
            qtable=None if outcome.qtable is None else pack(outcome.qtable),
            study_metrics=outcome.study_metrics,
            curve=outcome.curve,
        )
        with unit_of_work(self._sessions, write=True) as session:
            if outcome.trained is not None and outcome.completed:
                policy = outcome.trained.row(owner=claim.job.owner, created_at=now)
                session.add(policy)
                session.flush()
                values["trained_policy_id"] = policy.id
            row = _write_fenced(session, claim, values)
            session.add(result)
            drop_checkpoints(session, [claim.job.id])
            return JobRecord.of(row)

    def fail(self, claim: Claim, error: str, *, now: datetime | None = None) -> JobRecord:
        """The job ends failed with ``error``, a sentence a person can read."""
        now = now or utcnow()
        values = {"status": JobStatus.FAILED, "finished_at": now, "error": error}
        with unit_of_work(self._sessions) as session:
            row = _write_fenced(session, claim, {**values, **_lease_cleared()})
            drop_checkpoints(session, [claim.job.id])
            return JobRecord.of(row)

    def release(self, claim: Claim) -> JobRecord:
        """Give the job back to the queue untouched, as if this claim had never happened."""
        values = {
            "status": JobStatus.QUEUED,
            "attempts": Job.attempts - 1,
            "started_at": None,
            "episode": 0,
            "fraction": 0.0,
        }
        with unit_of_work(self._sessions) as session:
            row = _write_fenced(session, claim, {**values, **_lease_cleared()})
            announce(session)
            return JobRecord.of(row)

    def recover_expired(self, *, max_attempts: int, now: datetime | None = None) -> int:
        """Jobs whose lease ran out (their worker died) are queued again, or failed once they
        used ``max_attempts`` claims, or cancelled if a cancel was asked; returns how many."""
        now = now or utcnow()
        status = case(
            (Job.cancel_requested, JobStatus.CANCELLED.value),
            (Job.attempts >= max_attempts, JobStatus.FAILED.value),
            else_=JobStatus.QUEUED.value,
        )
        error = case(
            (Job.cancel_requested, None),
            (
                Job.attempts >= max_attempts,
                f"its worker stopped answering {max_attempts} times; given up",
            ),
            else_=None,
        )
        finished = case(
            (Job.cancel_requested | (Job.attempts >= max_attempts), literal(now, UTCDateTime())),
            else_=None,
        )
        statement = (
            update(Job)
            .where(Job.status == JobStatus.RUNNING, Job.lease_expires_at < now)
            .values(status=status, error=error, finished_at=finished, **_lease_cleared())
            .returning(Job.id, Job.status)
            .execution_options(synchronize_session=False)
        )
        with unit_of_work(self._sessions, write=True) as session:
            found = session.execute(statement).all()
            statuses = [JobStatus(status) for _, status in found]
            ended = [job_id for job_id, status in found if JobStatus(status).finished]
            drop_checkpoints(session, ended)
            if JobStatus.QUEUED in statuses:
                announce(session)
            return len(statuses)


def aware(value: datetime) -> datetime:
    """Aggregates bypass the column type: SQLite and PostgreSQL give naive UTC back."""
    return value if value.tzinfo is not None else value.replace(tzinfo=UTC)


def _lease_cleared() -> dict[str, Any]:
    return {"lease_token": None, "lease_owner": None, "lease_expires_at": None}


def _fenced(claim: Claim) -> Any:
    return (
        update(Job)
        .where(
            Job.id == claim.job.id,
            Job.lease_token == claim.token,
            Job.status == JobStatus.RUNNING,
        )
        .execution_options(synchronize_session=False)
    )


def _write_fenced(session: Session, claim: Claim, values: Mapping[str, Any]) -> Job:
    """Apply ``values`` to the claimed job's row, if the claim still holds its lease."""
    row: Job | None = session.scalars(_fenced(claim).values(**values).returning(Job)).one_or_none()
    if row is None:
        raise LeaseLost(claim.job.id)
    return row


def _job(session: Session, job_id: int) -> Job:
    row = session.get(Job, job_id)
    if row is None:
        raise JobNotFound(job_id)
    return row


def _with_results(session: Session, job_id: int, *, kept: bool = False) -> Job:
    """The job, if it has the results asked for: a succeeded job's, or (``kept``) also what a
    cancelled job kept of the episodes it finished."""
    row = _job(session, job_id)
    status = JobStatus(row.status)
    if status is JobStatus.SUCCEEDED or (kept and status is JobStatus.CANCELLED):
        return row
    raise ResultsUnavailable(job_id, status)


def _result_column(session: Session, job_id: int, column: Any, *, kept: bool = False) -> Any:
    """One column of a job's results, loading none of the others (blobs are large)."""
    row = _with_results(session, job_id, kept=kept)
    found = session.execute(select(column).where(JobResult.job_id == job_id)).one_or_none()
    if found is None or (found[0] is None and row.status != JobStatus.SUCCEEDED):
        raise ResultsUnavailable(job_id, JobStatus(row.status))
    return found[0]
