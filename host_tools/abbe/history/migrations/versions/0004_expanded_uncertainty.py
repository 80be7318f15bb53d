"""Each result's expanded uncertainty (issue 37): ``results.expanded_u`` (U, in the result's
unit) and ``results.coverage_k`` (the coverage factor k it was stated with, 2), both
nullable: a result whose producer states no U, and every result stored before this
revision, keeps NULL (never 0: "no uncertainty stated" is not "exact").

Revision ID: 0004
Revises: 0003
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("results") as batch:
        batch.add_column(sa.Column("expanded_u", sa.Float))
        batch.add_column(sa.Column("coverage_k", sa.Float))


def downgrade() -> None:
    with op.batch_alter_table("results") as batch:
        batch.drop_column("coverage_k")
        batch.drop_column("expanded_u")
