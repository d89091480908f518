"""Ids of 64 bits on PostgreSQL: the routes take ids up to 2^53 - 1, and an id past 2^31 - 1
bound to a 32-bit column failed the query (a 500, not a 404), as the 2^31-th row would have.

Every id, and every column naming one, becomes BIGINT, and so does the sequence that hands ids
out. Each table is rewritten once, closed to reads and writes until it is. SQLite's INTEGER
already holds 64 bits: nothing changes there. Going back fails once an id is past 2^31 - 1.

Revision ID: 0013
Revises: 0012
Create Date: 2026-12-08
"""

from collections.abc import Sequence

from alembic import op

revision: str = "0013"
down_revision: str | None = "0012"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

# Each table's id columns; the first four tables' ``id`` are handed out by a sequence.
ID_COLUMNS = {
    "studies": ("id",),
    "jobs": ("id", "study_id"),
    "deliveries": ("id", "job_id", "study_id"),
    "policies": ("id",),
    "job_results": ("job_id",),
    "job_plots": ("job_id",),
    "study_plots": ("study_id",),
}
SEQUENCED = ("studies", "jobs", "deliveries", "policies")


def _retype(sql_type: str) -> None:
    if op.get_context().dialect.name != "postgresql":
        return
    for table, columns in ID_COLUMNS.items():
        changes = ", ".join(f"ALTER COLUMN {column} TYPE {sql_type}" for column in columns)
        op.execute(f"ALTER TABLE {table} {changes}")
    for table in SEQUENCED:
        # the sequence found by name in the database, so that this also runs as offline SQL
        sequence = f"pg_get_serial_sequence('{table}', 'id')"
        op.execute(
            f"DO $$ BEGIN EXECUTE 'ALTER SEQUENCE ' || {sequence} || ' AS {sql_type}'; END $$"
        )


def upgrade() -> None:
    _retype("BIGINT")


def downgrade() -> None:
    _retype("INTEGER")
