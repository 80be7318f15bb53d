"""The history of a machine's campaigns in a database: what changed since the last time.

Every campaign (the outputs of ``abbe fit``, ``ballbar``, ``iso230-2``, ``diagnose``
or ``demo``) is read strictly and stored in one transaction; trends, bands and
alerts are computed from the stored results. SQLite by default, PostgreSQL for a
fleet (docs/history.md).

* :mod:`~abbe.history.deps`: the optional extra (SQLAlchemy, Alembic, psycopg),
  imported lazily with a clear message when missing.
* :mod:`~abbe.history.schema`: the tables (SQLAlchemy Core) at the newest revision.
* :mod:`~abbe.history.database`: where the database is, opening it (foreign and
  read-only databases refused before any write), migrations under a lock, the exit
  status of every database condition, passwords masked.
* :mod:`~abbe.history.readback`: every value read back checked (finite, typed, a date).
* :mod:`~abbe.history.zones`: dates stored in UTC, given and shown in the site's zone.
* :mod:`~abbe.history.ingest`: an output folder -> a :class:`Campaign` (no database);
  :mod:`~abbe.history.document` the strict JSON document and the campaign it fills,
  :mod:`~abbe.history.output_readers` the readers of the five-axis, thermal, printer,
  predict and export outputs.
* :mod:`~abbe.history.store`: a campaign in, series out (one transaction each);
  remove / amend with the audit trail.
* :mod:`~abbe.history.trends`: bands, trend lines and alerts (numpy).
* :mod:`~abbe.history.limits`: tolerances and the alert settings (TOML).
* :mod:`~abbe.history.report`, :mod:`~abbe.history.export`: what is written.
"""
