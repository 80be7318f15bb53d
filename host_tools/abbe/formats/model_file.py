"""A model file of any of abbe's forms -> :class:`abbe.model.table.Table`.

Accepted (by content, not by name):

* a table blob (``model.bin``, magic ``ABBE``; docs/table-format.md), at most
  ``BLOB_MAX_BYTES``;
* table JSON (``"format": "abbe-table"``, docs/formats.md);
* the ``model.json`` of ``abbe fit`` (``"abbe-fit"``) or ``abbe import``
  (``"abbe-import"``): their ``table`` member (the quantised table) is used, read
  as strictly as table JSON (unknown keys refused with a suggestion; its
  informational ``crc32`` and ``size_bytes`` are the only extra members).

The file is read by the bounded reader (``TABLE_JSON_MAX_BYTES``), JSON strictly
(no NaN / Infinity, no duplicated keys, bounded nesting and number length); a JSON
table must be one the table format can hold (travel min < max, every value within
the blob's caps: what the controller-side library would load); every problem raises :class:`abbe.errors.AbbeInputError` naming the file, the line
and the field.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from abbe.errors import AbbeInputError
from abbe.errors.numbers import show_value
from abbe.formats.blob import MAGIC, read_blob, write_blob
from abbe.formats.limits import BLOB_MAX_BYTES, TABLE_JSON_MAX_BYTES
from abbe.formats.structured import JsonLocator, json_from_bytes
from abbe.formats.table_json import JSON_FORMAT, table_from_json
from abbe.formats.text import read_bytes
from abbe.model.table import Table, TableError

#: JSON documents that carry a table under "table".
WRAPPED_FORMATS = ("abbe-fit", "abbe-import")
#: members of a wrapped "table" besides the table JSON's own
_WRAPPED_EXTRA = ("crc32", "size_bytes")


class _Within:
    """A JsonLocator for a member: ``line("axes.X")`` is the line of ``table.axes.X``."""

    def __init__(self, loc: JsonLocator, prefix: str) -> None:
        self.loc, self.prefix = loc, prefix

    def line(self, dotted: str | None) -> int | None:
        return self.loc.line(self.prefix + (f".{dotted}" if dotted else ""))


def _wrapped(doc: dict[str, Any], name: str, loc: JsonLocator) -> Table:
    inner = doc.get("table")
    if not isinstance(inner, dict):
        raise AbbeInputError(f"a {doc['format']} document needs a 'table' object, got "
                             f"{show_value(inner)}", file=name, line=loc.line("table"),
                             field="table")
    body = {k: v for k, v in inner.items() if k not in _WRAPPED_EXTRA}
    try:
        return table_from_json(body, name, _Within(loc, "table"))  # type: ignore[arg-type]
    except AbbeInputError as exc:
        if exc.field is not None and not exc.field.startswith("table"):
            exc.field = f"table.{exc.field}"
            exc.args = (str(exc),)
        raise


def _holdable(table: Table, name: str, loc: JsonLocator, prefix: str = "") -> Table:
    """``table`` if the table format can hold it (travel ordered, every value within the
    blob's caps: what the C library would load), else the encoder's error located."""
    try:
        write_blob(table)
    except TableError as exc:
        fld = prefix + (exc.field or "")
        raise AbbeInputError(exc.message, file=name, line=loc.line(fld) if fld else None,
                             field=fld or None) from None
    return table


def load_table(path: str | Path) -> Table:
    """The table in ``path`` (blob, table JSON, or a fit/import model.json)."""
    name = str(path)
    data = read_bytes(path, what="model", max_bytes=TABLE_JSON_MAX_BYTES)
    if data[:4] == MAGIC:
        if len(data) > BLOB_MAX_BYTES:
            raise AbbeInputError(f"a table blob is at most {BLOB_MAX_BYTES} bytes (docs/formats.md,"
                                 " \"Limits\")", file=name, field="model")
        return read_blob(data, source=name)
    head = data.lstrip(b"\xef\xbb\xbf \t\r\n")[:1]
    # "[" goes on to the JSON reader too: its message (nesting, syntax) says more than ours
    if head not in (b"{", b"[") and not data.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise AbbeInputError("not an abbe model: neither a table blob (magic ABBE) nor a JSON "
                             "object", file=name, field="model")
    doc, tf = json_from_bytes(data, name=name, what="model JSON")
    loc = JsonLocator(tf.text)
    if not isinstance(doc, dict):
        raise AbbeInputError(f"expected a JSON object, got {show_value(doc)}", file=name, line=1,
                             field="model")
    fmt = doc.get("format")
    if fmt in WRAPPED_FORMATS:
        return _holdable(_wrapped(doc, name, loc), name, loc, "table.")
    if fmt != JSON_FORMAT:
        raise AbbeInputError(f"expected a table ('{JSON_FORMAT}') or a model.json of "
                             f"{' / '.join(WRAPPED_FORMATS)}, got {show_value(fmt)}",
                             file=name, line=loc.line("format"), field="format")
    return _holdable(table_from_json(doc, name, loc), name, loc)
