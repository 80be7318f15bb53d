"""Declared instrument columns: how a real export is written, from the machine file.

A ``[laser.A.columns]`` or ``[ballbar.N.columns]`` section (docs/formats.md,
"Declared instrument files") states the dialect (delimiter, decimal mark, lines
before the header, a units row, comment prefix, encoding) and, per abbe field
(``linear``, ``pitch``, ``angle``, ...), the file's column name, its unit and its
sign. :func:`parse_columns` validates such a section; :func:`plan_columns` turns
it and a file's header into the :class:`abbe.formats.delimited.Column` plan the
reader converts with (value in abbe's unit = sign x scale x cell).

Units accepted (case-insensitive; ``µ``/``μ`` may stand for ``u``; brackets in a
units row such as ``[mm]`` or ``(arcsec)`` are ignored):

=============  ==========================================================
position       mm, um, m, in  -> mm
linear         mm, um, nm     -> um
angular        urad, mrad, mm/m (= mrad), um/m (= urad), arcsec, deg -> urad
angle          deg, rad       -> deg (ballbar angle)
time           s, ms, min     -> s
temperature    C, degC        -> deg C
=============  ==========================================================
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field
from typing import Any, Callable

from abbe.errors import AbbeInputError
from abbe.formats.delimited import DELIMITERS, Column, Dialect, Header
from abbe.formats.text import ENCODINGS

UNITS: dict[str, dict[str, float]] = {
    "position": {"mm": 1.0, "um": 1e-3, "m": 1e3, "in": 25.4},
    "linear": {"mm": 1e3, "um": 1.0, "nm": 1e-3},
    "angular": {"urad": 1.0, "mrad": 1e3, "mm/m": 1e3, "um/m": 1.0,
                "arcsec": math.pi / 180.0 / 3600.0 * 1e6, "deg": math.pi / 180.0 * 1e6},
    "angle": {"deg": 1.0, "rad": 180.0 / math.pi},
    "time": {"s": 1.0, "ms": 1e-3, "min": 60.0},
    "temperature": {"c": 1.0, "degc": 1.0},
    "expansion": {"ppm/k": 1.0, "um/m/k": 1.0},
}
ABBE_UNIT = {"position": "mm", "linear": "um", "angular": "urad", "angle": "deg", "time": "s",
             "temperature": "C", "expansion": "ppm/K"}
#: Range of each quantity in abbe's unit, whatever the file's unit (docs/formats.md, "Limits").
RANGE = {"position": 1e5, "linear": 1e5, "angular": 1e5, "angle": 1e4, "time": 1e10,
         "temperature": 200.0, "expansion": 1000.0}


@dataclass(frozen=True)
class Role:
    """One abbe field of a file: default column name, quantity, required or not."""

    default: str
    quantity: str  # a key of UNITS, or "run" / "direction"
    required: bool = True


LASER_ROLES: dict[str, Role] = {
    "run": Role("run", "run"), "direction": Role("direction", "direction"),
    "target": Role("target_mm", "position"),
    "linear": Role("linear_um", "linear", False), "straight_h": Role("straight_h_um", "linear", False),
    "straight_v": Role("straight_v_um", "linear", False), "pitch": Role("pitch_urad", "angular", False),
    "yaw": Role("yaw_urad", "angular", False), "roll": Role("roll_urad", "angular", False),
    "time": Role("time_s", "time", False), "temp": Role("temp_c", "temperature", False),
    "expansion": Role("expansion_ppm_per_k", "expansion", False),
}
BALLBAR_ROLES: dict[str, Role] = {
    "direction": Role("direction", "direction"), "angle": Role("angle_deg", "angle"),
    "radial": Role("radial_um", "linear"), "time": Role("time_s", "time"),
    "temp": Role("temp_c", "temperature", False),
}
_DIALECT_KEYS = ("delimiter", "decimal", "skip_lines", "units_row", "comment", "encoding",
                 "direction_values")


@dataclass(frozen=True)
class ColumnDecl:
    """A declared field: the file's column name, its unit (None: units row or abbe's), sign."""

    column: str
    unit: str | None = None
    sign: float = 1.0


@dataclass(frozen=True)
class Columns:
    """A validated columns section: dialect, declared fields, how directions are written."""

    dialect: Dialect
    fields: dict[str, ColumnDecl] = field(default_factory=dict)
    direction_values: tuple[str, str] = ("+", "-")


def norm_unit(text: str) -> str:
    """A unit as written (``[µm]``, ``(arcsec)``, ``°C``) in its plain key form."""
    u = text.strip().strip("[]()").strip().lower()
    u = u.replace("µ", "u").replace("μ", "u").replace("°", "deg").replace(" ", "")
    return {"degdeg": "deg", "degc": "degc", "sec": "arcsec", '"': "arcsec", "''": "arcsec",
            "microrad": "urad", "micron": "um", "microns": "um"}.get(u, u)


def unit_scale(quantity: str, unit: str) -> float | None:
    """Factor to abbe's unit of ``quantity`` for ``unit``, or None if not one of its units."""
    return UNITS[quantity].get(norm_unit(unit))


