"""When each worker was ready to take jobs: null while it prepares the engine (a first start
compiles it), so that /healthz tells a worker preparing from one at work.

Revision ID: 0012
Revises: 0011
Create Date: 2026-12-06
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0012"
down_revision: str | None = "0011"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("workers") as batch:
        batch.add_column(sa.Column("ready_at", sa.DateTime(), nullable=True))
    # every worker seen before this revision took jobs as soon as it said it was alive
    op.execute("UPDATE workers SET ready_at = started_at")


def downgrade() -> None:
    with op.batch_alter_table("workers") as batch:
        batch.drop_column("ready_at")
