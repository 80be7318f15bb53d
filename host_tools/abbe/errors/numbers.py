"""The strict number parser: ASCII decimal only, finite, inside a range stated per field.

Every reader turns text into numbers here, so every file accepts the same
numbers (docs/formats.md, "Numbers"):

* a number is ``[+-]digits[.digits][(e|E)[+-]digits]`` (or ``.digits``), ASCII
  digits only, at most :data:`MAX_NUMBER_CHARS` characters: no ``1_0``, no
  Arabic-Indic or full-width digits, no ``nan``/``inf``, no hex, no spaces inside;
* with ``decimal=","`` the decimal mark is a comma instead (``1,25``); a file
  uses one mark, never both, and no thousands separators;
* the value must be finite and inside the field's range ``[lo, hi]`` (in the
  unit the caller names), else :class:`abbe.errors.AbbeInputError` names the
  file, line and field, the text read and the range expected;
* integers (run numbers, counts) are ``[+-]digits`` inside ``[lo, hi]``.

:func:`check_number` / :func:`check_int` apply the same rules to values a TOML
or JSON parser already produced (booleans are not numbers; huge integers are
refused without converting them).

The column forms parse a whole column at once (numpy), for files of 10^6 rows;
the error names the first bad cell exactly as the scalar form would.
"""

from __future__ import annotations

import math
import re
from typing import Any, Sequence

import numpy as np

#: Longest number text accepted (characters).
MAX_NUMBER_CHARS = 64
#: Magnitude bound when a caller gives no range (far beyond any measurement).
DEFAULT_LIMIT = 1e15

_DEC = {".": re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"),
        ",": re.compile(r"[+-]?(?:[0-9]+(?:,[0-9]*)?|,[0-9]+)(?:[eE][+-]?[0-9]+)?")}
_INT = re.compile(r"[+-]?[0-9]+")
_NOT_DECIMAL = {".": re.compile(r"[^0-9.eE+\-\n]"), ",": re.compile(r"[^0-9,eE+\-\n]")}


def _err(msg: str, file: str | None, line: int | None, field: str | None) -> Exception:
    from abbe.errors.input_error import AbbeInputError
    return AbbeInputError(msg, file=file, line=line, field=field)


def _g(x: float) -> str:
    return f"{x:.6g}"


def _range_text(lo: float, hi: float, unit: str) -> str:
    u = f" {unit}" if unit else ""
    return f"[{_g(lo)}, {_g(hi)}]{u}"


def _show(text: str) -> str:
    """The offending text, shortened for a one-line message."""
    return repr(text if len(text) <= 40 else text[:30] + "..." + f" ({len(text)} characters)")


def show_value(v: Any) -> str:
    """A parsed value for a message, never converting a huge integer to text."""
    if isinstance(v, bool):
        return repr(v)
    if isinstance(v, int):
        if v.bit_length() > 128:
            return f"an integer of about {int(v.bit_length() * 0.30103) + 1} digits"
        return str(v)
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, str):
        return _show(v)
    if isinstance(v, (list, dict)):
        return f"a {'list' if isinstance(v, list) else 'table'} of {len(v)} items"
    return type(v).__name__


def _why_not(text: str, decimal: str) -> str:
    if not text:
        return "expected a number, got an empty cell"
    if len(text) > MAX_NUMBER_CHARS:
        return f"expected a number of at most {MAX_NUMBER_CHARS} characters, got {_show(text)}"
    low = text.lower().lstrip("+-")
    if low in ("nan", "inf", "infinity"):
        return f"expected a finite number, got {_show(text)}"
    if not text.isascii():
        return f"expected ASCII decimal digits, got {_show(text)}"
    other = "," if decimal == "." else "."
    if other in text and _DEC[other].fullmatch(text):
        return (f"expected a number with the decimal mark {decimal!r}, got {_show(text)}"
                + (" (declare decimal = \",\" for a decimal comma)" if decimal == "." else ""))
    return f"expected a number, got {_show(text)}"


def parse_number(text: str, *, file: str | None = None, line: int | None = None,
                 field: str | None = None, lo: float = -DEFAULT_LIMIT, hi: float = DEFAULT_LIMIT,
                 unit: str = "", decimal: str = ".", scale: float = 1.0) -> float:
    """A finite number in ``[lo, hi]`` from a text cell (already stripped).

    ``scale`` converts the file's unit into the unit of ``lo``/``hi``/``unit``
    (value = number x scale). Raises AbbeInputError naming file, line, field.
    """
    if len(text) > MAX_NUMBER_CHARS or not _DEC[decimal].fullmatch(text):
        raise _err(_why_not(text, decimal), file, line, field)
    raw = float(text if decimal == "." else text.replace(",", "."))
    if not math.isfinite(raw):
        raise _err(f"expected a finite number, got {_show(text)}", file, line, field)
    v = raw * scale
    if not lo <= v <= hi:  # also a product beyond the double range (inf)
        got = _show(text) if scale == 1.0 or not math.isfinite(v) else \
            f"{_show(text)} = {_g(v)} {unit}".rstrip()
        raise _err(f"expected a number in {_range_text(lo, hi, unit)}, got {got}", file, line,
                   field)
    return v