def _suggest(name: str, options: list[str]) -> str:
    close = difflib.get_close_matches(name, options, n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def parse_columns(d: Any, roles: dict[str, Role], where: str,
                  err: Callable[[str, str], AbbeInputError],
                  default_dirs: tuple[str, str]) -> Columns:
    """Validate a columns section (a TOML table) against ``roles``; ``err(dotted, msg)``."""
    if not isinstance(d, dict):
        raise err(where, "expected a table [" + where + "]")
    keys = list(_DIALECT_KEYS) + list(roles)
    for k in d:
        if k not in keys:
            raise err(f"{where}.{k}", f"unknown key{_suggest(k, keys)}; expected one of "
                      f"{', '.join(keys)}")
    delim = d.get("delimiter", ",")
    if not isinstance(delim, str) or delim not in DELIMITERS:
        raise err(f"{where}.delimiter", "expected one of \",\", \";\", \"tab\", \"|\", "
                  f"\"whitespace\", got {delim!r}")
    dec = d.get("decimal", ".")
    if dec not in (".", ","):
        raise err(f"{where}.decimal", f"expected \".\" or \",\", got {dec!r}")
    if dec == "," and DELIMITERS[delim] == ",":
        raise err(f"{where}.decimal", "a decimal comma needs another delimiter (\";\", \"tab\" ...)")
    skip = d.get("skip_lines", 0)
    if isinstance(skip, bool) or not isinstance(skip, int) or not 0 <= skip <= 1000:
        raise err(f"{where}.skip_lines", f"expected an integer in [0, 1000], got {skip!r}")
    units_row = d.get("units_row", False)
    if not isinstance(units_row, bool):
        raise err(f"{where}.units_row", f"expected true or false, got {units_row!r}")
    comment = d.get("comment", "#")
    if not isinstance(comment, str) or len(comment) > 8:
        raise err(f"{where}.comment", f"expected a short string (\"\" = none), got {comment!r}")
    enc = d.get("encoding", "utf-8")
    if not isinstance(enc, str) or enc.lower().replace("_", "-") not in ENCODINGS:
        raise err(f"{where}.encoding", f"expected one of {', '.join(ENCODINGS)}, got {enc!r}")
    dv = d.get("direction_values", list(default_dirs))
    if (not isinstance(dv, list) or len(dv) != 2 or not all(isinstance(x, str) and x.strip() for x in dv)
            or dv[0].strip().lower() == dv[1].strip().lower()):
        raise err(f"{where}.direction_values", "expected two different strings, how the file "
                  f"writes {default_dirs[0]!r} and {default_dirs[1]!r}, got {dv!r}")
    fields: dict[str, ColumnDecl] = {}
    for role, spec in roles.items():
        if role not in d:
            continue
        f = f"{where}.{role}"
        v = d[role]
        if isinstance(v, str):
            v = {"column": v}
        if not isinstance(v, dict):
            raise err(f, "expected a column name or { column = \"...\", unit = \"...\", sign = -1 }")
        for k in v:
            if k not in ("column", "unit", "sign"):
                raise err(f"{f}.{k}", f"unknown key{_suggest(k, ['column', 'unit', 'sign'])}; "
                          "expected column, unit, sign")
        col = v.get("column")
        if not isinstance(col, str) or not col.strip():
            raise err(f"{f}.column", f"expected the column name as the file writes it, got {col!r}")
        unit = v.get("unit")
        if unit is not None:
            if spec.quantity not in UNITS:
                raise err(f"{f}.unit", f"the {role} column has no unit")
            if not isinstance(unit, str) or unit_scale(spec.quantity, unit) is None:
                raise err(f"{f}.unit", f"expected one of {', '.join(UNITS[spec.quantity])} "
                          f"({spec.quantity}), got {unit!r}")
        sign = v.get("sign", 1)
        if isinstance(sign, bool) or sign not in (1, -1):
            raise err(f"{f}.sign", f"expected 1 or -1, got {sign!r}")
        if sign == -1 and spec.quantity not in ("linear", "angular"):
            raise err(f"{f}.sign", "only readings (linear and angular channels) take a sign")
        fields[role] = ColumnDecl(col.strip(), unit, float(sign))
    dialect = Dialect(delimiter=DELIMITERS[delim], decimal=dec, skip_lines=skip,
                      units_row=units_row, comment=comment, encoding=enc)
    return Columns(dialect=dialect, fields=fields,
                   direction_values=(dv[0].strip(), dv[1].strip()))


def plan_columns(header: Header, roles: dict[str, Role], cols: Columns | None, *, file: str,
                 need: tuple[str, ...], strict_names: bool,
                 default_dirs: tuple[str, str]) -> dict[str, Column]:
    """Map the file's header to the reader's columns.

    ``cols`` None: abbe's own format (default names, abbe units; with
    ``strict_names`` every other column is an error with a suggestion). Otherwise
    the declared names (others ignored), units from the declaration, else the
    units row, else abbe's unit; signs applied. ``need``: roles that must be present.
    """
    names = header.names
    index: dict[str, int] = {}
    for i, n in enumerate(names):
        if n in index and n:
            raise AbbeInputError("duplicated column", file=file, line=header.line, field=n)
        index[n] = i
    decl = cols.fields if cols is not None else {}
    wanted = {role: (decl[role].column if role in decl else r.default) for role, r in roles.items()}
    if cols is None and strict_names:
        known = list(wanted.values())
        for n in names:
            if n not in known:
                raise AbbeInputError(f"unknown column{_suggest(n, known)}; expected columns "
                                     f"{', '.join(known)}", file=file, line=header.line, field=n)
    plan: dict[str, Column] = {}
    dirs = cols.direction_values if cols is not None else default_dirs
    for role, r in roles.items():
        name = wanted[role]
        if name not in index:
            if r.required or role in need:
                raise AbbeInputError(f"missing column {name!r}{_suggest(name, names)}", file=file,
                                     line=header.line, field=name)
            continue
        i = index[name]
        if r.quantity == "run":
            plan[role] = Column(name, i, kind="int", lo=1, hi=1_000_000)
            continue
        if r.quantity == "direction":
            a, b = dirs
            plan[role] = Column(name, i, kind="choice", choices={a.lower(): 0, b.lower(): 1},
                                expected=f"{a!r} or {b!r}")
            continue
        unit = ABBE_UNIT[r.quantity]
        scale = 1.0
        src = None
        if role in decl and decl[role].unit is not None:
            src = decl[role].unit
        elif header.units is not None and header.units[i].strip():
            src = header.units[i]
            if unit_scale(r.quantity, src) is None:
                raise AbbeInputError(f"unit {src!r} in the units row is not a {r.quantity} unit; "
                                     f"expected one of {', '.join(UNITS[r.quantity])}", file=file,
                                     line=header.units_line, field=name)
        if src is not None:
            scale = unit_scale(r.quantity, src)  # type: ignore[assignment]
            if (role in decl and decl[role].unit is not None and header.units is not None
                    and header.units[i].strip()):
                row = unit_scale(r.quantity, header.units[i])
                if row is not None and row != scale:
                    raise AbbeInputError(
                        f"the units row says {header.units[i]!r} but the machine file declares "
                        f"{decl[role].unit!r}", file=file, line=header.units_line, field=name)
        if role in decl:
            scale *= decl[role].sign
        lim = RANGE[r.quantity]
        plan[role] = Column(name, i, kind="number", lo=-lim, hi=lim, unit=unit, scale=scale)
    return plan
