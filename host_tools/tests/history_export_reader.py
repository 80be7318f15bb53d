"""Independent reader of `abbe history export` (CSV and JSON, export version 1.1),
written from docs/history.md alone (its sections "abbe history export", "Tables", the
series table and "The expanded uncertainty of each value"), not from the writer.

``read_history_csv`` / ``read_history_json`` parse the file strictly (CSV: the documented
header in its order, one row per value; JSON: no NaN / Infinity, no repeated key, the
documented keys and nothing else), check every documented field (type, range, the
direction words, UTC ISO 8601 times ending in ``Z``, SHA-256 digests) and the invariants
the page states (U and k stated together or not at all, k = 2, U >= 0, a 95 % interval
low <= high and holding its value, removed campaigns left out: ids unique) and return the
rows. ``same_values`` checks that the CSV and JSON exports of one database hold the same
values. A violation raises ``FormatError`` naming the file, row and field. Nothing is
imported from abbe.
"""

from __future__ import annotations

import csv
import math
import re
from pathlib import Path
from typing import Any

from doc_json_readers import FormatError, _fail, _int, _list, _num, _obj, _str, load_strict

#: docs/history.md, "abbe history export": the CSV header, in this order (1.1 appends
#: expanded_u and coverage_k after ci_high).
CSV_HEADER = ("machine", "campaign", "measured_at", "operator", "series", "source", "quantity",
              "axis", "direction", "plane", "feed_mm_min", "value", "unit", "ci_low", "ci_high",
              "expanded_u", "coverage_k")
#: The result keys of the JSON (the same fields as the CSV's value columns).
RESULT_KEYS = {"series", "source", "quantity", "axis", "direction", "plane", "feed_mm_min",
               "value", "unit", "ci_low", "ci_high", "expanded_u", "coverage_k"}
CAMPAIGN_KEYS = {"id", "measured_at", "added_at", "operator", "kinds", "note", "content_sha256",
                 "instruments", "temperatures", "inputs", "tables", "results"}
#: docs/history.md "Tables": results.direction.
DIRECTIONS = {"bi", "up", "down", "ccw", "cw"}
#: docs/history.md "Tables": campaigns.kinds; tables.source.
KINDS_WORDS = re.compile(r"[a-z0-9][a-z0-9 ._-]*")
TABLE_SOURCES = {"fit", "diagnose"}
#: "exports keep UTC (...Z)"; "dates ... from 1970".
_UTC = re.compile(r"(\d{4})-(\d{2})-(\d{2})T(\d{2}):(\d{2}):(\d{2})Z")
_SHA256 = re.compile(r"[0-9a-f]{64}")
#: The series table's units (the effect's unit for `diagnose KEY`: one of these too).
UNITS = {"um", "urad", "um/K", "ppm/K", "ms", "mm", "um/h", "um/run", "1", "%", "ppm", "deg",
         "um/m", "K", "mm/min", "deg C", "s", "h"}
#: A 95 % interval and the value it is written with are rounded alike; a value may sit this
#: far outside its interval by rounding alone (relative to the interval's width and value).
_ROUND = 1e-6


def _utc(v: Any, where: str) -> str:
    s = _str(v, where)
    m = _UTC.fullmatch(s)
    if not m:
        _fail(where, f"expected a UTC time YYYY-MM-DDTHH:MM:SSZ, got {s!r}")
    y, mo, d, h, mi, se = map(int, m.groups())
    if not (y >= 1970 and 1 <= mo <= 12 and 1 <= d <= 31 and h < 24 and mi < 60 and se < 60):
        _fail(where, f"not a real date from 1970: {s!r}")
    return s


