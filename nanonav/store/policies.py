"""Every query about policies: Q-tables and networks (ONNX models) made elsewhere and sent, that
scenarios evaluate.

A scenario names one as ``policy_from: "policy-<id>"``, as it names a job's learned table by the
job's id. Each public method of :class:`PolicyStore` is one transaction. The store keeps what it
is given: the labels and values were checked by whoever sent them (``nanonav.policy``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from datetime import datetime
from functools import partial
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import Engine, delete, func, select, update
from sqlalchemy.orm import Session, defer

from nanonav.store.arrays import pack, unpack
from nanonav.store.db import make_sessionmaker, serialise, unit_of_work
from nanonav.store.errors import PolicyInUse, PolicyLimitReached, StoreError
from nanonav.store.idempotency import Idempotency, insert_once
from nanonav.store.models import Job, JobStatus, Policy

# What a scenario's policy_from names: a job's id, or a policy's name, POLICY_PREFIX + its id.
PolicySource = int | str
POLICY_PREFIX = "policy-"
# A record is read without the table, which may be large: only ``table()`` reads it.
WITHOUT_TABLE = defer(Policy.table)
# The jobs a refused delete names (it counts them all).
SHOWN_JOBS = 5
TABLE = "table"
NETWORK = "network"


def policy_name(policy_id: int) -> str:
    """What a scenario's ``policy_from`` names the policy by."""
    return f"{POLICY_PREFIX}{policy_id}"


def policy_number(name: str) -> int:
    """The id of the policy ``name`` (``policy-<id>``) names; ValueError for another string."""
    digits = name.removeprefix(POLICY_PREFIX)
    if digits == name or not (digits.isascii() and digits.isdigit()) or digits[0] == "0":
        raise ValueError(f"{name!r} is not a policy's name, {POLICY_PREFIX}<id>")
    return int(digits)


class PolicyNotFound(StoreError):
    def __init__(self, policy_id: int) -> None:
        super().__init__(f"there is no policy {policy_id}")
        self.policy_id = policy_id


@dataclass(frozen=True)
class PolicyRecord:
    """A policy as its row says, without its table or model."""

    id: int
    name: str | None
    owner: str
    created_at: datetime
    action_set: str
    communication: tuple[str, ...]
    states: int  # a network's: the columns of its observation
    actions: int
    tables: int  # 1 for a table every robot starts from, else one per robot; 1 for a network
    per_robot: bool
    kind: str = TABLE  # TABLE or NETWORK

    @property
    def policy_from(self) -> str:
        return policy_name(self.id)

    @classmethod
    def of(cls, row: Policy) -> PolicyRecord:
        return cls(
            id=row.id,
            name=row.name,
            owner=row.owner,
            created_at=row.created_at,
            action_set=row.action_set,
            communication=tuple(row.communication),
            states=row.states,
            actions=row.actions,
            tables=row.tables,
            per_robot=row.per_robot,
            kind=row.kind,
        )


@dataclass(frozen=True)
class PolicyPage:
    policies: list[PolicyRecord]
    next_before_id: int | None


@dataclass(frozen=True)
class Network:
    """A network to keep as a policy: an ONNX ``model`` checked already, that decides among
    ``actions`` from the ``observation`` columns it names (a recurrent one with ``memory``
    inputs), and what its check counted of its ``cost`` (``nanonav.rl.graph.Cost``)."""

    action_set: str
    communication: tuple[str, ...]
    observation: list[str]
    actions: list[str]
    model: bytes
    memory: int = 0
    cost: dict[str, int] = field(default_factory=dict)
    name: str | None = None

    def row(self, **columns: Any) -> Policy:
        """Its row, with the other ``columns`` given (owner, keys, created_at)."""
        arrays = {
            "observation": np.array(self.observation, dtype=np.str_),
            "actions": np.array(self.actions, dtype=np.str_),
            "model": np.frombuffer(self.model, dtype=np.uint8),
            "memory": np.array(self.memory),
        }
        arrays.update({f"cost_{key}": np.array(value) for key, value in self.cost.items()})
        return Policy(
            name=self.name,
            kind=NETWORK,
            action_set=self.action_set,
            communication=list(self.communication),
            states=len(self.observation),
            actions=len(self.actions),
            tables=1,
            per_robot=False,
            table=pack(arrays),
            **columns,
        )


