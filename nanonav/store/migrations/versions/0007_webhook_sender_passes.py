"""A worker's row says when its webhook sender last made progress, for /healthz.

A sender thread that died left every webhook due with nothing to tell: jobs ran and the
health check said ok. Each sender now records when it last finished a pass or a try on its
worker's presence row; /healthz reads the latest, and says so when webhooks are due and no
sender has made progress lately. Existing rows get null (no pass recorded yet).

Revision ID: 0007
Revises: 0006
Create Date: 2026-12-02
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0007"
down_revision: str | None = "0006"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("workers") as batch:
        batch.add_column(sa.Column("webhooks_passed_at", sa.DateTime(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("workers") as batch:
        batch.drop_column("webhooks_passed_at")
