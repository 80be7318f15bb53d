"""Every value read back from the database, checked before it is used or written.

The database is shared and may have been edited by hand, by another program or
damaged: abbe never trusts what it reads. :func:`fetch` selects a table's rows
without the driver's conversions (the raw values; PostgreSQL timestamps as text) and
checks each field against the column of :mod:`abbe.history.schema`:

* Float: a finite number (an integer is accepted as a number); Infinity, NaN, text,
  a blob are refused;
* Integer: an integer (not a boolean, not a real);
* String / Text: text, valid UTF-8, no longer than the column;
* DateTime: ``YYYY-MM-DD HH:MM:SS[.ffffff]`` of a real date (UTC), years 1970..9999;
* LargeBinary: bytes;
* NOT NULL columns: present.

A bad value is an :class:`AbbeInputError` (exit 2) naming the database, the table, the
row (its ``id``) and the field: nothing is written from a database that holds one.
"""

from __future__ import annotations

import datetime as dt
import math
import re
from typing import Any

import sqlalchemy as sa

from abbe.errors import AbbeInputError

_DATETIME = re.compile(r"\d{4}-\d{2}-\d{2}[ T]\d{2}:\d{2}:\d{2}(\.\d{1,6})?")


class BadValue(AbbeInputError):
    """A value in the database that abbe did not write (exit 2)."""


def _short(v: Any) -> str:
    raw = getattr(v, "raw", None)
    r = repr(raw if isinstance(raw, bytes) else v)
    return r if len(r) <= 40 else r[:37] + "..."


def check_value(table: str, row: Any, col: sa.Column, v: Any, shown: str | None) -> Any:
    """``v`` as the Python value of column ``col`` of ``table``'s row ``row``, or BadValue."""

    def bad(expected: str) -> BadValue:
        return BadValue(f"table {table}, row {row}, field {col.name}: expected {expected}, "
                        f"found {_short(v)} (the database holds a value abbe did not write: "
                        "edited by hand or damaged); nothing was written",
                        file=shown, field=f"{table}.{col.name}")

    if v is None:
        if not col.nullable and not col.primary_key:
            raise bad("a value (the column is NOT NULL)")
        return None
    t = col.type
    if isinstance(t, sa.Float):
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise bad("a number")
        if not math.isfinite(float(v)):
            raise bad("a finite number")
        return float(v)
    if isinstance(t, sa.Integer):  # BigInteger included
        if isinstance(v, bool) or not isinstance(v, int):
            raise bad("an integer")
        return v
    if isinstance(t, sa.DateTime):
        if not isinstance(v, str) or getattr(v, "raw", None) is not None \
                or not _DATETIME.fullmatch(v):
            raise bad("a date and time YYYY-MM-DD HH:MM:SS (UTC)")
        try:
            when = dt.datetime.fromisoformat(v.replace(" ", "T"))
        except ValueError:
            raise bad("a date and time YYYY-MM-DD HH:MM:SS (UTC) of a real date") from None
        if when.year < 1970:
            raise bad("a date from 1970 on")
        return when
    if isinstance(t, sa.LargeBinary):
        if isinstance(v, memoryview):
            v = v.tobytes()
        if not isinstance(v, bytes):
            raise bad("bytes (a blob)")
        return v
    if isinstance(t, (sa.String, sa.Text)):
        if not isinstance(v, str):
            raise bad("text")
        if getattr(v, "raw", None) is not None:
            raise bad("text in UTF-8")
        length = getattr(t, "length", None)
        if length is not None and len(v) > length:
            raise bad(f"text of at most {length} characters")
        return v
    raise bad(f"a value of type {type(t).__name__}")  # pragma: no cover -- schema has no other


def _raw(conn: Any, col: sa.Column) -> Any:
    """``col`` selected without the driver's or SQLAlchemy's conversion."""
    if isinstance(col.type, sa.DateTime) and conn.dialect.name == "postgresql":
        return sa.cast(col, sa.Text).label(col.name)  # 'infinity' stays text, refused
    return sa.type_coerce(col, sa.types.NullType()).label(col.name)


def fetch(conn: Any, table: sa.Table, *where: Any, order_by: Any = None,
          columns: list[str] | None = None, shown: str | None = None) -> list[dict[str, Any]]:
    """The rows of ``table`` matching ``where``, each field checked (module docstring)."""
    cols = [table.c[n] for n in (columns or [c.name for c in table.columns])]
    if "id" not in [c.name for c in cols]:
        cols = [table.c.id, *cols]
    q = sa.select(*[_raw(conn, c) for c in cols])
    for w in where:
        q = q.where(w)
    q = q.order_by(*(order_by if isinstance(order_by, (list, tuple)) else
                     [order_by] if order_by is not None else [table.c.id]))
    out = []
    name = table.name
    id_col = table.c.id
    for r in conn.execute(q):
        row_id = check_value(name, "?", id_col, r[0], shown)
        out.append({c.name: check_value(name, row_id, c, v, shown) for c, v in zip(cols, r)})
    return out
