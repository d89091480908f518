"""Policies may be networks (ONNX models) as well as Q-tables: a column says which. Added in
place, every policy kept so far a table.

Revision ID: 0010
Revises: 0009
Create Date: 2026-12-04
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0010"
down_revision: str | None = "0009"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column(
        "policies",
        sa.Column("kind", sa.String(length=16), nullable=False, server_default="table"),
    )


def downgrade() -> None:
    op.drop_column("policies", "kind")
