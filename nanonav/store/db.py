"""Engines and sessions for SQLite and PostgreSQL.

SQLite runs in WAL mode (readers never wait for the writer) with a busy timeout and foreign keys
on. SQLAlchemy, not the ``sqlite3`` module, emits BEGIN: an ordinary unit of work starts with a
deferred BEGIN, and one that asked for :data:`WRITE_LOCK` starts with ``BEGIN IMMEDIATE``, which
takes the write lock up front so a read-then-write transaction (the claim) can never fail to
upgrade its lock half-way.
"""

from __future__ import annotations

import zlib
from collections.abc import Iterator
from contextlib import contextmanager
from functools import partial
from pathlib import Path
from typing import Any

from sqlalchemy import Engine, create_engine, event, inspect, text
from sqlalchemy.engine import Connection, ExceptionContext, make_url
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session, sessionmaker
from sqlalchemy.pool import ConnectionPoolEntry

BUSY_TIMEOUT_S = 30.0
WRITE_LOCK = "nanonav_write_lock"
# Errors after which a connection is thrown away rather than reused: one opened while the
# database was read-only stays read-only after the database is writable again.
STALE_CONNECTION_WORDS = ("readonly database", "read-only transaction")


def make_engine(url: str, *, busy_timeout_s: float = BUSY_TIMEOUT_S, **kwargs: Any) -> Engine:
    """An engine for ``url``; for a SQLite file, its directory is created if missing. A write
    waits up to ``busy_timeout_s`` for another's lock before it fails (transiently): SQLite's
    busy timeout, PostgreSQL's ``lock_timeout``."""
    parsed = make_url(url)
    if parsed.get_backend_name() != "sqlite":
        engine = create_engine(parsed, pool_pre_ping=True, **kwargs)
        event.listen(engine, "connect", partial(_postgresql_on_connect, busy_timeout_s))
        event.listen(engine, "handle_error", _recycle_stale)
        return engine
    if parsed.database and parsed.database != ":memory:":
        Path(parsed.database).parent.mkdir(parents=True, exist_ok=True)
    engine = create_engine(
        parsed,
        connect_args={"timeout": busy_timeout_s, "check_same_thread": False},
        **kwargs,
    )
    event.listen(engine, "connect", partial(_sqlite_on_connect, busy_timeout_s))
    event.listen(engine, "begin", _sqlite_on_begin)
    event.listen(engine, "handle_error", _recycle_stale)
    return engine


def _recycle_stale(context: ExceptionContext) -> None:
    """Have the pool discard a connection whose error it would otherwise keep repeating."""
    message = str(context.original_exception).lower()
    if any(words in message for words in STALE_CONNECTION_WORDS):
        context.is_disconnect = True


def _postgresql_on_connect(
    lock_timeout_s: float, dbapi_connection: Any, record: ConnectionPoolEntry
) -> None:
    cursor = dbapi_connection.cursor()
    try:
        cursor.execute(f"SET lock_timeout = {max(1, round(lock_timeout_s * 1000))}")
    finally:
        cursor.close()
    dbapi_connection.commit()


def _sqlite_on_connect(
    busy_timeout_s: float, dbapi_connection: Any, record: ConnectionPoolEntry
) -> None:
    dbapi_connection.isolation_level = None
    cursor = dbapi_connection.cursor()
    try:
        cursor.execute("PRAGMA journal_mode=WAL")
        cursor.execute(f"PRAGMA busy_timeout={round(busy_timeout_s * 1000)}")
        cursor.execute("PRAGMA foreign_keys=ON")
        cursor.execute("PRAGMA synchronous=NORMAL")
    finally:
        cursor.close()


def _sqlite_on_begin(connection: Connection) -> None:
    if connection.get_execution_options().get(WRITE_LOCK):
        connection.exec_driver_sql("BEGIN IMMEDIATE")
    else:
        connection.exec_driver_sql("BEGIN")


def make_sessionmaker(engine: Engine) -> sessionmaker[Session]:
    """Sessions that keep loaded rows readable after commit (rows map to frozen records)."""
    return sessionmaker(engine, expire_on_commit=False)


def add_once(sessions: sessionmaker[Session], row: Any) -> None:
    """Insert ``row`` unless a row with its primary key exists (another process may have kept
    the same thing first, e.g. a picture drawn twice from one result: the first one stays)."""
    try:
        with unit_of_work(sessions) as session:
            session.add(row)
    except IntegrityError:
        key = tuple(getattr(row, column.key) for column in inspect(type(row)).primary_key)
        with unit_of_work(sessions) as session:
            if session.get(type(row), key) is None:
                raise


@contextmanager
def unit_of_work(sessions: sessionmaker[Session], *, write: bool = False) -> Iterator[Session]:
    """One transaction: committed if the block returns, rolled back if it raises.

    ``write=True`` takes SQLite's write lock at BEGIN (PostgreSQL ignores the option): use it for
    every transaction that reads rows and then changes them.
    """
    with sessions() as session, session.begin():
        if write:
            session.connection(execution_options={WRITE_LOCK: True})
        yield session


def serialise(session: Session, name: str) -> None:
    """Hold, until ``session``'s transaction ends, a lock that every transaction serialising on
    ``name`` takes: a count and the insert it permits then cannot interleave with another's. On
    SQLite the transaction's write lock (``unit_of_work(write=True)``) already does; on
    PostgreSQL, a transaction-scoped advisory lock on ``name``'s hash."""
    if session.get_bind().dialect.name == "postgresql":
        lock = zlib.crc32(name.encode()) - 2**31
        session.execute(text("SELECT pg_advisory_xact_lock(:lock)"), {"lock": lock})
