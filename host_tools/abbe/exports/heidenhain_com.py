"""``heidenhain-com``: Heidenhain nonlinear axis error compensation tables (*.COM + *.CMA).

Format (HEIDENHAIN technical manuals: TNC 407/415/425, TNC 426/430, iTNC 530,
MANUALplus 620, chapter "axis error compensation / nonlinear"): a ``*.COM``
table has a column ``AXISPOS`` (compensation points, machine datum), one column
per compensated axis (named as in CfgAxes) and optionally ``BACKLASH``; a
``*.CMA`` table assigns tables to axes: "[axis in a column of the *.COM] =
F(axis whose *.CMA column names the *.COM)", one line active (``*`` in
``ACTIVE``). Linear interpolation between points. At most 256 entries per
table (TNC 407 module 9095 error 3; the option ``points``). Tables are written
in the TNC table file layout (``BEGIN name``, column header, rows, ``[END]``).

Sign: the compensation value is the axis error (as for the linear compensation
MP720: "the error is positive if the table travel is too long"); the control
corrects by its negative.

BACKLASH (position-dependent reversal): "enter the compensation values measured
in the negative direction of traverse in the BACKLASH column" -- read here as
the change of the own axis' value when traversing in the negative direction:
value(moving -) = axis column + BACKLASH, value(moving +) = axis column, so
BACKLASH = e_-(p) - e_+(p) of the own axis, from :func:`terms.reversal_um`.

What it holds: per input axis one table with a column for every output axis:
everything that depends on one axis position alone, and the reversal. Not:
products with other axes' positions, thermal.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from abbe.exports.grids import choose_grid
from abbe.exports.target import (
    TABLE_MAX_POINTS,
    Context,
    Export,
    Option,
    Unheld,
    fmt,
    not_held,
)
from abbe.exports.terms import Item, has_reversal, line_error, own_error
from abbe.model.table import AXES

NAME = "heidenhain-com"
SUMMARY = "Heidenhain nonlinear compensation: one *.COM per input axis (+ BACKLASH), *.CMA"
DECIMALS = 5  # mm: 10 nm
POS_DECIMALS = 4
OPTIONS = {
    "points": Option("int", 256, "entries per *.COM table (older TNCs: 256)", lo=2,
                     hi=TABLE_MAX_POINTS),
    "axis_names": Option("axes", {"X": "X", "Y": "Y", "Z": "Z"}, "axis keys (CfgAxes)"),
}
SOURCES = ["HEIDENHAIN Technical Manual MANUALplus 620 (entering compensation values in *.COM: "
           "AXISPOS, BACKLASH, axis columns; *.CMA assignment, ACTIVE)",
           "HEIDENHAIN TNC 407/415/425 Technical Manual (nonlinear axis error compensation, "
           ".CMA/.COM, module 9095: at most 256 entries per table)",
           "HEIDENHAIN TNC 426/430 and iTNC 530 Technical Manuals (MP720 sign, MP710 backlash)"]


def _table_text(name: str, cols: list[str], rows: list[list[str]]) -> bytes:
    widths = [max(len(c), *(len(r[i]) for r in rows)) + 2 for i, c in enumerate(cols)]
    out = [f"BEGIN {name} MM", "".join(c.ljust(w) for c, w in zip(cols, widths)).rstrip()]
    out += ["".join(v.ljust(w) for v, w in zip(r, widths)).rstrip() for r in rows]
    out.append("[END]")
    return ("\n".join(out) + "\n").encode()


def build(ctx: Context) -> Export:
    limit = int(ctx.options["points"])
    names = ctx.options["axis_names"]
    files: dict[str, bytes] = {}
    tabs: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray | None]] = {}
    tables: list[dict[str, Any]] = []
    for a in AXES:
        j = AXES.index(a)
        lo, hi = ctx.volume.travel_mm[a]
        rev = has_reversal(ctx.table, a)

        def f(q: np.ndarray, a: str = a, j: int = j, rev: bool = rev) -> np.ndarray:
            v = line_error(ctx.table, a, q)
            if rev:  # own column = moving +; BACKLASH = moving - minus moving +
                up, dn = own_error(ctx.table, a, q, 1.0), own_error(ctx.table, a, q, -1.0)
                v[:, j] = up
                return np.column_stack([v, dn - up])
            return v

        g = choose_grid(lo, hi, f, limit, quantum_mm=10.0 ** -POS_DECIMALS)
        pos_txt = [fmt(v, POS_DECIMALS) for v in g.knots]
        k = np.array([float(v) for v in pos_txt])
        vals = f(k) * 1e-3
        txt = [[fmt(v, DECIMALS) for v in row] for row in vals]
        cols = ["NR", "AXISPOS"] + [names[b] for b in AXES] + (["BACKLASH"] if rev else [])
        rows = [[str(i), pos_txt[i]] + t for i, t in enumerate(txt)]
        fname = f"{names[a]}.COM"
        files[fname] = _table_text(fname, cols, rows)
        back = np.array([[float(v) for v in t] for t in txt])
        tabs[a] = (k, back[:, :3], back[:, 3] if rev else None)
        tables.append({"name": f"{fname}: X, Y, Z = f({a})" + (" + BACKLASH" if rev else ""),
                       **g.describe()})
    cma_cols = ["NR"] + [names[a] for a in AXES] + ["ACTIVE"]
    files["CONFIG.CMA"] = _table_text("CONFIG.CMA", cma_cols,
                                      [["0"] + [f"{names[a]}.COM" for a in AXES] + ["*"]])

    def correction(pos: np.ndarray, state: np.ndarray) -> np.ndarray:
        out = np.zeros_like(pos, dtype=np.float64)
        for i, a in enumerate(AXES):
            k, v, bl = tabs[a]
            for j in range(3):
                val = np.interp(pos[:, i], k, v[:, j])
                if j == i and bl is not None:
                    val = val + np.where(state[:, i] < 0, np.interp(pos[:, i], k, bl), 0.0)
                out[:, j] -= val * 1e3
        return out

    def cannot(item: Item) -> Unheld | None:
        if item.kind == "term" and item.part == "product":
            return Unheld("products with other axes' positions need more than one input")
        if item.kind == "thermal":
            return Unheld("no temperature input (the TNC's thermal compensation is separate)")
        return None

    return Export(
        target=NAME, files=files, correction=correction,
        expressed=[f"X, Y, Z = f({a}) (straightness, positioning, the single-axis Abbe and "
                   "squareness parts)" + (" with BACKLASH" if has_reversal(ctx.table, a) else "")
                   for a in AXES],
        not_held=not_held(ctx, cannot), tables=tables, direction="sign",
        notes=["own-axis column: the error moving +; BACKLASH: moving - minus moving +"],
        assumptions=["compensation values are errors (the control applies their negative)",
                     "BACKLASH is added to the own axis' value when traversing in the negative "
                     "direction (our reading of the manual)",
                     "AXISPOS is the model's machine coordinate (machine datum)"],
        sources=SOURCES)
