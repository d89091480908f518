"""Waking idle workers the moment a job is queued, on PostgreSQL.

Every transaction that queues a job (a submit, a study, a job given back or recovered) sends
``NOTIFY`` on its schema's channel; PostgreSQL delivers it when the transaction commits, so a
listener never wakes before the job can be claimed. An idle worker waits on a connection of its
own that listens there, and still looks at the queue every poll interval: a notification
lost with a dropped connection costs at most one interval. SQLite has no such thing: there the
wait is a plain sleep.

Channels belong to a database, not to a schema: the name carries a digest of the schema, so
stores that share a database in different schemas do not wake each other's workers.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Any

from sqlalchemy import Engine, text
from sqlalchemy.orm import Session

from nanonav.store.faults import reason

logger = logging.getLogger(__name__)

CHANNEL = "nanonav_jobs"
# The channel's full name, in SQL: under PostgreSQL's 63-character limit whatever the schema.
CHANNEL_NAME = f"'{CHANNEL}_' || md5(current_schema())"
# The longest a listener blocks in one go, so that a stop request is seen promptly.
SLICE_S = 0.5
# After a listening connection failed, wait this long before opening another.
RECONNECT_S = 5.0


def announce(session: Session) -> None:
    """Tell listening workers, when ``session``'s transaction commits, that jobs are queued."""
    if session.get_bind().dialect.name == "postgresql":
        session.execute(text(f"SELECT pg_notify({CHANNEL_NAME}, '')"))


class Wakeups:
    """What an idle worker waits on: a notification that a job was queued, or the time out.

    Each instance owns one connection outside the engine's pool (a listening connection must
    stay in autocommit and never be handed to anyone else). Not thread-safe: one per loop.
    """

    def __init__(self, engine: Engine) -> None:
        self._engine = engine
        self._listening = engine.dialect.name == "postgresql"
        self._connection: Any = None
        self._retry_at = 0.0

    @property
    def listening(self) -> bool:
        """Whether notifications can wake this waiter (PostgreSQL), not only the clock."""
        return self._listening

    def listen(self) -> bool:
        """Open the listening connection now (it is opened on the first wait otherwise);
        False on SQLite or if the server cannot be reached."""
        return self._connect() is not None

    def wait(self, timeout_s: float, stop: threading.Event) -> bool:
        """Block until a job is announced (True), ``timeout_s`` passes or ``stop`` is set
        (False). Notifications that arrived while nobody waited count: they wake at once."""
        deadline = time.monotonic() + timeout_s
        while not stop.is_set():
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            connection = self._connect()
            if connection is None:
                stop.wait(min(left, SLICE_S))
                continue
            try:
                if any(True for _ in connection.notifies(timeout=min(left, SLICE_S), stop_after=1)):
                    for _ in connection.notifies(timeout=0.0):
                        pass  # the rest arrived together: one look at the queue serves them all
                    return True
            except Exception as error:  # a dropped connection: the poll covers until the next
                logger.warning("stopped listening for queued jobs (%s)", reason(error))
                self._drop()
        return False

    def close(self) -> None:
        self._drop()

    def _connect(self) -> Any:
        if not self._listening or self._connection is not None:
            return self._connection
        if time.monotonic() < self._retry_at:
            return None
        import psycopg

        args, kwargs = self._engine.dialect.create_connect_args(self._engine.url)
        try:
            connection = psycopg.connect(
                *args, **{**kwargs, "autocommit": True, "application_name": "nanonav-listener"}
            )
            (channel,) = connection.execute(f"SELECT {CHANNEL_NAME}").fetchall()[0]
            connection.execute(f'LISTEN "{channel}"')
        except psycopg.Error as error:
            logger.warning("cannot listen for queued jobs (%s); polling", reason(error))
            self._retry_at = time.monotonic() + RECONNECT_S
            return None
        self._connection = connection
        return connection

    def _drop(self) -> None:
        connection, self._connection = self._connection, None
        self._retry_at = time.monotonic() + RECONNECT_S
        if connection is not None:
            try:
                connection.close()
            except Exception:  # already broken; nothing more to release
                logger.debug("closing a broken listening connection failed", exc_info=True)
