"""Alembic environment: run on the connection :mod:`abbe.history.database` passes in."""

from __future__ import annotations

from alembic import context

from abbe.history.schema import metadata

connection = context.config.attributes["connection"]
context.configure(connection=connection, target_metadata=metadata,
                  render_as_batch=connection.dialect.name == "sqlite")
with context.begin_transaction():
    context.run_migrations()
