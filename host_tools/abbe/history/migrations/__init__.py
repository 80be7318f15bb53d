"""Alembic migrations of the history database (run by :mod:`abbe.history.database`)."""
