"""Idempotency keys, as Stripe has them: a key names one request for a while.

Within ``ttl_s`` of its first use a key answers with what it made, provided the request is the
same one (the same digest); a different request under the key is refused. After ``ttl_s`` the
key is free again: the old row forgets it in the same transaction that makes the new one.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import TypeVar

from sqlalchemy import select, update
from sqlalchemy.orm import Session

from nanonav.store.errors import IdempotencyKeyReused
from nanonav.store.models import Job, Study


@dataclass(frozen=True)
class Idempotency:
    """A request's key, the digest of what it asked for, and how long the key holds."""

    key: str
    digest: str
    ttl_s: float


Keyed = TypeVar("Keyed", Job, Study)


def earlier(
    session: Session, model: type[Keyed], idempotency: Idempotency | None, now: datetime
) -> Keyed | None:
    """The row this key already made, if it still holds; an expired key is freed here."""
    if idempotency is None:
        return None
    row = session.scalars(
        select(model).where(model.idempotency_key == idempotency.key).with_for_update()
    ).one_or_none()
    if row is None:
        return None
    if row.created_at <= now - timedelta(seconds=idempotency.ttl_s):
        session.execute(update(model).where(model.id == row.id).values(idempotency_key=None))
        session.flush()
        return None
    # Rows keyed before digests were kept cannot be compared: they replay.
    if row.request_digest is not None and row.request_digest != idempotency.digest:
        kind = "job" if model is Job else "study"
        raise IdempotencyKeyReused(idempotency.key, kind, row.id)
    return row
