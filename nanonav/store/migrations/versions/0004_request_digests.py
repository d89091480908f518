"""Idempotency keys remember the request that used them, so another request under the key is
refused rather than answered with the first one's job.

Revision ID: 0004
Revises: 0003
Create Date: 2026-12-01
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0004"
down_revision: str | None = "0003"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    for table in ("jobs", "studies"):
        with op.batch_alter_table(table) as batch:
            batch.add_column(sa.Column("request_digest", sa.String(length=64), nullable=True))


def downgrade() -> None:
    for table in ("jobs", "studies"):
        with op.batch_alter_table(table) as batch:
            batch.drop_column("request_digest")
