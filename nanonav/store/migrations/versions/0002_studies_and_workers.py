"""Studies and their plots, what a study reads of a job, and the workers seen.

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-30
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0002"
down_revision: str | None = "0001"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "studies",
        sa.Column("id", sa.Integer(), autoincrement=True, nullable=False),
        sa.Column("name", sa.String(length=200), nullable=False),
        sa.Column("spec", sa.JSON(), nullable=False),
        sa.Column("jobs", sa.Integer(), nullable=False),
        sa.Column("idempotency_key", sa.String(length=200), nullable=True),
        sa.Column("created_at", sa.DateTime(), nullable=False),
        sa.Column("cancel_requested", sa.Boolean(), nullable=False),
        sa.Column("report", sa.JSON(), nullable=True),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_studies")),
        sa.UniqueConstraint("idempotency_key", name=op.f("uq_studies_idempotency_key")),
    )
    with op.batch_alter_table("jobs") as batch:
        batch.add_column(sa.Column("study_id", sa.Integer(), nullable=True))
        batch.add_column(sa.Column("study_point", sa.Integer(), nullable=True))
        batch.add_column(sa.Column("study_seed", sa.BigInteger(), nullable=True))
        batch.create_foreign_key(
            op.f("fk_jobs_study_id_studies"), "studies", ["study_id"], ["id"], ondelete="CASCADE"
        )
        batch.create_index(op.f("ix_jobs_study_id_id"), ["study_id", "id"])
    with op.batch_alter_table("job_results") as batch:
        batch.add_column(sa.Column("study_metrics", sa.JSON(), nullable=True))
        batch.add_column(sa.Column("curve", sa.JSON(), nullable=True))
    op.create_table(
        "study_plots",
        sa.Column("study_id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(length=64), nullable=False),
        sa.Column("png", sa.LargeBinary(), nullable=False),
        sa.ForeignKeyConstraint(
            ["study_id"],
            ["studies.id"],
            name=op.f("fk_study_plots_study_id_studies"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("study_id", "name", name=op.f("pk_study_plots")),
    )
    op.create_table(
        "workers",
        sa.Column("name", sa.String(length=200), nullable=False),
        sa.Column("started_at", sa.DateTime(), nullable=False),
        sa.Column("seen_at", sa.DateTime(), nullable=False),
        sa.PrimaryKeyConstraint("name", name=op.f("pk_workers")),
    )
    op.create_index(op.f("ix_workers_seen_at"), "workers", ["seen_at"])


def downgrade() -> None:
    op.drop_index(op.f("ix_workers_seen_at"), table_name="workers")
    op.drop_table("workers")
    op.drop_table("study_plots")
    with op.batch_alter_table("job_results") as batch:
        batch.drop_column("curve")
        batch.drop_column("study_metrics")
    with op.batch_alter_table("jobs") as batch:
        batch.drop_index(op.f("ix_jobs_study_id_id"))
        batch.drop_constraint(op.f("fk_jobs_study_id_studies"), type_="foreignkey")
        batch.drop_column("study_seed")
        batch.drop_column("study_point")
        batch.drop_column("study_id")
    op.drop_table("studies")
