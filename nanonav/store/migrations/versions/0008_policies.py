"""Policies: Q-tables made elsewhere and sent, that scenarios evaluate as ``policy-<id>``.

A row keeps the table (its labels and values as ``.npz``) and what lists show of it: the action
set and communication models whose layout it is, its numbers of states, actions and tables.
On SQLite its ids are never handed out again, as jobs' and studies' are not (0006).

Revision ID: 0008
Revises: 0007
Create Date: 2026-12-03
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0008"
down_revision: str | None = "0007"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "policies",
        sa.Column("id", sa.Integer(), autoincrement=True, nullable=False),
        sa.Column("name", sa.String(length=200), nullable=True),
        sa.Column("owner", sa.String(length=64), server_default="", nullable=False),
        sa.Column("created_at", sa.DateTime(), nullable=False),
        sa.Column("action_set", sa.String(length=16), nullable=False),
        sa.Column("communication", sa.JSON(), nullable=False),
        sa.Column("states", sa.Integer(), nullable=False),
        sa.Column("actions", sa.Integer(), nullable=False),
        sa.Column("tables", sa.Integer(), nullable=False),
        sa.Column("per_robot", sa.Boolean(), nullable=False),
        sa.Column("table", sa.LargeBinary(), nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_policies")),
        sqlite_autoincrement=True,
    )
    op.create_index(op.f("ix_policies_owner_id"), "policies", ["owner", "id"])


def downgrade() -> None:
    op.drop_index(op.f("ix_policies_owner_id"), table_name="policies")
    op.drop_table("policies")
