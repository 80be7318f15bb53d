"""The history database's tables at the newest revision (SQLAlchemy Core).

The migrations (``migrations/versions``) build exactly this; a test compares the
two (Alembic's autogenerate comparison finds no difference). Units are in the
column names or in ``unit``; times are UTC without a zone.

* ``machines``: one row per machine name.
* ``campaigns``: one measurement campaign of a machine: when (``measured_at``), who
  (``operator``), what it was read from (``kinds``: fit, ballbar, ...), the SHA-256
  of its content (``content_sha256``, unique: the same campaign twice is refused),
  a free ``note`` (revision 0002).
* ``instruments``, ``temperatures``, ``inputs``: per campaign, the instruments, the
  temperatures (deg C, with where each came from) and the SHA-256 of every file
  read and of every measurement file the outputs name.
* ``results``: one value per row: ``series`` (the key a trend follows, e.g.
  ``iso230-2 B X bi``), the quantity, axis, direction, plane and feed where they
  apply, value, unit, 95 % interval when the producer gave one, and (revision 0004) the
  expanded uncertainty U with its coverage factor k (``expanded_u``, ``coverage_k``)
  when the producer states one (NULL otherwise, and in every row stored before 0004).
* ``tables``: the table blobs (``model.bin`` of fit / diagnose) with their CRC-32.
* ``exports``: every export and report written from the database (what, where, when).
* ``audit`` (revision 0003): every correction of a campaign (``history amend``) and
  every removal (``history remove``): who, when (UTC), why, the field and its old and
  new value. A removed campaign stays, with ``removed_at`` set: nothing is deleted.
"""

from __future__ import annotations

import sqlalchemy as sa

metadata = sa.MetaData()

machines = sa.Table(
    "machines", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("name", sa.String(200), nullable=False, unique=True),
    sa.Column("created_at", sa.DateTime, nullable=False),
)

campaigns = sa.Table(
    "campaigns", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("machine_id", sa.Integer, sa.ForeignKey("machines.id"), nullable=False, index=True),
    sa.Column("measured_at", sa.DateTime, nullable=False),
    sa.Column("added_at", sa.DateTime, nullable=False),
    sa.Column("operator", sa.String(200)),
    sa.Column("kinds", sa.String(200), nullable=False),
    sa.Column("source", sa.Text, nullable=False),
    sa.Column("content_sha256", sa.String(64), nullable=False, unique=True),
    sa.Column("abbe_version", sa.String(40), nullable=False),
    sa.Column("note", sa.Text),  # revision 0002
    sa.Column("removed_at", sa.DateTime),  # revision 0003: removed (kept, hidden), UTC
)

instruments = sa.Table(
    "instruments", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("campaign_id", sa.Integer, sa.ForeignKey("campaigns.id", ondelete="CASCADE"),
              nullable=False, index=True),
    sa.Column("name", sa.String(200), nullable=False),
)

temperatures = sa.Table(
    "temperatures", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("campaign_id", sa.Integer, sa.ForeignKey("campaigns.id", ondelete="CASCADE"),
              nullable=False, index=True),
    sa.Column("source", sa.String(200), nullable=False),
    sa.Column("value_c", sa.Float, nullable=False),
)

inputs = sa.Table(
    "inputs", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("campaign_id", sa.Integer, sa.ForeignKey("campaigns.id", ondelete="CASCADE"),
              nullable=False, index=True),
    sa.Column("role", sa.String(200), nullable=False),
    sa.Column("file", sa.Text, nullable=False),
    sa.Column("sha256", sa.String(64), nullable=False),
)

results = sa.Table(
    "results", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("campaign_id", sa.Integer, sa.ForeignKey("campaigns.id", ondelete="CASCADE"),
              nullable=False, index=True),
    sa.Column("series", sa.String(200), nullable=False, index=True),
    sa.Column("source", sa.String(40), nullable=False),
    sa.Column("quantity", sa.String(100), nullable=False),
    sa.Column("axis", sa.String(8)),
    sa.Column("direction", sa.String(8)),
    sa.Column("plane", sa.String(8)),
    sa.Column("feed_mm_min", sa.Float),
    sa.Column("value", sa.Float, nullable=False),
    sa.Column("unit", sa.String(20), nullable=False),
    sa.Column("ci_low", sa.Float),
    sa.Column("ci_high", sa.Float),
    sa.Column("expanded_u", sa.Float),  # revision 0004: U in the result's unit, or NULL
    sa.Column("coverage_k", sa.Float),  # revision 0004: its coverage factor (2), or NULL
)

tables = sa.Table(
    "tables", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("campaign_id", sa.Integer, sa.ForeignKey("campaigns.id", ondelete="CASCADE"),
              nullable=False, index=True),
    sa.Column("source", sa.String(40), nullable=False),
    sa.Column("blob", sa.LargeBinary, nullable=False),
    sa.Column("crc32", sa.BigInteger, nullable=False),
    sa.Column("size_bytes", sa.Integer, nullable=False),
)

exports = sa.Table(
    "exports", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("machine_id", sa.Integer, sa.ForeignKey("machines.id"), index=True),
    sa.Column("created_at", sa.DateTime, nullable=False),
    sa.Column("kind", sa.String(20), nullable=False),
    sa.Column("path", sa.Text, nullable=False),
    sa.Column("n_campaigns", sa.Integer, nullable=False),
)

audit = sa.Table(
    "audit", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("campaign_id", sa.Integer, sa.ForeignKey("campaigns.id"), nullable=False,
              index=True),
    sa.Column("at", sa.DateTime, nullable=False),
    sa.Column("who", sa.String(200), nullable=False),
    sa.Column("action", sa.String(20), nullable=False),
    sa.Column("field", sa.String(40)),
    sa.Column("old_value", sa.Text),
    sa.Column("new_value", sa.Text),
    sa.Column("reason", sa.Text, nullable=False),
)
