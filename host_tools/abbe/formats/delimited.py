"""Delimited text tables (CSV and instrument exports) read column-wise with bounded memory.

:class:`Dialect` says how a file is written (delimiter, decimal mark, lines before
the header, a units row under the header, comment prefix, encoding);
:func:`read_columns` reads a :class:`abbe.formats.text.TextFile` in that dialect:
the header row, the optional units row, then the data rows, converting only the
planned columns (:class:`Column`) chunk by chunk with the strict number parser,
so 10^6 rows cost a few arrays, not 10^7 Python strings. Every problem names
file, line and the column as the file spells it.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from abbe.errors import AbbeInputError, parse_int_column, parse_number_column
from abbe.formats.text import TextFile

#: Rows converted at once (bounds the transient Python strings).
CHUNK_ROWS = 65_536
#: Whitespace around cells: ASCII only (a no-break space is not a separator, it is garbage).
_WS = " \t"
DELIMITERS = {",": ",", ";": ";", "tab": "\t", "\t": "\t", "|": "|", "whitespace": None, " ": None}


@dataclass(frozen=True)
class Dialect:
    """How a delimited file is written. ``delimiter`` None = runs of whitespace."""

    delimiter: str | None = ","
    decimal: str = "."
    skip_lines: int = 0
    units_row: bool = False
    comment: str = "#"
    encoding: str = "utf-8"

    def split(self, line: str, *, file: str, no: int) -> list[str]:
        """The stripped cells of one line (quotes honoured for a one-character delimiter)."""
        if self.delimiter is None:
            return line.split(None) if line.isascii() else [c for c in line.replace("\t", " ").split(" ") if c]
        if '"' not in line:
            cells = line.split(self.delimiter)
            return [c.strip(_WS) for c in cells] if (" " in line or "\t" in line) else cells
        try:
            rec = next(csv.reader([line], delimiter=self.delimiter, strict=True))
        except csv.Error as exc:
            raise AbbeInputError(f"malformed quoted cell: {exc}", file=file, line=no) from None
        return [c.strip(_WS) for c in rec]


DEFAULT_DIALECT = Dialect()


@dataclass
class Column:
    """A planned column: where it is and how its cells become values.

    kind "number": finite float in [lo, hi] (unit of lo/hi) after x scale;
    kind "int": integer in [lo, hi]; kind "choice": ``choices`` maps the cell
    (lower-cased) to a small integer. ``name`` is the column as the file spells it.
    """

    name: str
    index: int
    kind: str = "number"
    lo: float = -1e15
    hi: float = 1e15
    unit: str = ""
    scale: float = 1.0
    choices: dict[str, int] = field(default_factory=dict)
    expected: str = ""  # for choice errors: what the cell may be


@dataclass
class Header:
    """The header row (and the units row) as read."""

    line: int
    names: list[str]
    units: list[str] | None = None
    units_line: int | None = None


def read_columns(tf: TextFile, dialect: Dialect, *, what: str, max_rows: int,
                 plan: Callable[[Header], dict[str, Column]]) -> tuple[Header, dict[str, np.ndarray], np.ndarray]:
    """Read the table of ``tf``: ``plan(header)`` names the columns to convert.

    Returns (header, key -> array (int64 for int/choice, float64 for number),
    line number of every data row). Blank lines and comment lines are skipped
    (after the first ``skip_lines`` lines, which are skipped whatever they hold).
    """
    name = tf.name
    header: Header | None = None
    cols: dict[str, Column] = {}
    chunk_rows: list[list[str]] = []
    parts: dict[str, list[np.ndarray]] = {}
    line_parts: list[np.ndarray] = []
    chunk_lines: list[int] = []
    n_rows = 0
    want_units = dialect.units_row

    def flush() -> None:
        if not chunk_lines:
            return
        ln = np.array(chunk_lines, dtype=np.int64)
        columns = list(zip(*chunk_rows))
        for key, col in cols.items():
            cells = columns[col.index]
            if col.kind == "number":
                arr = parse_number_column(cells, ln, file=name, field=col.name, lo=col.lo,
                                          hi=col.hi, unit=col.unit, decimal=dialect.decimal,
                                          scale=col.scale)
            elif col.kind == "int":
                arr = parse_int_column(cells, ln, file=name, field=col.name, lo=int(col.lo),
                                       hi=int(col.hi))
            else:
                got = [col.choices.get(c.lower(), -1) for c in cells]
                arr = np.array(got, dtype=np.int64)
                if (arr < 0).any():
                    i = int(np.argmax(arr < 0))
                    raise AbbeInputError(f"expected {col.expected}, got {cells[i]!r}", file=name,
                                         line=int(ln[i]), field=col.name)
            parts[key].append(arr)
        line_parts.append(ln)
        chunk_lines.clear()
        chunk_rows.clear()

    width = 0
    for no, line in tf.lines():
        if no <= dialect.skip_lines:
            continue
        stripped = line.strip(_WS)
        if not stripped or (dialect.comment and stripped.startswith(dialect.comment)):
            continue
        cells = dialect.split(line, file=name, no=no)
        if not any(cells):
            continue
        if header is None:
            header = Header(no, cells)
            width = len(cells)
            if not want_units:
                cols = plan(header)
                parts = {k: [] for k in cols}
            continue
        if want_units:
            if len(cells) != width:
                raise AbbeInputError(f"units row has {len(cells)} cells, the header has {width}",
                                     file=name, line=no)
            header.units, header.units_line = cells, no
            want_units = False
            cols = plan(header)
            parts = {k: [] for k in cols}
            continue
        if len(cells) != width:
            raise AbbeInputError(f"row has {len(cells)} cells, the header has {width}", file=name,
                                 line=no)
        n_rows += 1
        if n_rows > max_rows:
            raise AbbeInputError(f"more than {max_rows} data rows: the limit for a {what} "
                                 "(docs/formats.md, \"Limits\")", file=name, line=no)
        chunk_lines.append(no)
        chunk_rows.append(cells)
        if len(chunk_lines) >= CHUNK_ROWS:
            flush()
    if header is None:
        raise AbbeInputError(f"empty {what}: expected a header row", file=name,
                             line=dialect.skip_lines + 1 if dialect.skip_lines else 1)
    if want_units:
        raise AbbeInputError("expected a units row under the header (units_row = true)",
                             file=name, line=header.line)
    flush()
    data = {k: (np.concatenate(v) if v else np.empty(0, dtype=np.int64 if cols[k].kind != "number"
                                                      else np.float64)) for k, v in parts.items()}
    lines = np.concatenate(line_parts) if line_parts else np.empty(0, dtype=np.int64)
    return header, data, lines
