"""Thermal test records (ISO 230-3): time, spindle speed, temperatures, displacements.

Two sources, one result (:class:`ThermalRecord`):

* a CSV (docs/formats.md, "Thermal record CSV"): header ``time_s,spindle_rpm,<name>_c ...,
  <name>_um ...``: temperatures end in ``_c`` (deg C), displacement channels in ``_um``;
  ``spindle_rpm`` may be absent (no speed input);
* an ``.xlsx`` workbook as data loggers export it, read with openpyxl (extra ``thermal``):
  the first sheet (or the one named), a header row ``NAME(UNIT)`` per column: ``(s)`` the
  time, ``(RPM)`` the speed, ``(°C)`` / ``(degC)`` / ``(C)`` a temperature, ``(um)`` /
  ``(µm)`` a displacement (the shared record's ``時間(s) ``, ``spindle(RPM)``, ``ch1(um)``,
  ``t1(°C)``).

Promises: every problem is an :class:`AbbeInputError` naming the file, the line (CSV) or the
sheet row (xlsx, 1-based as the spreadsheet shows it), the column and what was expected;
no NaN / Inf, no empty cell, no dropped row (an empty row between data rows is an error);
times strictly increasing; values inside :data:`RANGES`.
"""

from __future__ import annotations

import re
from array import array
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np

from abbe.errors import AbbeInputError, check_number, parse_number
from abbe.formats.delimited import DEFAULT_DIALECT, Column, Header, read_columns
from abbe.formats.limits import LASER_CSV_MAX_BYTES
from abbe.formats.text import read_bytes, read_text

#: Largest record (rows): 30 days at 1 s.
MAX_ROWS = 2_600_000
#: Largest .xlsx file, bytes.
XLSX_MAX_BYTES = 256 * 1024 * 1024
#: Accepted ranges: time s, speed rpm, temperature deg C, displacement um.
RANGES = {"time": (0.0, 1e8, "s"), "speed": (0.0, 100000.0, "rpm"),
          "temperature": (-50.0, 200.0, "deg C"), "displacement": (-10000.0, 10000.0, "um")}
_HEADER_RE = re.compile(r"^\s*(.*?)\s*\(\s*([^()]*?)\s*\)\s*$")
_UNITS = {"s": "time", "rpm": "speed", "°c": "temperature", "degc": "temperature",
          "c": "temperature", "um": "displacement", "µm": "displacement", "μm": "displacement"}


@dataclass(frozen=True)
class ThermalRecord:
    """A thermal test record.

    ``time_s`` (n,) s; ``speed_rpm`` (n,) rpm or None; ``temps_c`` (n, k) deg C with
    ``temp_names``; ``disp_um`` (n, m) um with ``channel_names``; ``rows``: the line (CSV)
    or sheet row (xlsx) of every sample, ``row_kind`` "line" / "row".
    """

    file: str
    time_s: np.ndarray
    speed_rpm: np.ndarray | None
    temps_c: np.ndarray
    temp_names: tuple[str, ...]
    disp_um: np.ndarray
    channel_names: tuple[str, ...]
    rows: np.ndarray
    row_kind: str = "line"

    @property
    def hours(self) -> np.ndarray:
        return self.time_s / 3600.0

    def to_csv(self) -> str:
        """The record in the CSV format (time s, rpm, deg C, um)."""
        head = ["time_s"] + (["spindle_rpm"] if self.speed_rpm is not None else [])
        head += [f"{n}_c" for n in self.temp_names] + [f"{n}_um" for n in self.channel_names]
        cols = [self.time_s] + ([self.speed_rpm] if self.speed_rpm is not None else [])
        cols += list(self.temps_c.T) + list(self.disp_um.T)
        lines = [",".join(head)]
        for row in zip(*cols):
            lines.append(",".join(f"{v:.10g}" for v in row))
        return "\n".join(lines) + "\n"


