"""The first schema: machines, campaigns, instruments, temperatures, inputs, results,
tables, exports.

Revision ID: 0001
Revises:
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None


def _child(name: str, *cols: sa.Column) -> None:
    op.create_table(
        name,
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("campaign_id", sa.Integer, sa.ForeignKey("campaigns.id", ondelete="CASCADE"),
                  nullable=False),
        *cols)
    op.create_index(f"ix_{name}_campaign_id", name, ["campaign_id"])


def upgrade() -> None:
    op.create_table(
        "machines",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("name", sa.String(200), nullable=False, unique=True),
        sa.Column("created_at", sa.DateTime, nullable=False))
    op.create_table(
        "campaigns",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("machine_id", sa.Integer, sa.ForeignKey("machines.id"), nullable=False),
        sa.Column("measured_at", sa.DateTime, nullable=False),
        sa.Column("added_at", sa.DateTime, nullable=False),
        sa.Column("operator", sa.String(200)),
        sa.Column("kinds", sa.String(200), nullable=False),
        sa.Column("source", sa.Text, nullable=False),
        sa.Column("content_sha256", sa.String(64), nullable=False, unique=True),
        sa.Column("abbe_version", sa.String(40), nullable=False))
    op.create_index("ix_campaigns_machine_id", "campaigns", ["machine_id"])
    _child("instruments", sa.Column("name", sa.String(200), nullable=False))
    _child("temperatures", sa.Column("source", sa.String(200), nullable=False),
           sa.Column("value_c", sa.Float, nullable=False))
    _child("inputs", sa.Column("role", sa.String(200), nullable=False),
           sa.Column("file", sa.Text, nullable=False),
           sa.Column("sha256", sa.String(64), nullable=False))
    _child("results", sa.Column("series", sa.String(200), nullable=False),
           sa.Column("source", sa.String(40), nullable=False),
           sa.Column("quantity", sa.String(100), nullable=False),
           sa.Column("axis", sa.String(8)), sa.Column("direction", sa.String(8)),
           sa.Column("plane", sa.String(8)), sa.Column("feed_mm_min", sa.Float),
           sa.Column("value", sa.Float, nullable=False),
           sa.Column("unit", sa.String(20), nullable=False),
           sa.Column("ci_low", sa.Float), sa.Column("ci_high", sa.Float))
    op.create_index("ix_results_series", "results", ["series"])
    _child("tables", sa.Column("source", sa.String(40), nullable=False),
           sa.Column("blob", sa.LargeBinary, nullable=False),
           sa.Column("crc32", sa.BigInteger, nullable=False),
           sa.Column("size_bytes", sa.Integer, nullable=False))
    op.create_table(
        "exports",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("machine_id", sa.Integer, sa.ForeignKey("machines.id")),
        sa.Column("created_at", sa.DateTime, nullable=False),
        sa.Column("kind", sa.String(20), nullable=False),
        sa.Column("path", sa.Text, nullable=False),
        sa.Column("n_campaigns", sa.Integer, nullable=False))
    op.create_index("ix_exports_machine_id", "exports", ["machine_id"])


def downgrade() -> None:
    for name in ("exports", "tables", "results", "inputs", "temperatures", "instruments",
                 "campaigns", "machines"):
        op.drop_table(name)
