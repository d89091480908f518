"""Sessions a logout ended: kept until their tokens would have expired, and then forgotten, on
SQLite and PostgreSQL."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

from sqlalchemy import func, select

from nanonav.store import JobStore
from nanonav.store.models import RevokedSession
from nanonav.store.revocations import KEPT_PAST_EXPIRY, RevocationStore

T0 = datetime(2030, 1, 1, tzinfo=UTC)
HOUR = timedelta(hours=1)


def session_id(n: int) -> str:
    """A session id as tokens carry them: 32 hex digits."""
    return f"{n:032x}"


def kept(store: JobStore) -> dict[str, datetime]:
    """Each revoked session's id and expiry, as stored."""
    with store.engine.connect() as connection:
        rows = connection.execute(select(RevokedSession.id, RevokedSession.expires_at))
        return {row.id: row.expires_at for row in rows}


def test_a_revoked_session_is_refused_and_no_other(store: JobStore) -> None:
    revocations = RevocationStore(store.engine)
    assert not revocations.revoked(session_id(1))
    revocations.revoke(session_id(1), expires_at=T0 + 8 * HOUR, now=T0)
    assert revocations.revoked(session_id(1))
    assert not revocations.revoked(session_id(2))
    assert kept(store) == {session_id(1): T0 + 8 * HOUR}


def test_revoking_a_session_twice_keeps_one_row(store: JobStore) -> None:
    first, second = RevocationStore(store.engine), RevocationStore(store.engine)
    first.revoke(session_id(1), expires_at=T0 + 8 * HOUR, now=T0)
    second.revoke(session_id(1), expires_at=T0 + 8 * HOUR, now=T0 + timedelta(seconds=5))
    assert first.revoked(session_id(1)) and second.revoked(session_id(1))
    with store.engine.connect() as connection:
        assert connection.scalar(select(func.count()).select_from(RevokedSession)) == 1


def test_a_revocation_is_forgotten_only_once_its_expiry_is_long_past(store: JobStore) -> None:
    revocations = RevocationStore(store.engine)
    revocations.revoke(session_id(1), expires_at=T0 + HOUR, now=T0)
    revocations.revoke(session_id(2), expires_at=T0 + 8 * HOUR, now=T0)
    # past the first's expiry, but within the margin kept for clocks that run behind
    revocations.revoke(session_id(3), expires_at=T0 + 9 * HOUR, now=T0 + 2 * HOUR)
    assert set(kept(store)) == {session_id(1), session_id(2), session_id(3)}
    later = T0 + HOUR + KEPT_PAST_EXPIRY + timedelta(seconds=1)
    revocations.revoke(session_id(4), expires_at=later + 8 * HOUR, now=later)
    assert set(kept(store)) == {session_id(2), session_id(3), session_id(4)}
    assert not revocations.revoked(session_id(1))
    assert revocations.revoked(session_id(2))