def _check(rec: ThermalRecord) -> ThermalRecord:
    where = "LINE" if rec.row_kind == "line" else "ROW"
    n = rec.time_s.size
    if n < 2:
        raise AbbeInputError(f"{n} samples: a thermal record needs at least 2", file=rec.file,
                             field="time")
    if not rec.channel_names:
        raise AbbeInputError("no displacement channel (a column in um)", file=rec.file,
                             line=int(rec.rows[0]) - 1 if rec.rows.size else None)
    dt = np.diff(rec.time_s)
    if np.any(dt <= 0):
        i = int(np.argmax(dt <= 0)) + 1
        raise AbbeInputError(f"time {rec.time_s[i]:g} s after {rec.time_s[i - 1]:g} s: expected "
                             f"strictly increasing times ({where} {int(rec.rows[i])})",
                             file=rec.file, line=int(rec.rows[i]), field="time")
    return rec


def _names(names: list[str], suffix: str) -> tuple[str, ...]:
    return tuple(n[: -len(suffix)] for n in names)


def read_thermal_csv(path: str | Path) -> ThermalRecord:
    """Read a thermal record CSV (module docs); AbbeInputError (file, line, column)."""
    path = Path(path)
    f = str(path)
    tf = read_text(path, what="thermal record CSV", max_bytes=LASER_CSV_MAX_BYTES)

    def plan(header: Header) -> dict[str, Column]:
        cols: dict[str, Column] = {}
        seen: set[str] = set()
        for i, h in enumerate(header.names):
            if h in seen:
                raise AbbeInputError(f"column {h!r} appears twice", file=f, line=header.line,
                                     field=h)
            seen.add(h)
            if h == "time_s":
                kind = "time"
            elif h == "spindle_rpm":
                kind = "speed"
            elif h.endswith("_c") and len(h) > 2:
                kind = "temperature"
            elif h.endswith("_um") and len(h) > 3:
                kind = "displacement"
            else:
                raise AbbeInputError(f"unknown column {h!r}: expected time_s, spindle_rpm, "
                                     "NAME_c (deg C) or NAME_um (um)", file=f, line=header.line,
                                     field=h)
            lo, hi, unit = RANGES[kind]
            cols[h] = Column(h, i, lo=lo, hi=hi, unit=unit)
        if "time_s" not in cols:
            raise AbbeInputError("missing column 'time_s'", file=f, line=header.line,
                                 field="time_s")
        return cols

    header, vals, lines = read_columns(tf, DEFAULT_DIALECT, what="thermal record CSV",
                                       max_rows=MAX_ROWS, plan=plan)
    temps = [h for h in header.names if h.endswith("_c") and h != "spindle_rpm"]
    disps = [h for h in header.names if h.endswith("_um")]
    n = lines.size
    rec = ThermalRecord(
        file=f, time_s=vals["time_s"],
        speed_rpm=vals.get("spindle_rpm"),
        temps_c=np.column_stack([vals[h] for h in temps]) if temps else np.empty((n, 0)),
        temp_names=_names(temps, "_c"),
        disp_um=np.column_stack([vals[h] for h in disps]) if disps else np.empty((n, 0)),
        channel_names=_names(disps, "_um"), rows=lines, row_kind="line")
    return _check(rec)


def _classify_header(cells: tuple, f: str, row: int) -> list[tuple[str, str]]:
    """(kind, name) per column of an xlsx header row."""
    out: list[tuple[str, str]] = []
    for j, c in enumerate(cells):
        col = _col_letter(j)
        if not isinstance(c, str) or not c.strip():
            raise AbbeInputError(f"header cell {col}{row} is {c!r}: expected NAME(UNIT) "
                                 "(units s, RPM, °C, um)", file=f, line=row, field=col)
        m = _HEADER_RE.match(c)
        kind = _UNITS.get(m.group(2).strip().lower()) if m else None
        if kind is None:
            raise AbbeInputError(f"header {c!r}: expected NAME(UNIT) with unit s, RPM, °C or um",
                                 file=f, line=row, field=c.strip())
        name = m.group(1).strip() if kind not in ("time", "speed") else kind
        if kind in ("temperature", "displacement") and not re.fullmatch(r"[A-Za-z0-9_.-]+", name):
            raise AbbeInputError(f"header {c!r}: a sensor name of letters, digits, _ . -",
                                 file=f, line=row, field=c.strip())
        if any(name == n for _, n in out):
            raise AbbeInputError(f"header {c!r}: {name} appears twice", file=f, line=row,
                                 field=c.strip())
        out.append((kind, name))
    kinds = [k for k, _ in out]
    if kinds.count("time") != 1 or kinds.count("speed") > 1:
        raise AbbeInputError("expected one time column (s) and at most one speed column (RPM)",
                             file=f, line=row, field="header")
    return out


