from __future__ import annotations

from sqlalchemy import inspect

from nanonav.store.db import make_engine
from nanonav.store.migrate import at_head, check, downgrade, upgrade


def tables(url: str) -> set[str]:
    engine = make_engine(url)
    try:
        return set(inspect(engine).get_table_names()) - {"alembic_version"}
    finally:
        engine.dispose()


def test_migrations_and_models_agree_both_ways(database_url: str) -> None:
    upgrade(database_url)
    check(database_url)
    assert tables(database_url) == {
        "jobs",
        "job_results",
        "job_plots",
        "studies",
        "study_plots",
        "workers",
        "deliveries",
        "policies",
        "revoked_sessions",
    }
    downgrade(database_url, "base")
    assert tables(database_url) == set()
    upgrade(database_url)
    check(database_url)
    engine = make_engine(database_url)
    try:
        assert at_head(engine)
    finally:
        engine.dispose()


def test_an_unmigrated_database_is_not_at_head(sqlite_url: str) -> None:
    engine = make_engine(sqlite_url)
    try:
        assert not at_head(engine)
    finally:
        engine.dispose()