class PolicyStore:
    """The policies on one database."""

    def __init__(self, engine: Engine) -> None:
        self._sessions = make_sessionmaker(engine)

    def add(
        self,
        *,
        action_set: str,
        communication: tuple[str, ...],
        states: list[str],
        actions: list[str],
        values: NDArray[np.float64],
        name: str | None = None,
        owner: str = "",
        idempotency: Idempotency | None = None,
        limit: int = 0,
    ) -> PolicyRecord:
        """Keep a table ``values`` of ``states`` x ``actions``, or one such table per robot;
        ``owner``'s key still naming an earlier request answers that request's policy instead
        (``IdempotencyKeyReused`` for another request under it). PolicyLimitReached when
        ``owner`` already keeps ``limit`` policies (0: no limit)."""
        if values.ndim not in (2, 3) or values.shape[-2:] != (len(states), len(actions)):
            raise ValueError(f"a table of shape {values.shape} is not states x actions")
        table = pack(
            {
                "states": np.array(states, dtype=np.str_),
                "actions": np.array(actions, dtype=np.str_),
                "values": np.asarray(values, dtype=np.float64),
            }
        )
        row = partial(
            Policy,
            name=name,
            owner=owner,
            kind=TABLE,
            action_set=action_set,
            communication=list(communication),
            states=len(states),
            actions=len(actions),
            tables=1 if values.ndim == 2 else int(values.shape[0]),
            per_robot=values.ndim == 3,
            table=table,
        )
        return self._insert(row, owner, idempotency, limit)

    def add_network(
        self,
        *,
        action_set: str,
        communication: tuple[str, ...],
        observation: list[str],
        actions: list[str],
        model: bytes,
        memory: int = 0,
        cost: dict[str, int] | None = None,
        name: str | None = None,
        owner: str = "",
        idempotency: Idempotency | None = None,
        limit: int = 0,
    ) -> PolicyRecord:
        """Keep a network, an ONNX ``model`` checked already, that decides among ``actions``
        from the ``observation`` columns it names (a recurrent one with ``memory`` inputs), and
        what its check counted of its ``cost`` (``nanonav.rl.graph.Cost``, as a dict); keys and
        limits as ``add``."""
        network = Network(action_set, tuple(communication), list(observation), list(actions),
                          model, memory, cost or {}, name)  # fmt: skip
        return self._insert(partial(network.row, owner=owner), owner, idempotency, limit)

    def _insert(
        self,
        make: Callable[..., Policy],
        owner: str,
        idempotency: Idempotency | None,
        limit: int,
    ) -> PolicyRecord:
        """Insert the row ``make`` makes once under ``owner``'s key, within ``owner``'s
        limit."""

        def insert(session: Session, now: datetime) -> Policy:
            _check_limit(session, owner, limit)
            row = make(
                idempotency_key=None if idempotency is None else idempotency.key,
                request_digest=None if idempotency is None else idempotency.digest,
                created_at=now,
            )
            session.add(row)
            session.flush()
            return row

        kept = insert_once(
            self._sessions, Policy, idempotency, insert, owner=owner, reads_first=limit > 0
        )
        return PolicyRecord.of(kept)

    def get(self, policy_id: int) -> PolicyRecord:
        with unit_of_work(self._sessions) as session:
            return PolicyRecord.of(_policy(session, policy_id))

    def owner_of(self, policy_id: int) -> str | None:
        """The owner of the policy (its key's digest, '' for none), or None if there is none."""
        with unit_of_work(self._sessions) as session:
            owner: str | None = session.scalar(select(Policy.owner).where(Policy.id == policy_id))
            return owner

    def table(self, policy_id: int) -> dict[str, NDArray[Any]]:
        """A table's ``states`` and ``actions`` labels and its ``values``, as a job's Q-table
        is read (without visits: it was not learned here); a network's ``observation`` and
        ``actions`` labels, its ``model`` (the ONNX bytes, as uint8), the count of its
        ``memory`` inputs and its counted cost (``cost_multiply_adds``, ``cost_live_bytes``,
        ..., where its check counted one)."""
        with unit_of_work(self._sessions) as session:
            blob = session.scalar(select(Policy.table).where(Policy.id == policy_id))
        if blob is None:
            raise PolicyNotFound(policy_id)
        return unpack(blob)

    def page(self, *, limit: int, before_id: int | None, owner: str | None = None) -> PolicyPage:
        """Up to ``limit`` policies, newest first, older than ``before_id`` when given; only
        ``owner``'s when given."""
        query = select(Policy).options(WITHOUT_TABLE).order_by(Policy.id.desc()).limit(limit + 1)
        if owner is not None:
            query = query.where(Policy.owner == owner)
        if before_id is not None:
            query = query.where(Policy.id < before_id)
        with unit_of_work(self._sessions) as session:
            rows = [PolicyRecord.of(row) for row in session.scalars(query)]
        more = len(rows) > limit
        rows = rows[:limit]
        return PolicyPage(policies=rows, next_before_id=rows[-1].id if more else None)

    def delete(self, policy_id: int) -> None:
        """Forget the policy; PolicyInUse while queued or running jobs evaluate it (a job
        queued while it is deleted fails, saying so, when a worker claims it). A job that
        trained it names no trained policy any more."""
        with unit_of_work(self._sessions, write=True) as session:
            # Locked before the jobs are counted: a transaction queueing a job for this policy
            # (``hold_policies``) either commits first, and its job is counted, or waits and then
            # finds the policy gone.
            found = select(Policy.id).where(Policy.id == policy_id).with_for_update()
            if session.scalar(found) is None:
                raise PolicyNotFound(policy_id)
            users = (
                select(Job.id)
                .where(
                    Job.status.in_([JobStatus.QUEUED, JobStatus.RUNNING]),
                    Job.scenario["policy_from"].as_string() == policy_name(policy_id),
                )
                .order_by(Job.id)
            )
            job_ids = list(session.scalars(users))
            if job_ids:
                raise PolicyInUse(policy_id, job_ids[:SHOWN_JOBS], len(job_ids))
            session.execute(delete(Policy).where(Policy.id == policy_id))
            # a job that trained it no longer names it (a rare write: no index on the column)
            session.execute(
                update(Job)
                .where(Job.trained_policy_id == policy_id)
                .values(trained_policy_id=None)
                .execution_options(synchronize_session=False)
            )