def _check_result(r: dict[str, Any], where: str) -> dict[str, Any]:
    """The invariants of one value (docs/history.md, "Tables" and "The expanded uncertainty
    of each value"); ``r`` holds numbers or None."""
    _str(r["series"], where + ".series")
    _str(r["source"], where + ".source")
    _str(r["quantity"], where + ".quantity")
    if r["direction"] is not None and r["direction"] not in DIRECTIONS:
        _fail(where + ".direction", f"expected one of {sorted(DIRECTIONS)} or none, got "
                                    f"{r['direction']!r}")
    if r["feed_mm_min"] is not None:
        _num(r["feed_mm_min"], where + ".feed_mm_min", lo=0.0)
        if r["feed_mm_min"] <= 0:
            _fail(where + ".feed_mm_min", f"a feed must be > 0, got {r['feed_mm_min']!r}")
    v = _num(r["value"], where + ".value")
    if r["unit"] not in UNITS:
        _fail(where + ".unit", f"expected a unit of the series table {sorted(UNITS)}, got "
                               f"{r['unit']!r}")
    lo, hi = r["ci_low"], r["ci_high"]
    if (lo is None) != (hi is None):
        _fail(where + ".ci_low", f"a 95 % interval has both ends or none: {lo!r}, {hi!r}")
    if lo is not None:
        _num(lo, where + ".ci_low")
        _num(hi, where + ".ci_high")
        tol = _ROUND * max(1.0, abs(v), hi - lo)
        if not lo <= hi or not lo - tol <= v <= hi + tol:
            _fail(where + ".ci_low", f"the 95 % interval [{lo!r}, {hi!r}] must hold the value "
                                     f"{v!r}")
    U, k = r["expanded_u"], r["coverage_k"]
    if (U is None) != (k is None):
        _fail(where + ".expanded_u", f"U and its coverage factor are stated together or not at "
                                     f"all: expanded_u {U!r}, coverage_k {k!r}")
    if U is not None:
        _num(U, where + ".expanded_u", lo=0.0)
        if _num(k, where + ".coverage_k") != 2.0:
            _fail(where + ".coverage_k", f"k must be 2, got {k!r}")
    return r


def _cell(text: str, where: str, kind: str) -> Any:
    """A CSV cell: empty = none; a number written as a JSON-like decimal (no nan / inf)."""
    if text == "":
        return None
    if kind == "str":
        return text
    if not re.fullmatch(r"-?(0|[1-9]\d*)(\.\d+)?([eE][-+]?\d+)?", text):
        _fail(where, f"expected a decimal number or an empty cell, got {text!r}")
    v = float(text)
    if not math.isfinite(v):
        _fail(where, f"expected a finite number, got {text!r}")
    return v


_NUMBER_COLS = {"feed_mm_min", "value", "ci_low", "ci_high", "expanded_u", "coverage_k"}


def read_history_csv(path: Path) -> list[dict[str, Any]]:
    """The rows of a CSV export (docs/history.md): each a dict of the header's columns,
    numbers as float, an empty cell as None, ``campaign`` an int."""
    where0 = str(path)
    raw = Path(path).read_bytes()
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        _fail(where0, f"not UTF-8 ({e})")
    rows = list(csv.reader(text.splitlines()))
    if not rows or tuple(rows[0]) != CSV_HEADER:
        _fail(where0 + ":1", f"header {rows[0] if rows else None!r}, expected {CSV_HEADER!r}")
    out: list[dict[str, Any]] = []
    campaigns: dict[tuple[str, int], tuple[str, str | None]] = {}
    for n, cells in enumerate(rows[1:], start=2):
        where = f"{where0}:{n}"
        if len(cells) != len(CSV_HEADER):
            _fail(where, f"{len(cells)} cells, the header has {len(CSV_HEADER)}")
        r: dict[str, Any] = {}
        for col, c in zip(CSV_HEADER, cells):
            r[col] = _cell(c, f"{where}.{col}", "num" if col in _NUMBER_COLS else "str")
        r["machine"] = _str(r["machine"], where + ".machine")
        if not re.fullmatch(r"[1-9]\d*", cells[1]):
            _fail(where + ".campaign", f"expected a campaign id (integer >= 1), got {cells[1]!r}")
        r["campaign"] = int(cells[1])
        _utc(r["measured_at"], where + ".measured_at")
        key = (r["machine"], r["campaign"])
        seen = campaigns.setdefault(key, (r["measured_at"], r["operator"]))
        if seen != (r["measured_at"], r["operator"]):
            _fail(where + ".measured_at", f"campaign {key} has two dates / operators: {seen} "
                                          f"and {(r['measured_at'], r['operator'])}")
        out.append(_check_result(r, where))
    return out


