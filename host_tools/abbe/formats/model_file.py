"""A model file of any of abbe's forms -> :class:`abbe.model.table.Table`.

Accepted (by content, not by name):

* a table blob (``model.bin``, magic ``ABBE``; docs/table-format.md);
* table JSON (``"format": "abbe-table"``, docs/formats.md);
* the ``model.json`` of ``abbe fit`` (``"abbe-fit"``) or ``abbe import``
  (``"abbe-import"``): their ``table`` member (the quantised table) is used.

Every problem raises :class:`abbe.errors.AbbeInputError` naming the file.
"""

from __future__ import annotations

import json
from pathlib import Path

from abbe.errors import AbbeInputError
from abbe.formats.blob import read_blob
from abbe.formats.table_json import JSON_FORMAT, table_from_json
from abbe.model.table import Table, TableError

#: JSON documents that carry a table under "table".
WRAPPED_FORMATS = ("abbe-fit", "abbe-import")


def load_table(path: str | Path) -> Table:
    """The table in ``path`` (blob, table JSON, or a fit/import model.json)."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise AbbeInputError(f"cannot read the model: {exc.strerror}", file=str(p),
                             field="model") from None
    if data[:4] == b"ABBE":
        try:
            return read_blob(data, source=str(p))
        except TableError as exc:
            raise AbbeInputError(exc.message, file=str(p), field=exc.field or "model") from None
    try:
        doc = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError):
        raise AbbeInputError("not an abbe model: neither a table blob (magic ABBE) nor JSON",
                             file=str(p), field="model") from None
    if isinstance(doc, dict) and doc.get("format") in WRAPPED_FORMATS:
        inner = doc.get("table")
        if not isinstance(inner, dict):
            raise AbbeInputError(f"a {doc['format']} document without a 'table' object",
                                 file=str(p), field="table")
        inner = {k: v for k, v in inner.items() if k not in ("crc32", "size_bytes")}
        return table_from_json(inner, str(p))
    if isinstance(doc, dict) and doc.get("format") != JSON_FORMAT:
        raise AbbeInputError(f"expected a table ('{JSON_FORMAT}') or a model.json of "
                             f"{' / '.join(WRAPPED_FORMATS)}, got format {doc.get('format')!r}",
                             file=str(p), field="format")
    return table_from_json(doc, str(p))
