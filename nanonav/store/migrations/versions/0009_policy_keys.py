"""Policies take an Idempotency-Key, as jobs and studies do: the key (unique per owner) and the
digest of the request that used it. Both are added in place, the key's uniqueness by a unique
index: rebuilding the table, as a new constraint would on SQLite, would lose AUTOINCREMENT's
mark of the ids already given, and a deleted policy's id could be given again.

Revision ID: 0009
Revises: 0008
Create Date: 2026-12-02
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0009"
down_revision: str | None = "0008"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column("policies", sa.Column("idempotency_key", sa.String(length=200), nullable=True))
    op.add_column("policies", sa.Column("request_digest", sa.String(length=64), nullable=True))
    op.create_index(
        op.f("ix_policies_owner_idempotency_key"),
        "policies",
        ["owner", "idempotency_key"],
        unique=True,
    )


def downgrade() -> None:
    op.drop_index(op.f("ix_policies_owner_idempotency_key"), table_name="policies")
    op.drop_column("policies", "request_digest")
    op.drop_column("policies", "idempotency_key")
