"""Every query about dashboard sessions ended before their expiry (a logout).

A session token names a random session id (``service.sessions``); a logout keeps that id here
until the token would have expired anyway, and every API process refuses a token whose id is
kept. A row outlives its expiry by :data:`KEPT_PAST_EXPIRY`, so that a process whose clock runs
behind the one that purged it still refuses the token; each logout purges the rows past that.
"""

from __future__ import annotations

from datetime import datetime, timedelta

from sqlalchemy import Engine, delete, select
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.orm import Session

from nanonav.store.db import make_sessionmaker, unit_of_work
from nanonav.store.models import RevokedSession

KEPT_PAST_EXPIRY = timedelta(hours=1)


class RevocationStore:
    """The sessions ended by a logout, on the job store's database. Each method is one
    transaction."""

    def __init__(self, engine: Engine) -> None:
        self._sessions = make_sessionmaker(engine)

    def revoke(self, session_id: str, *, expires_at: datetime, now: datetime) -> None:
        """Refuse ``session_id`` from now on, in every process, and forget the sessions whose
        expiry passed :data:`KEPT_PAST_EXPIRY` before ``now``. Revoking one twice (two tabs,
        two processes) keeps one row."""
        with unit_of_work(self._sessions, write=True) as session:
            session.execute(
                delete(RevokedSession).where(RevokedSession.expires_at < now - KEPT_PAST_EXPIRY)
            )
            session.execute(
                _insert(session)
                .values(id=session_id, expires_at=expires_at)
                .on_conflict_do_nothing(index_elements=[RevokedSession.id])
            )

    def revoked(self, session_id: str) -> bool:
        """Whether a logout ended ``session_id``."""
        with unit_of_work(self._sessions) as session:
            found = session.scalar(select(RevokedSession.id).where(RevokedSession.id == session_id))
            return found is not None


def _insert(session: Session) -> postgresql.Insert | sqlite.Insert:
    """An INSERT that can leave alone a row already there, in the database's own dialect."""
    if session.get_bind().dialect.name == "postgresql":
        return postgresql.insert(RevokedSession)
    return sqlite.insert(RevokedSession)