def parse_int(text: str, *, file: str | None = None, line: int | None = None,
              field: str | None = None, lo: int, hi: int) -> int:
    """An integer in ``[lo, hi]`` from a text cell: ASCII ``[+-]digits`` only."""
    if len(text) > 20 or not _INT.fullmatch(text):
        if _INT.fullmatch(text):
            raise _err(f"expected an integer in [{lo}, {hi}], got {_show(text)}", file, line,
                       field)
        raise _err(f"expected an integer, got {_show(text)}", file, line, field)
    v = int(text)
    if not lo <= v <= hi:
        raise _err(f"expected an integer in [{lo}, {hi}], got {_show(text)}", file, line, field)
    return v


def parse_number_column(cells: Sequence[str], lines: Sequence[int] | np.ndarray, *,
                        file: str | None, field: str | None, lo: float = -DEFAULT_LIMIT,
                        hi: float = DEFAULT_LIMIT, unit: str = "", decimal: str = ".",
                        scale: float = 1.0) -> np.ndarray:
    """:func:`parse_number` over a column (cells stripped; lines[i] = line of cells[i]).

    Vectorised: one character-class scan and one numpy conversion; on any
    failure the first bad cell is re-parsed by :func:`parse_number` for its message.
    """
    n = len(cells)
    out = np.empty(n, dtype=np.float64)
    if n == 0:
        return out

    def first_bad() -> None:
        for i, c in enumerate(cells):
            parse_number(c, file=file, line=int(lines[i]), field=field, lo=lo, hi=hi, unit=unit,
                         decimal=decimal, scale=scale)
        raise AssertionError("parse_number_column: no bad cell found")  # pragma: no cover

    joined = "\n".join(cells)
    if (_NOT_DECIMAL[decimal].search(joined) or max(map(len, cells)) > MAX_NUMBER_CHARS
            or not all(cells)):
        first_bad()
    if decimal == ",":
        joined = joined.replace(",", ".")
        cells = joined.split("\n")
    try:
        out[:] = np.array(cells, dtype=np.float64)
    except ValueError:
        first_bad()
    if scale != 1.0:
        with np.errstate(over="ignore", invalid="ignore"):  # an overflow is refused below
            out *= scale
    bad = ~np.isfinite(out) | (out < lo) | (out > hi)
    if bad.any():
        i = int(np.argmax(bad))
        orig = cells[i].replace(".", ",") if decimal == "," else cells[i]
        parse_number(orig, file=file, line=int(lines[i]), field=field, lo=lo, hi=hi, unit=unit,
                     decimal=decimal, scale=scale)
    return out


def parse_int_column(cells: Sequence[str], lines: Sequence[int] | np.ndarray, *,
                     file: str | None, field: str | None, lo: int, hi: int) -> np.ndarray:
    """:func:`parse_int` over a column; int64 array."""
    n = len(cells)
    if n == 0:
        return np.empty(0, dtype=np.int64)
    ok = all(c and len(c) <= 18 and c.isascii() and (c.isdigit() or (c[0] in "+-" and c[1:].isdigit()))
             for c in cells)
    if ok:
        out = np.array(cells).astype(np.int64)
        bad = (out < lo) | (out > hi)
        if not bad.any():
            return out
        i = int(np.argmax(bad))
        parse_int(cells[i], file=file, line=int(lines[i]), field=field, lo=lo, hi=hi)
    for i, c in enumerate(cells):
        parse_int(c, file=file, line=int(lines[i]), field=field, lo=lo, hi=hi)
    raise AssertionError("parse_int_column: no bad cell found")  # pragma: no cover


def check_number(v: Any, *, file: str | None = None, line: int | None = None,
                 field: str | None = None, lo: float = -DEFAULT_LIMIT, hi: float = DEFAULT_LIMIT,
                 unit: str = "", lo_open: bool = False) -> float:
    """A value from a TOML/JSON parser as a finite float in ``[lo, hi]`` (``(lo, hi]``
    with ``lo_open``); booleans, strings and huge integers are refused."""
    u = f" ({unit})" if unit else ""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise _err(f"expected a number{u}, got {show_value(v)}", file, line, field)
    if isinstance(v, float) and not math.isfinite(v):
        raise _err(f"expected a finite number{u}, got {show_value(v)}", file, line, field)
    # int vs float comparisons are exact in Python: no overflow for huge integers
    if v < lo or v > hi or (lo_open and v <= lo):
        rng = _range_text(lo, hi, unit)
        if lo_open:
            rng = "(" + rng[1:]
        raise _err(f"expected a number in {rng}, got {show_value(v)}", file, line, field)
    return float(v)


def check_int(v: Any, *, file: str | None = None, line: int | None = None,
              field: str | None = None, lo: int, hi: int) -> int:
    """A value from a TOML/JSON parser as an integer in ``[lo, hi]``."""
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
        raise _err(f"expected an integer in [{lo}, {hi}], got {show_value(v)}", file, line, field)
    return int(v)
