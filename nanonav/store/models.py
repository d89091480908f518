"""The tables of the job store.

``jobs`` is the queue and the state machine; ``job_results`` holds what a finished run produced
(metrics as JSON, arrays as ``.npz`` blobs, and the few metrics and the binned learning curve a
study reads, apart so that a study never loads the rest) and ``job_plots``
the PNGs drawn the first time each was asked for. ``studies`` groups jobs (a grid of scenarios
x seeds); ``study_plots`` keeps the pictures of finished studies. ``workers`` says which worker
processes were seen lately. ``deliveries`` is the outbox of webhooks: a row per job or study
that named a ``callback_url``, from its submit until the receiver took it or it was given up.
``policies`` holds the Q-tables clients made elsewhere and sent, for scenarios to evaluate.
``revoked_sessions`` names the dashboard sessions a logout ended, until they would have expired.
``job_checkpoints`` keeps the last checkpoint of a job that trains a network, until it ends.
A claim gives a job a lease: ``lease_token`` names the claim, ``lease_expires_at`` says until when
it holds (every progress write renews it) and every later write by the worker is fenced by the
token, so a worker that lost its lease can neither report progress nor store a result.
"""

from __future__ import annotations

import enum
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import (
    JSON,
    BigInteger,
    Boolean,
    DateTime,
    Dialect,
    Enum,
    Float,
    ForeignKey,
    Index,
    Integer,
    LargeBinary,
    MetaData,
    String,
    Text,
    TypeDecorator,
    UniqueConstraint,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column

from nanonav.status import FINISHED

NAMING_CONVENTION = {
    "ix": "ix_%(table_name)s_%(column_0_N_name)s",
    "uq": "uq_%(table_name)s_%(column_0_N_name)s",
    "ck": "ck_%(table_name)s_%(constraint_name)s",
    "fk": "fk_%(table_name)s_%(column_0_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}


class Base(DeclarativeBase):
    metadata = MetaData(naming_convention=NAMING_CONVENTION)


# A row's id, and every column naming one: BIGINT on PostgreSQL, as the routes take ids up to
# MAX_EXACT_INT (migration 0013); on SQLite INTEGER, 64 bits there already and the only type
# whose primary key is the rowid that AUTOINCREMENT counts.
RowId = BigInteger().with_variant(Integer(), "sqlite")


class UTCDateTime(TypeDecorator[datetime]):
    """A timestamp stored as naive UTC and read back timezone-aware, on SQLite and PostgreSQL."""

    impl = DateTime(timezone=False)
    cache_ok = True

    def process_bind_param(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            raise ValueError("timestamps must be timezone-aware")
        return value.astimezone(UTC).replace(tzinfo=None)

    def process_result_value(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        return None if value is None else value.replace(tzinfo=UTC)


class JobStatus(enum.StrEnum):
    """Where a job is in its life; the last three never change again."""

    QUEUED = "queued"  # waiting for a worker
    RUNNING = "running"  # claimed: a worker holds its lease
    SUCCEEDED = "succeeded"  # ran to the end; results and plots are stored
    FAILED = "failed"  # the scenario raised, ran out of time, or its attempts ran out
    CANCELLED = "cancelled"  # a client cancelled it; what finished before is kept

    @property
    def finished(self) -> bool:
        return self.value in FINISHED


ENDED = tuple(JobStatus(status) for status in sorted(FINISHED))
"""The statuses of a job that never change again, as the store's column holds them."""


class Study(Base):
    __tablename__ = "studies"
    # On SQLite, an id is never handed out again after its row is deleted (migration 0006).
    __table_args__ = (UniqueConstraint("owner", "idempotency_key"), {"sqlite_autoincrement": True})

    id: Mapped[int] = mapped_column(RowId, primary_key=True, autoincrement=True)
    name: Mapped[str] = mapped_column(String(200))
    spec: Mapped[dict[str, Any]] = mapped_column(JSON)
    jobs: Mapped[int] = mapped_column(Integer)
    # The SHA-256 of the API key that made it; '' when the API has no keys.
    owner: Mapped[str] = mapped_column(String(64), default="", server_default="")
    idempotency_key: Mapped[str | None] = mapped_column(String(200))
    # sha256 of the request that used the key: the same key with another request is refused.
    request_digest: Mapped[str | None] = mapped_column(String(64))
    created_at: Mapped[datetime] = mapped_column(UTCDateTime())
    cancel_requested: Mapped[bool] = mapped_column(Boolean, default=False)
    # The report of a finished study, kept once computed: its jobs never change again.
    report: Mapped[dict[str, Any] | None] = mapped_column(JSON)


class Job(Base):
    __tablename__ = "jobs"
    __table_args__ = (
        Index(None, "status", "id"),
        Index(None, "status", "lease_expires_at"),
        Index(None, "study_id", "id"),
        Index(None, "owner", "id"),
        Index(None, "quota_key", "status"),
        Index(None, "finished_at"),  # what retention looks for
        UniqueConstraint("owner", "idempotency_key"),
        {"sqlite_autoincrement": True},  # no id is handed out twice (migration 0006)
    )

    id: Mapped[int] = mapped_column(RowId, primary_key=True, autoincrement=True)
    status: Mapped[JobStatus] = mapped_column(
        Enum(
            JobStatus,
            native_enum=False,
            length=16,
            values_callable=lambda members: [m.value for m in members],
            validate_strings=True,
        ),
        default=JobStatus.QUEUED,
    )
    scenario: Mapped[dict[str, Any]] = mapped_column(JSON)
    robot_steps: Mapped[int] = mapped_column(BigInteger)
    # The SHA-256 of the API key that made it ('' when the API has no keys), and whom its
    # quota counts against: the owner, or without keys the client's address.
    owner: Mapped[str] = mapped_column(String(64), default="", server_default="")
    quota_key: Mapped[str] = mapped_column(String(64), default="", server_default="")
    idempotency_key: Mapped[str | None] = mapped_column(String(200))
    # sha256 of the request that used the key: the same key with another request is refused.
    request_digest: Mapped[str | None] = mapped_column(String(64))
    created_at: Mapped[datetime] = mapped_column(UTCDateTime())
    started_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
    finished_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
    episode: Mapped[int] = mapped_column(Integer, default=0)
    episodes: Mapped[int] = mapped_column(Integer)
    fraction: Mapped[float] = mapped_column(Float, default=0.0)
    cancel_requested: Mapped[bool] = mapped_column(Boolean, default=False)
    error: Mapped[str | None] = mapped_column(Text)
    attempts: Mapped[int] = mapped_column(Integer, default=0)
    lease_token: Mapped[str | None] = mapped_column(String(64))
    lease_owner: Mapped[str | None] = mapped_column(String(200))
    lease_expires_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
    study_id: Mapped[int | None] = mapped_column(
        RowId, ForeignKey("studies.id", ondelete="CASCADE")
    )
    study_point: Mapped[int | None] = mapped_column(Integer)  # index of its grid point
    study_seed: Mapped[int | None] = mapped_column(BigInteger)
    # It trains a network (robots.policy ppo, recurrent_ppo): only a worker that trains
    # claims it. While it trains, the decisions done; once resumed from a checkpoint, the
    # decisions it took up from; once it succeeded, the policy its network was kept as. Its
    # training curve so far (rows as the metrics' training_curve), for its page to draw live.
    trains: Mapped[bool] = mapped_column(Boolean, default=False, server_default="0")
    decisions: Mapped[int | None] = mapped_column(BigInteger)
    training_curve: Mapped[list[dict[str, Any]] | None] = mapped_column(JSON)
    resumed_from_decisions: Mapped[int | None] = mapped_column(BigInteger)
    trained_policy_id: Mapped[int | None] = mapped_column(RowId)


class JobCheckpoint(Base):
    """The last checkpoint of a job's training (the trainer's state at ``decisions``, and its
    curve so far), from which a job whose worker died resumes; gone when the job ends."""

    __tablename__ = "job_checkpoints"

    job_id: Mapped[int] = mapped_column(
        RowId, ForeignKey("jobs.id", ondelete="CASCADE"), primary_key=True
    )
    decisions: Mapped[int] = mapped_column(BigInteger)
    data: Mapped[bytes] = mapped_column(LargeBinary)
    curve: Mapped[list[dict[str, Any]]] = mapped_column(JSON)
    written_at: Mapped[datetime] = mapped_column(UTCDateTime())


class JobResult(Base):
    __tablename__ = "job_results"

    job_id: Mapped[int] = mapped_column(
        RowId, ForeignKey("jobs.id", ondelete="CASCADE"), primary_key=True
    )
    completed: Mapped[bool] = mapped_column(Boolean)
    metrics: Mapped[dict[str, Any]] = mapped_column(JSON)
    trajectory: Mapped[bytes | None] = mapped_column(LargeBinary)
    qtable: Mapped[bytes | None] = mapped_column(LargeBinary)
    study_metrics: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    curve: Mapped[dict[str, Any] | None] = mapped_column(JSON)


class JobPlot(Base):
    __tablename__ = "job_plots"

    job_id: Mapped[int] = mapped_column(
        RowId, ForeignKey("jobs.id", ondelete="CASCADE"), primary_key=True
    )
    name: Mapped[str] = mapped_column(String(32), primary_key=True)
    png: Mapped[bytes] = mapped_column(LargeBinary)


class StudyPlot(Base):
    __tablename__ = "study_plots"

    study_id: Mapped[int] = mapped_column(
        RowId, ForeignKey("studies.id", ondelete="CASCADE"), primary_key=True
    )
    name: Mapped[str] = mapped_column(String(64), primary_key=True)
    png: Mapped[bytes] = mapped_column(LargeBinary)


class Worker(Base):
    """A worker process, as it last reported itself."""

    __tablename__ = "workers"

    name: Mapped[str] = mapped_column(String(200), primary_key=True)
    started_at: Mapped[datetime] = mapped_column(UTCDateTime())
    seen_at: Mapped[datetime] = mapped_column(UTCDateTime(), index=True)
    # when it was ready to take jobs; null while it prepares the engine (compiles it, at first)
    ready_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
    # when its webhook sender last made progress (a pass, or a try within one); null without one
    webhooks_passed_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
    # it claims jobs that train a network (``nanonav worker --train``)
    trains: Mapped[bool] = mapped_column(Boolean, default=False, server_default="0")


class DeliveryState(enum.StrEnum):
    """Where a webhook is; the last two never change again."""

    WAITING = "waiting"  # its job or study has not ended
    DUE = "due"  # it ended: the summary is fixed, and sent at next_attempt_at
    DELIVERED = "delivered"  # the receiver answered 2xx
    FAILED = "failed"  # every attempt failed, or it could not be sent at all


class Delivery(Base):
    """A webhook to send when a job or a study ends; leased like a job while it is sent."""

    __tablename__ = "deliveries"
    __table_args__ = (Index(None, "state", "next_attempt_at"),)

    id: Mapped[int] = mapped_column(RowId, primary_key=True, autoincrement=True)
    job_id: Mapped[int | None] = mapped_column(
        RowId, ForeignKey("jobs.id", ondelete="SET NULL"), unique=True
    )
    study_id: Mapped[int | None] = mapped_column(
        RowId, ForeignKey("studies.id", ondelete="SET NULL"), unique=True
    )
    url: Mapped[str] = mapped_column(String(2048))
    state: Mapped[DeliveryState] = mapped_column(
        Enum(
            DeliveryState,
            native_enum=False,
            length=16,
            values_callable=lambda members: [m.value for m in members],
            validate_strings=True,
        ),
        default=DeliveryState.WAITING,
    )
    event: Mapped[str | None] = mapped_column(String(32))
    payload: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime())
    attempts: Mapped[int] = mapped_column(Integer, default=0)
    next_attempt_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
    last_attempt_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
    delivered_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
    last_status: Mapped[int | None] = mapped_column(Integer)  # the receiver's HTTP status
    last_error: Mapped[str | None] = mapped_column(String(500))
    lease_token: Mapped[str | None] = mapped_column(String(64))
    lease_expires_at: Mapped[datetime | None] = mapped_column(UTCDateTime())


class Policy(Base):
    """A Q-table or a network (an ONNX model) made elsewhere and sent, for scenarios to
    evaluate (``policy_from``)."""

    __tablename__ = "policies"
    __table_args__ = (
        Index(None, "owner", "id"),
        # a unique index, not a constraint: SQLite adds it without rebuilding the table (which
        # would lose AUTOINCREMENT's high-water mark of deleted ids)
        Index(None, "owner", "idempotency_key", unique=True),
        {"sqlite_autoincrement": True},
    )

    id: Mapped[int] = mapped_column(RowId, primary_key=True, autoincrement=True)
    name: Mapped[str | None] = mapped_column(String(200))
    # The SHA-256 of the API key that sent it; '' when the API has no keys.
    owner: Mapped[str] = mapped_column(String(64), default="", server_default="")
    idempotency_key: Mapped[str | None] = mapped_column(String(200))
    # sha256 of the request that used the key: the same key with another request is refused.
    request_digest: Mapped[str | None] = mapped_column(String(64))
    created_at: Mapped[datetime] = mapped_column(UTCDateTime())
    # 'table' (a Q-table) or 'network' (an ONNX model)
    kind: Mapped[str] = mapped_column(String(16), default="table", server_default="table")
    action_set: Mapped[str] = mapped_column(String(16))
    # The communication models whose state layout its rows are (several share one).
    communication: Mapped[list[str]] = mapped_column(JSON)
    states: Mapped[int] = mapped_column(Integer)  # a network's: its observation's columns
    actions: Mapped[int] = mapped_column(Integer)
    tables: Mapped[int] = mapped_column(Integer)
    per_robot: Mapped[bool] = mapped_column(Boolean)
    # ``.npz``: a table's arrays ``states`` and ``actions`` (labels) and ``values``; a
    # network's ``observation`` and ``actions`` (labels) and ``model`` (the ONNX bytes).
    table: Mapped[bytes] = mapped_column(LargeBinary)


class RevokedSession(Base):
    """A dashboard session a logout ended: its token is refused though it has not expired."""

    __tablename__ = "revoked_sessions"

    id: Mapped[str] = mapped_column(String(32), primary_key=True)  # the token's session id
    # when its token expires; the row may go some time after (``store.revocations``)
    expires_at: Mapped[datetime] = mapped_column(UTCDateTime(), index=True)
