from __future__ import annotations

import os
import shutil
import sqlite3
import subprocess
import sys
from pathlib import Path

import numpy as np
from sqlalchemy import inspect, text

from nanonav.engine import qlearning
from nanonav.store import JobStore, StudyJob, StudyStore
from nanonav.store.db import make_engine
from nanonav.store.deliveries import DeliveryStore
from nanonav.store.migrate import at_head, check, downgrade, upgrade
from tests.conftest import migrated_store
from tests.store.test_deliveries import URL
from tests.store.test_ids import id_columns
from tests.store.test_queue import claim, outcome

# the id columns 0013 made BIGINT: those of the tables that stood then (later ones are made so)
ID_COLUMNS = [
    (table, column)
    for table, column in id_columns()
    if table != "job_checkpoints" and column != "trained_policy_id"
]


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
        "job_checkpoints",
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


# What PostgreSQL hands ids out from: a sequence per table whose rows a client names by id.
SEQUENCES = [f"{table}_id_seq" for table in ("deliveries", "jobs", "policies", "studies")]
COLUMN_TYPES = text(
    "SELECT table_name || '.' || column_name, data_type FROM information_schema.columns "
    "WHERE table_schema = current_schema()"
)
SEQUENCE_TYPES = text(
    "SELECT sequence_name, data_type FROM information_schema.sequences "
    "WHERE sequence_schema = current_schema()"
)


def id_types(url: str) -> dict[str, str]:
    """The type of each id column (``table.column``) and of each sequence, as PostgreSQL's
    information_schema names it."""
    ids = {f"{table}.{column}" for table, column in ID_COLUMNS}
    engine = make_engine(url)
    try:
        with engine.connect() as connection:
            columns = {name: kind for name, kind in connection.execute(COLUMN_TYPES)}
            sequences = {name: kind for name, kind in connection.execute(SEQUENCE_TYPES)}
    finally:
        engine.dispose()
    return {name: kind for name, kind in columns.items() if name in ids} | sequences


def test_postgresql_ids_become_bigint_and_keep_their_rows(postgres_url: str) -> None:
    names = [f"{table}.{column}" for table, column in ID_COLUMNS] + SEQUENCES
    upgrade(postgres_url, "0012")
    assert id_types(postgres_url) == dict.fromkeys(names, "integer")
    # the rows are written by today's models, at the head, and taken back to 0012 with it
    upgrade(postgres_url)
    store = JobStore.from_url(postgres_url)
    try:
        studies = StudyStore(store.engine)
        study = studies.create(
            name="s", spec={}, jobs=[StudyJob({"seed": 1}, 10, 1, 0, 1)], callback_url=URL
        )
        job = store.get(store.finish(claim(store), outcome()).id)
        store.save_plot(job.id, "learning", b"job png")
        studies.keep_plot(study.id, "metrics", b"study png")
        states, actions = qlearning.labels("behaviors")
        policy = store.policies.add(
            action_set="behaviors", communication=("none",), states=states, actions=actions,
            values=np.zeros((len(states), len(actions))),
        )  # fmt: skip
    finally:
        store.close()

    downgrade(postgres_url, "0012")
    assert id_types(postgres_url) == dict.fromkeys(names, "integer")
    upgrade(postgres_url, "0013")
    assert id_types(postgres_url) == dict.fromkeys(names, "bigint")
    downgrade(postgres_url, "0012")
    assert id_types(postgres_url) == dict.fromkeys(names, "integer")
    upgrade(postgres_url)
    with migrated_store(postgres_url) as store:
        studies = StudyStore(store.engine)
        assert studies.get(study.id) == study and store.get(job.id) == job
        assert store.metrics(job.id)["summary"]["total_steps"] == 7
        assert store.plot(job.id, "learning") == b"job png"
        assert studies.plot(study.id, "metrics") == b"study png"
        assert store.policies.get(policy.id) == policy
        delivery = DeliveryStore(store.engine).for_study(study.id)
        assert delivery is not None and delivery.url == URL
        with store.engine.begin() as connection:
            connection.execute(text("SELECT setval('jobs_id_seq', 2147483647)"))
        assert store.enqueue({}, robot_steps=1, episodes=1).id == 2**31


def test_sqlite_keeps_its_tables_as_they_were(sqlite_url: str) -> None:
    upgrade(sqlite_url, "0012")
    engine = make_engine(sqlite_url)
    schema = text("SELECT name, sql FROM sqlite_master ORDER BY name")
    try:
        with engine.connect() as connection:
            before = connection.execute(schema).all()
        upgrade(sqlite_url, "0013")
        with engine.connect() as connection:
            assert connection.execute(schema).all() == before
    finally:
        engine.dispose()


def test_an_installed_wheel_migrates_a_database_from_its_own_files(tmp_path: Path) -> None:
    """The migrations ship in the package (nanonav/store/migrations), so a wheel installed
    away from the source tree finds them and migrates a new database to the head revision."""
    root = Path(__file__).resolve().parents[2]
    source = tmp_path / "source"  # built from a copy: a build leaves its folders beside it
    for part in ("nanonav", "service", "worker"):
        shutil.copytree(root / part, source / part, ignore=shutil.ignore_patterns("__pycache__"))
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy(root / name, source / name)
    built = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
         "-w", str(tmp_path / "wheel"), str(source)],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert built.returncode == 0, built.stderr
    [wheel] = (tmp_path / "wheel").glob("nanonav-*.whl")
    installed = tmp_path / "installed"
    done = subprocess.run(
        [sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", str(installed),
         str(wheel)],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    url = f"sqlite:///{tmp_path / 'fresh.db'}"
    code = (
        "import nanonav.store.migrate as m\n"
        f"assert m.__file__.startswith({str(installed)!r}), m.__file__\n"
        f"m.upgrade({url!r})\n"
        "print(m.MIGRATIONS_DIR)\n"
    )
    ran = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=False,
        cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(installed)},
    )  # fmt: skip
    assert ran.returncode == 0, ran.stderr[-2000:]
    assert ran.stdout.strip().startswith(str(installed))
    with sqlite3.connect(tmp_path / "fresh.db") as connection:
        [(revision,)] = connection.execute("SELECT version_num FROM alembic_version").fetchall()
    heads = sorted(
        p.name.split("_")[0] for p in (root / "nanonav/store/migrations/versions").glob("0*.py")
    )
    assert revision == heads[-1]