def _col_letter(j: int) -> str:
    s = ""
    j += 1
    while j:
        j, r = divmod(j - 1, 26)
        s = chr(65 + r) + s
    return s


def _sheet_rows(ws: object, f: str) -> Iterator[tuple[int, dict[int, object]]]:
    """(sheet row, {column (1-based): value}) of every row the sheet's XML holds, in order.

    Not ``ws.iter_rows``: openpyxl's read-only iterator trusts the sheet's ``<dimension>``
    and the row numbers, and silently drops the rows below and the cells right of the
    declared dimension and any row numbered at or below an earlier one. Its own parser is
    used instead (the same one, same cell values), and a repeated or out-of-order row or
    cell is refused."""
    from openpyxl.worksheet._reader import WorkSheetParser

    wb = ws.parent  # type: ignore[attr-defined]
    src = ws._get_source()  # type: ignore[attr-defined]
    try:
        parser = WorkSheetParser(src, ws._shared_strings,  # type: ignore[attr-defined]
                                 data_only=True, epoch=wb.epoch,
                                 date_formats=wb._date_formats,
                                 timedelta_formats=wb._timedelta_formats)
        prev = 0
        for r, cells in parser.parse():
            if r <= prev:
                raise AbbeInputError(f"sheet row {r} comes after row {prev}: expected the rows "
                                     "of the sheet's XML in increasing order, each once",
                                     file=f, line=r)
            prev = r
            row: dict[int, object] = {}
            for c in cells:
                j = int(c["column"])
                if j in row or (row and j < max(row)):
                    col = _col_letter(j - 1)
                    raise AbbeInputError(f"cell {col}{r} repeated or out of order in the "
                                         "sheet's XML: expected each cell once, left to right",
                                         file=f, line=r, field=col)
                row[j] = c["value"]
            yield r, row
    finally:
        src.close()


