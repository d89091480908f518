"""Jobs and studies belong to the API key that made them; idempotency keys are per owner.

Revision ID: 0005
Revises: 0004
Create Date: 2026-12-01
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0005"
down_revision: str | None = "0004"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("jobs") as batch:
        batch.add_column(
            sa.Column("owner", sa.String(length=64), server_default="", nullable=False)
        )
        batch.add_column(
            sa.Column("quota_key", sa.String(length=64), server_default="", nullable=False)
        )
        batch.drop_constraint(op.f("uq_jobs_idempotency_key"), type_="unique")
        batch.create_unique_constraint(
            op.f("uq_jobs_owner_idempotency_key"), ["owner", "idempotency_key"]
        )
        batch.create_index(op.f("ix_jobs_owner_id"), ["owner", "id"])
        batch.create_index(op.f("ix_jobs_quota_key_status"), ["quota_key", "status"])
    with op.batch_alter_table("studies") as batch:
        batch.add_column(
            sa.Column("owner", sa.String(length=64), server_default="", nullable=False)
        )
        batch.drop_constraint(op.f("uq_studies_idempotency_key"), type_="unique")
        batch.create_unique_constraint(
            op.f("uq_studies_owner_idempotency_key"), ["owner", "idempotency_key"]
        )


def downgrade() -> None:
    with op.batch_alter_table("studies") as batch:
        batch.drop_constraint(op.f("uq_studies_owner_idempotency_key"), type_="unique")
        batch.create_unique_constraint(op.f("uq_studies_idempotency_key"), ["idempotency_key"])
        batch.drop_column("owner")
    with op.batch_alter_table("jobs") as batch:
        batch.drop_index(op.f("ix_jobs_quota_key_status"))
        batch.drop_index(op.f("ix_jobs_owner_id"))
        batch.drop_constraint(op.f("uq_jobs_owner_idempotency_key"), type_="unique")
        batch.create_unique_constraint(op.f("uq_jobs_idempotency_key"), ["idempotency_key"])
        batch.drop_column("quota_key")
        batch.drop_column("owner")