def evaluated_policies(sources: Iterable[object]) -> list[int]:
    """The ids of the policies among jobs' ``policy_from`` values (a job's id is no policy)."""
    names = {s for s in sources if isinstance(s, str) and s.startswith(POLICY_PREFIX)}
    return sorted(policy_number(name) for name in names)


def hold_policies(session: Session, policy_ids: list[int]) -> None:
    """Keep, until ``session``'s transaction ends, the policies that the jobs it queues
    evaluate; PolicyNotFound for one that is gone. A delete then waits for those jobs and
    counts them. On PostgreSQL, a shared row lock that the delete's exclusive one waits for; on
    SQLite, the transaction's write lock (``unit_of_work(write=True)``) keeps every other
    writer out."""
    if not policy_ids:
        return
    held = select(Policy.id).where(Policy.id.in_(policy_ids)).with_for_update(read=True)
    found = set(session.scalars(held))
    for policy_id in policy_ids:
        if policy_id not in found:
            raise PolicyNotFound(policy_id)


def _check_limit(session: Session, owner: str, limit: int) -> None:
    """Refuse a policy past ``limit`` of ``owner``'s, counted after a lock that serialises
    adds of one owner."""
    if not limit:
        return
    serialise(session, f"policies:{owner}")
    kept = session.scalar(select(func.count()).where(Policy.owner == owner))
    if int(kept or 0) >= limit:
        raise PolicyLimitReached(limit)


def _policy(session: Session, policy_id: int) -> Policy:
    row = session.get(Policy, policy_id, options=[WITHOUT_TABLE])
    if row is None:
        raise PolicyNotFound(policy_id)
    return row
