"""Ids run to MAX_EXACT_INT, the largest a route takes, on PostgreSQL as on SQLite: rows whose
ids are past 2^31 - 1 are handed out, stored, found and paged, and such an id that names no row
is simply not found."""

from __future__ import annotations

import numpy as np
import pytest
from sqlalchemy import text
from sqlalchemy.engine import make_url

from nanonav.engine import qlearning
from nanonav.scenario import MAX_EXACT_INT
from nanonav.store import (
    JobNotFound,
    JobStore,
    PolicyNotFound,
    StudyJob,
    StudyNotFound,
    StudyStore,
)
from nanonav.store.deliveries import DeliveryStore
from nanonav.store.models import Base
from tests.store.test_deliveries import URL
from tests.store.test_queue import LEASE_S, claim, outcome

PAST_32_BITS = 2**31


def id_columns() -> list[tuple[str, str]]:
    """Every column of the models that holds a row's id: an integer primary key or a foreign
    key."""
    return sorted(
        (table.name, column.name)
        for table in Base.metadata.sorted_tables
        for column in table.columns
        if column.foreign_keys or (column.primary_key and column.type.python_type is int)
    )


def next_id_after(store: JobStore, table: str, last: int) -> None:
    """Make ``table``'s next row take ``last + 1`` as its id (on SQLite, a table that counts
    with AUTOINCREMENT)."""
    with store.engine.begin() as connection:
        if connection.dialect.name == "sqlite":
            named = {"table": table, "last": last}
            connection.execute(text("DELETE FROM sqlite_sequence WHERE name = :table"), named)
            connection.execute(text("INSERT INTO sqlite_sequence VALUES (:table, :last)"), named)
        else:
            setval = "SELECT setval(pg_get_serial_sequence(:table, 'id'), :last)"
            connection.execute(text(setval), {"table": table, "last": last})


def test_every_id_column_is_bigint_on_postgresql_and_the_rowid_on_sqlite() -> None:
    assert id_columns() == [
        ("deliveries", "id"), ("deliveries", "job_id"), ("deliveries", "study_id"),
        ("job_checkpoints", "job_id"), ("job_plots", "job_id"), ("job_results", "job_id"),
        ("jobs", "id"), ("jobs", "study_id"),
        ("policies", "id"), ("studies", "id"), ("study_plots", "study_id"),
    ]  # fmt: skip
    postgresql, sqlite = (make_url(url).get_dialect()() for url in ("postgresql://", "sqlite://"))
    for table, name in id_columns():
        column = Base.metadata.tables[table].columns[name]
        assert column.type.compile(dialect=postgresql) == "BIGINT", (table, name)
        assert column.type.compile(dialect=sqlite) == "INTEGER", (table, name)


def test_rows_past_32_bits_are_handed_out_stored_and_found(store: JobStore) -> None:
    for table in ("studies", "jobs", "policies"):
        next_id_after(store, table, PAST_32_BITS - 1)
    # SQLite gives a delivery the largest rowid plus one; PostgreSQL takes it from a sequence
    wide_deliveries = store.engine.dialect.name == "postgresql"
    if wide_deliveries:
        next_id_after(store, "deliveries", PAST_32_BITS - 1)
    studies, deliveries = StudyStore(store.engine), DeliveryStore(store.engine)
    study = studies.create(
        name="wide", spec={}, jobs=[StudyJob({"seed": 1}, 10, 1, 0, 1)], callback_url=URL
    )
    assert study.id == PAST_32_BITS
    [job] = store.page(status=None, limit=10, before_id=MAX_EXACT_INT, study_id=study.id).jobs
    assert (job.id, job.study_id) == (PAST_32_BITS, PAST_32_BITS)
    alone = store.enqueue({"seed": 2}, robot_steps=10, episodes=1, callback_url=URL)
    assert alone.id == PAST_32_BITS + 1
    for_study, for_job = deliveries.for_study(study.id), deliveries.for_job(alone.id)
    assert for_study is not None and for_job is not None
    if wide_deliveries:
        assert (for_study.id, for_job.id) == (PAST_32_BITS, PAST_32_BITS + 1)

    finished = store.finish(claim(store), outcome())
    assert finished.id == PAST_32_BITS and store.metrics(job.id)["summary"]["total_steps"] == 7
    assert deliveries.promote() == 1
    sending = deliveries.claim(lease_s=LEASE_S)
    assert sending is not None and sending.id == for_study.id
    assert deliveries.settle(sending, status=204, error=None, retry_in_s=None)
    store.save_plot(job.id, "learning", b"png")
    studies.keep_plot(study.id, "metrics", b"png")
    assert store.plot(job.id, "learning") == studies.plot(study.id, "metrics") == b"png"

    states, actions = qlearning.labels("behaviors")
    values = np.zeros((len(states), len(actions)))
    policy = store.policies.add(
        action_set="behaviors", communication=("none",), states=states, actions=actions,
        values=values,
    )  # fmt: skip
    assert policy.id == PAST_32_BITS
    assert store.policies.get(policy.id) == policy
    assert store.owner_of(policy.policy_from) == ""


@pytest.mark.parametrize("missing", [PAST_32_BITS, MAX_EXACT_INT])
def test_an_id_past_32_bits_that_names_no_row_is_not_found(store: JobStore, missing: int) -> None:
    studies, deliveries = StudyStore(store.engine), DeliveryStore(store.engine)
    job = store.enqueue({"seed": 1}, robot_steps=10, episodes=1)
    with pytest.raises(JobNotFound):
        store.get(missing)
    with pytest.raises(JobNotFound):
        store.plot(missing, "learning")
    with pytest.raises(StudyNotFound):
        studies.get(missing)
    with pytest.raises(StudyNotFound):
        studies.plot(missing, "metrics")
    with pytest.raises(PolicyNotFound):
        store.policies.get(missing)
    assert store.owner_of(missing) is None and studies.owner_of(missing) is None
    assert store.policies.owner_of(missing) is None
    assert deliveries.for_job(missing) is None and deliveries.for_study(missing) is None
    assert store.get_many([missing, job.id]) == {job.id: job}
    listed = store.page(status=None, limit=10, before_id=missing)
    assert [j.id for j in listed.jobs] == [job.id]
    assert store.page(status=None, limit=10, before_id=None, study_id=missing).jobs == []
    assert studies.page(limit=10, before_id=missing).studies == []
    assert store.policies.page(limit=10, before_id=missing).policies == []
