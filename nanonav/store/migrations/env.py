"""Alembic's entry point: migrate the database the settings (or the caller) name."""

from __future__ import annotations

from logging.config import fileConfig
from typing import Any

from alembic import context
from sqlalchemy import Connection

from nanonav.settings import Settings
from nanonav.store.db import make_engine
from nanonav.store.models import Base

config = context.config
given: str | None = config.attributes.get("database_url")
if given is None and config.config_file_name is not None:
    fileConfig(config.config_file_name, disable_existing_loggers=False)
database_url: str = given if given is not None else Settings().database_url


def run_migrations_offline() -> None:
    context.configure(
        url=database_url,
        target_metadata=Base.metadata,
        literal_binds=True,
        render_as_batch=True,
    )
    with context.begin_transaction():
        context.run_migrations()


def _driver(connection: Connection) -> Any:
    """The DB-API connection under ``connection`` (sqlite3's), to speak to it directly."""
    driver = connection.connection.driver_connection
    assert driver is not None
    return driver


def run_migrations_online() -> None:
    engine = make_engine(database_url)
    try:
        with engine.connect() as connection:
            sqlite = connection.dialect.name == "sqlite"
            if sqlite:
                # Batch mode rebuilds a table by copy and DROP; with foreign keys on, that DROP
                # would cascade into the rows that point at it. The pragma only works outside a
                # transaction, so it goes straight to the driver before BEGIN.
                _driver(connection).execute("PRAGMA foreign_keys=OFF")
            context.configure(
                connection=connection,
                target_metadata=Base.metadata,
                render_as_batch=connection.dialect.name == "sqlite",
                # SQLite can roll DDL back too, since the store's engine emits BEGIN itself.
                transactional_ddl=True,
                compare_type=True,
            )
            with context.begin_transaction():
                context.run_migrations()
            if sqlite:
                _driver(connection).execute("PRAGMA foreign_keys=ON")
    finally:
        engine.dispose()


if context.is_offline_mode():
    run_migrations_offline()
else:
    run_migrations_online()
