"""Networks trained in jobs: which jobs train one (``trains``: only a worker that trains claims
them, ``workers.trains``), the decisions done and where a resumed run took up
(``decisions``, ``resumed_from_decisions``), the policy the trained network was kept as
(``trained_policy_id``), and the checkpoint of a training under way (``job_checkpoints``: the
trainer's state and its curve, kept until the job ends).

Revision ID: 0014
Revises: 0013
Create Date: 2026-12-07
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0014"
down_revision: str | None = "0013"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

ROW_ID = sa.BigInteger().with_variant(sa.Integer(), "sqlite")
# a default given as text: one given as an expression would make SQLite rebuild ``jobs``, and
# the rebuilt table would lose AUTOINCREMENT's high-water mark of deleted ids (migration 0006)
FALSE = "0"


def upgrade() -> None:
    with op.batch_alter_table("jobs") as batch:
        batch.add_column(sa.Column("trains", sa.Boolean(), server_default=FALSE,
                                   nullable=False))  # fmt: skip
        batch.add_column(sa.Column("decisions", sa.BigInteger(), nullable=True))
        batch.add_column(sa.Column("resumed_from_decisions", sa.BigInteger(), nullable=True))
        batch.add_column(sa.Column("trained_policy_id", ROW_ID, nullable=True))
    with op.batch_alter_table("workers") as batch:
        batch.add_column(sa.Column("trains", sa.Boolean(), server_default=FALSE,
                                   nullable=False))  # fmt: skip
    op.create_table(
        "job_checkpoints",
        sa.Column("job_id", ROW_ID, nullable=False),
        sa.Column("decisions", sa.BigInteger(), nullable=False),
        sa.Column("data", sa.LargeBinary(), nullable=False),
        sa.Column("curve", sa.JSON(), nullable=False),
        sa.Column("written_at", sa.DateTime(), nullable=False),
        sa.ForeignKeyConstraint(
            ["job_id"],
            ["jobs.id"],
            name=op.f("fk_job_checkpoints_job_id_jobs"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("job_id", name=op.f("pk_job_checkpoints")),
    )


def downgrade() -> None:
    op.drop_table("job_checkpoints")
    with op.batch_alter_table("workers") as batch:
        batch.drop_column("trains")
    with op.batch_alter_table("jobs") as batch:
        for column in ("trained_policy_id", "resumed_from_decisions", "decisions", "trains"):
            batch.drop_column(column)
