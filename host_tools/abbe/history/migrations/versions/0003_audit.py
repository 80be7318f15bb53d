"""Corrections and removals with an audit trail (``abbe history amend`` / ``remove``):
``campaigns.removed_at`` (a removed campaign is kept, hidden from trends) and the
``audit`` table (who, when, why, the field, its old and new value).

Revision ID: 0003
Revises: 0002
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("campaigns") as batch:
        batch.add_column(sa.Column("removed_at", sa.DateTime))
    op.create_table(
        "audit",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("campaign_id", sa.Integer, sa.ForeignKey("campaigns.id"), nullable=False),
        sa.Column("at", sa.DateTime, nullable=False),
        sa.Column("who", sa.String(200), nullable=False),
        sa.Column("action", sa.String(20), nullable=False),
        sa.Column("field", sa.String(40)),
        sa.Column("old_value", sa.Text),
        sa.Column("new_value", sa.Text),
        sa.Column("reason", sa.Text, nullable=False))
    op.create_index("ix_audit_campaign_id", "audit", ["campaign_id"])


def downgrade() -> None:
    op.drop_index("ix_audit_campaign_id", "audit")
    op.drop_table("audit")
    with op.batch_alter_table("campaigns") as batch:
        batch.drop_column("removed_at")
