"""``abbe history export``: the stored campaigns as CSV (one row per value) or JSON.

CSV columns (units in the ``unit`` column; times UTC, ISO 8601)::

    machine,campaign,measured_at,operator,series,source,quantity,axis,direction,plane,
    feed_mm_min,value,unit,ci_low,ci_high,expanded_u,coverage_k

(``expanded_u``: the expanded uncertainty U in ``unit`` with its coverage factor
``coverage_k``, empty when the producer stated none; added in version 1.1, appended at
the end so a reader by position keeps working.)

JSON: ``{"format": "abbe-history", "version": "1.1", "machines": [{"name", "campaigns":
[{"id", "measured_at", "added_at", "operator", "kinds", "note", "content_sha256",
"instruments", "temperatures": [{"source", "value_c"}], "inputs": [{"role", "file",
"sha256"}], "tables": [{"source", "crc32", "size_bytes"}], "results": [...]}]}]}``
with the same result fields as the CSV. Empty fields are empty cells / ``null``.
"""

from __future__ import annotations

import csv
import io
import json
from typing import Any

import sqlalchemy as sa

from abbe.history import schema as S
from abbe.history.readback import fetch
from abbe.history.store import campaigns_of

CSV_COLUMNS = ("machine", "campaign", "measured_at", "operator", "series", "source", "quantity",
               "axis", "direction", "plane", "feed_mm_min", "value", "unit", "ci_low", "ci_high",
               "expanded_u", "coverage_k")
_RESULT_FIELDS = CSV_COLUMNS[4:]


def _iso(t: Any) -> str:
    return t.strftime("%Y-%m-%dT%H:%M:%SZ")


def collect(conn: Any, machine_ids: list[int], shown: str | None = None) -> dict[str, Any]:
    """Everything stored about ``machine_ids`` (removed campaigns left out) as one
    JSON-ready document, every value checked as read (:mod:`abbe.history.readback`)."""
    doc: dict[str, Any] = {"format": "abbe-history", "version": "1.1", "machines": []}
    for mid in machine_ids:
        name = fetch(conn, S.machines, S.machines.c.id == mid, shown=shown)[0]["name"]
        camps = campaigns_of(conn, mid, shown)
        ids = [c["id"] for c in camps]
        by: dict[int, dict[str, list]] = {i: {"instruments": [], "temperatures": [], "inputs": [],
                                              "tables": [], "results": []} for i in ids}

        def rows(table: sa.Table, cols: list[str]) -> Any:
            for r in fetch(conn, table, table.c.campaign_id.in_(ids), shown=shown,
                           columns=["campaign_id", *cols]):
                if r["campaign_id"] in by:
                    yield r["campaign_id"], {k: r[k] for k in cols}

        if ids:
            for cid, r in rows(S.instruments, ["name"]):
                by[cid]["instruments"].append(r["name"])
            for cid, r in rows(S.temperatures, ["source", "value_c"]):
                by[cid]["temperatures"].append(r)
            for cid, r in rows(S.inputs, ["role", "file", "sha256"]):
                by[cid]["inputs"].append(r)
            for cid, r in rows(S.tables, ["source", "crc32", "size_bytes"]):
                by[cid]["tables"].append(
                    {"source": r["source"], "crc32": f"0x{r['crc32']:08X}",
                     "size_bytes": r["size_bytes"]})
            for cid, r in rows(S.results, list(_RESULT_FIELDS)):
                by[cid]["results"].append(r)
        doc["machines"].append({"name": name, "campaigns": [
            {"id": c["id"], "measured_at": _iso(c["measured_at"]), "added_at": _iso(c["added_at"]),
             "operator": c["operator"], "kinds": c["kinds"].split(","), "note": c["note"],
             "content_sha256": c["content_sha256"], **by[c["id"]]} for c in camps]})
    return doc


def to_json(doc: dict[str, Any]) -> str:
    return json.dumps(doc, indent=1, allow_nan=False) + "\n"


def to_csv(doc: dict[str, Any]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for m in doc["machines"]:
        for c in m["campaigns"]:
            for r in c["results"]:
                w.writerow([m["name"], c["id"], c["measured_at"], c["operator"] or "",
                            *("" if r[k] is None else (repr(r[k]) if isinstance(r[k], float)
                                                       else r[k]) for k in _RESULT_FIELDS)])
    return buf.getvalue()
