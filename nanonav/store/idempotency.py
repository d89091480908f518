"""Idempotency keys, as Stripe has them: a key names one request for a while.

Within ``ttl_s`` of its first use a key answers with what it made, provided the request is the
same one (the same digest); a different request under the key is refused. After ``ttl_s`` the
key is free again: the old row forgets it in the same transaction that makes the new one.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from typing import TypeVar

from sqlalchemy import select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session, sessionmaker

from nanonav.store.db import unit_of_work
from nanonav.store.errors import IdempotencyKeyReused
from nanonav.store.models import Job, Policy, Study


@dataclass(frozen=True)
class Idempotency:
    """A request's key, the digest of what it asked for, and how long the key holds."""

    key: str
    digest: str
    ttl_s: float


Keyed = TypeVar("Keyed", Job, Study, Policy)
# What the refusal of a reused key calls the row the key made.
_KINDS = {Job: "job", Study: "study", Policy: "policy"}


def earlier(
    session: Session,
    model: type[Keyed],
    idempotency: Idempotency | None,
    now: datetime,
    *,
    owner: str = "",
) -> Keyed | None:
    """The row this key of ``owner`` already made, if it still holds (keys are scoped per
    owner); an expired key is freed here."""
    if idempotency is None:
        return None
    row = session.scalars(
        select(model)
        .where(model.owner == owner, model.idempotency_key == idempotency.key)
        .with_for_update()
    ).one_or_none()
    if row is None:
        return None
    if row.created_at <= now - timedelta(seconds=idempotency.ttl_s):
        session.execute(update(model).where(model.id == row.id).values(idempotency_key=None))
        session.flush()
        return None
    # Rows keyed before digests were kept cannot be compared: they replay.
    if row.request_digest is not None and row.request_digest != idempotency.digest:
        raise IdempotencyKeyReused(idempotency.key, _KINDS[model], row.id)
    return row


def insert_once(
    sessions: sessionmaker[Session],
    model: type[Keyed],
    idempotency: Idempotency | None,
    insert: Callable[[Session, datetime], Keyed],
    *,
    owner: str,
    reads_first: bool,
) -> Keyed:
    """The row ``insert`` makes in one transaction, unless ``owner``'s key still names one: then
    that row. Of two requests racing for one key, the loser finds the winner's row."""
    # Looking up the key (or counting a quota: ``reads_first``) and then inserting reads before
    # it writes: take SQLite's write lock up front.
    write = reads_first or idempotency is not None
    for attempt in range(2):
        try:
            with unit_of_work(sessions, write=write) as session:
                now = datetime.now(UTC)
                existing = earlier(session, model, idempotency, now, owner=owner)
                return existing if existing is not None else insert(session, now)
        except IntegrityError:
            if idempotency is None or attempt == 1:
                raise
    raise AssertionError("unreachable")