def read_history_json(path: Path) -> dict[str, Any]:
    """A JSON export (docs/history.md): every documented key and invariant checked."""
    where0 = str(path)
    doc = _obj(load_strict(path), where0, {"format", "version", "machines"})
    if doc["format"] != "abbe-history":
        _fail(where0 + ".format", f"expected 'abbe-history', got {doc['format']!r}")
    if doc["version"] != "1.1":
        _fail(where0 + ".version", f"expected '1.1' (this reader's version), got "
                                   f"{doc['version']!r}")
    names: set[str] = set()
    for i, m in enumerate(_list(doc["machines"], where0 + ".machines")):
        wm = f"{where0}.machines[{i}]"
        _obj(m, wm, {"name", "campaigns"})
        name = _str(m["name"], wm + ".name")
        if name in names:
            _fail(wm + ".name", f"machine {name!r} twice")
        names.add(name)
        ids: set[int] = set()
        for j, c in enumerate(_list(m["campaigns"], wm + ".campaigns")):
            wc = f"{wm}.campaigns[{j}]"
            _obj(c, wc, CAMPAIGN_KEYS)
            cid = _int(c["id"], wc + ".id", lo=1)
            if cid in ids:
                _fail(wc + ".id", f"campaign {cid} twice")
            ids.add(cid)
            _utc(c["measured_at"], wc + ".measured_at")
            _utc(c["added_at"], wc + ".added_at")
            for key in ("operator", "note"):
                if c[key] is not None:
                    _str(c[key], f"{wc}.{key}", empty=True)
            kinds = _list(c["kinds"], wc + ".kinds")
            for w in kinds:
                if not isinstance(w, str) or not KINDS_WORDS.fullmatch(w):
                    _fail(wc + ".kinds", f"expected the kinds of the campaign, got {kinds!r}")
            if not _SHA256.fullmatch(_str(c["content_sha256"], wc + ".content_sha256")):
                _fail(wc + ".content_sha256", f"not a SHA-256: {c['content_sha256']!r}")
            for s in _list(c["instruments"], wc + ".instruments"):
                _str(s, wc + ".instruments")
            for t, te in enumerate(_list(c["temperatures"], wc + ".temperatures")):
                wt = f"{wc}.temperatures[{t}]"
                _obj(te, wt, {"source", "value_c"})
                _str(te["source"], wt + ".source")
                _num(te["value_c"], wt + ".value_c", lo=-273.15, hi=1000.0)
            for t, inp in enumerate(_list(c["inputs"], wc + ".inputs")):
                wi = f"{wc}.inputs[{t}]"
                _obj(inp, wi, {"role", "file", "sha256"})
                _str(inp["role"], wi + ".role")
                _str(inp["file"], wi + ".file")
                if not _SHA256.fullmatch(_str(inp["sha256"], wi + ".sha256")):
                    _fail(wi + ".sha256", f"not a SHA-256: {inp['sha256']!r}")
            for t, tb in enumerate(_list(c["tables"], wc + ".tables")):
                wt = f"{wc}.tables[{t}]"
                _obj(tb, wt, {"source", "crc32", "size_bytes"})
                if tb["source"] not in TABLE_SOURCES:
                    _fail(wt + ".source", f"expected one of {sorted(TABLE_SOURCES)}, got "
                                          f"{tb['source']!r}")
                crc = tb["crc32"]
                if not isinstance(crc, str) or not re.fullmatch(r"0x[0-9A-F]{8}", crc):
                    _fail(wt + ".crc32", f"expected a CRC-32 as 0x%08X, got {crc!r}")
                _int(tb["size_bytes"], wt + ".size_bytes", lo=1)
            for t, r in enumerate(_list(c["results"], wc + ".results")):
                wr = f"{wc}.results[{t}]"
                _obj(r, wr, RESULT_KEYS)
                for key in ("axis", "plane", "direction"):
                    if r[key] is not None:
                        _str(r[key], f"{wr}.{key}")
                _check_result(r, wr)
    return doc


def same_values(rows: list[dict[str, Any]], doc: dict[str, Any], where: str = "export") -> int:
    """The CSV rows and the JSON document of one database hold the same values (the CSV:
    one row per value of the JSON's results, with its campaign's date and operator).
    Returns the number of values."""
    want = []
    for m in doc["machines"]:
        for c in m["campaigns"]:
            for r in c["results"]:
                want.append({"machine": m["name"], "campaign": c["id"],
                             "measured_at": c["measured_at"], "operator": c["operator"] or None,
                             **{k: r[k] for k in RESULT_KEYS}})

    def key(r: dict[str, Any]) -> tuple:
        return tuple("" if r[k] is None else str(r[k]) for k in ("machine", "campaign", "series"))

    got = sorted(rows, key=key)
    want.sort(key=key)
    if len(got) != len(want):
        _fail(where, f"the CSV has {len(got)} values, the JSON {len(want)}")
    for a, b in zip(got, want):
        for k in CSV_HEADER:
            x, y = a[k], b[k]
            if isinstance(y, (int, float)) and not isinstance(y, bool) and x is not None:
                if not math.isclose(float(x), float(y), rel_tol=1e-12, abs_tol=0.0):
                    _fail(f"{where}: {key(a)}.{k}", f"CSV {x!r}, JSON {y!r}")
            elif (x if x != "" else None) != (y if y != "" else None):
                _fail(f"{where}: {key(a)}.{k}", f"CSV {x!r}, JSON {y!r}")
    return len(got)


__all__ = ["FormatError", "read_history_csv", "read_history_json", "same_values"]