def read_thermal_xlsx(path: str | Path, sheet: str | None = None) -> ThermalRecord:
    """Read a thermal record from an ``.xlsx`` workbook (module docs); errors name the
    sheet row and the column (``FILE:ROW: field 'ch3': ...``)."""
    path = Path(path)
    f = str(path)
    read_bytes(path, what="thermal record workbook", max_bytes=XLSX_MAX_BYTES)  # size, access
    try:
        import openpyxl
    except ImportError as exc:  # pragma: no cover - the extra is in the lock
        raise AbbeInputError("reading .xlsx needs openpyxl: pip install 'abbe[thermal]'",
                             file=f) from exc
    try:
        wb = openpyxl.load_workbook(f, read_only=True, data_only=True)
    except Exception as exc:  # a corrupt or foreign file: openpyxl's many exception types
        raise AbbeInputError(f"not a readable .xlsx workbook ({type(exc).__name__}: {exc})",
                             file=f) from None
    r = 0  # the sheet row being read (for an error in the sheet's XML)
    try:
        if sheet is not None and sheet not in wb.sheetnames:
            raise AbbeInputError(f"no sheet {sheet!r}: the workbook has {wb.sheetnames}",
                                 file=f, field="sheet")
        if sheet is None and not wb.worksheets:
            raise AbbeInputError("the workbook has no worksheet", file=f, field="sheet")
        ws = wb[sheet] if sheet is not None else wb.worksheets[0]
        it = _sheet_rows(ws, f)
        header: dict[int, object] | None = None
        hrow = 0
        for r, cells in it:
            if any(c is not None for c in cells.values()):
                header, hrow = cells, r
                break
        if header is None:
            raise AbbeInputError("empty sheet: expected a header row", file=f, line=1)
        width = max(j for j, c in header.items() if c is not None)
        spec = _classify_header(tuple(header.get(j) for j in range(1, width + 1)), f, hrow)
        # one pass, converted as read: 8 bytes a value (array 'd'), not a row of objects
        cols = [array("d") for _ in range(width)]
        rows = array("q")
        checks = [(RANGES[kind], name, _col_letter(j)) for j, (kind, name) in enumerate(spec)]
        blank_at: int | None = None
        last = hrow
        for r, raw in it:
            if blank_at is None and r > last + 1:  # rows the sheet XML leaves out are empty
                blank_at = last + 1
            last = r
            if all(c is None for c in raw.values()):
                if blank_at is None:
                    blank_at = r
                continue
            if blank_at is not None:
                raise AbbeInputError(f"empty row {blank_at} between data rows: a record has no "
                                     "gaps (delete the row or split the record)", file=f,
                                     line=blank_at)
            beyond = sorted(j for j, c in raw.items() if j > width and c is not None)
            if beyond:
                c = _col_letter(beyond[0] - 1)
                raise AbbeInputError(f"cell {c}{r} lies beyond the header's {width} columns: "
                                     "expected a header for every column", file=f, line=r,
                                     field=c)
            if len(rows) >= MAX_ROWS:
                raise AbbeInputError(f"more than {MAX_ROWS} data rows", file=f, line=r)
            for j in range(width):
                v = raw.get(j + 1)
                (lo, hi, unit), name, col = checks[j]
                if isinstance(v, str):
                    # only ASCII blanks: str.strip() would also drop a no-break space
                    v = parse_number(v.strip(" \t"), file=f, line=r, field=name, lo=lo, hi=hi,
                                     unit=unit)
                elif v is None:
                    raise AbbeInputError(f"empty cell {col}{r}: expected a number in "
                                         f"[{lo:g}, {hi:g}] {unit}", file=f, line=r, field=name)
                else:
                    v = check_number(v, file=f, line=r, field=name, lo=lo, hi=hi, unit=unit)
                cols[j].append(v)
            rows.append(r)
    except (AbbeInputError, MemoryError):
        raise
    except Exception as exc:  # openpyxl on a broken sheet XML: its many exception types
        raise AbbeInputError(f"the sheet's XML is not readable after row {r} "
                             f"({type(exc).__name__}: {exc})", file=f, line=r + 1) from None
    finally:
        wb.close()
    vals = (np.column_stack([np.frombuffer(c, dtype=np.float64) for c in cols]) if len(rows)
            else np.empty((0, width)))
    kinds = [k for k, _ in spec]
    temps = [j for j, k in enumerate(kinds) if k == "temperature"]
    disps = [j for j, k in enumerate(kinds) if k == "displacement"]
    rec = ThermalRecord(
        file=f, time_s=vals[:, kinds.index("time")],
        speed_rpm=vals[:, kinds.index("speed")] if "speed" in kinds else None,
        temps_c=vals[:, temps], temp_names=tuple(spec[j][1] for j in temps),
        disp_um=vals[:, disps], channel_names=tuple(spec[j][1] for j in disps),
        rows=np.array(rows, dtype=np.int64), row_kind="row")
    return _check(rec)


def read_thermal_record(path: str | Path, sheet: str | None = None) -> ThermalRecord:
    """A record from ``.xlsx`` (openpyxl) or CSV, by the file's extension."""
    if str(path).lower().endswith(".xlsx"):
        return read_thermal_xlsx(path, sheet)
    if sheet is not None:
        raise AbbeInputError("a sheet is named only for an .xlsx workbook", file=str(path),
                             field="sheet")
    return read_thermal_csv(path)
