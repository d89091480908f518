"""An id, once given, is never given again; retention finds expired jobs by an index.

SQLite gives a new row the largest id plus one, so deleting the newest job or study handed its
id to the next one: a client holding the old id, a browser's cached ``immutable`` results and a
webhook receiver would all take the new row for the old. ``AUTOINCREMENT`` keeps a high-water
mark instead (PostgreSQL's sequences already never go back). Rows keep their ids.

Revision ID: 0006
Revises: 0005
Create Date: 2026-12-01
"""

from collections.abc import Sequence

from alembic import op

revision: str = "0006"
down_revision: str | None = "0005"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    if op.get_context().dialect.name == "sqlite":
        for table in ("studies", "jobs"):
            with op.batch_alter_table(
                table, recreate="always", table_kwargs={"sqlite_autoincrement": True}
            ):
                pass
    op.create_index(op.f("ix_jobs_finished_at"), "jobs", ["finished_at"])


def downgrade() -> None:
    op.drop_index(op.f("ix_jobs_finished_at"), table_name="jobs")
    if op.get_context().dialect.name == "sqlite":
        for table in ("jobs", "studies"):
            with op.batch_alter_table(
                table, recreate="always", table_kwargs={"sqlite_autoincrement": False}
            ):
                pass
