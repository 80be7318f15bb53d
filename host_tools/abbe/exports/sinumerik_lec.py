"""``sinumerik-lec``: Siemens Sinumerik leadscrew / measuring system error compensation.

Format (SINUMERIK function manual "Extended functions", K3 Compensations,
interpolatory compensation; example %_N_AX_EEC_INI): a part program
``%_N_AX_EEC_INI`` / ``CHANDATA(1)`` with, per machine axis AXi and measuring
system e = 0, ``$AA_ENC_COMP[0,N,AXi]=value`` (mm) for interpolation points
N = 0..k, ``$AA_ENC_COMP_STEP[0,AXi]`` (spacing, mm), ``_MIN`` (position of
point 0), ``_MAX`` (position of point k = MIN + k STEP), ``_IS_MODULO``, ending
``M17``. Linear interpolation between points; the first and last values are
held outside. At most MD38000 $MA_MM_ENC_COMP_MAX_POINTS points per axis (set
on the control; the 808D manual gives 200, the 840D sl example 801). The table
can only be loaded while MD32700 ENC_COMP_ENABLE = 0.

Sign: "A positive compensation value causes the corresponding machine axis to
move in the negative direction" (808D function manual, LEC): the value is the
axis' error (actual - nominal), and the correction is its negative.

What it holds: each axis' own positioning error on its line through the
reference point, the mean of both directions: LEC is not direction dependent.
The reversal belongs in the backlash machine data MD32450 $MA_BACKLASH (not in
this file; reported as not held, with the value to enter).
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
from abbe.exports.terms import (
    Item,
    has_reversal,
    own_error,
    reversal_range_note,
    reversal_um,
)
from abbe.model.table import AXES, OWN_SIGN

NAME = "sinumerik-lec"
SUMMARY = "Siemens Sinumerik LEC: %_N_AX_EEC_INI with $AA_ENC_COMP per axis"
DECIMALS = 6  # mm: 1 nm
POS_DECIMALS = 4
OPTIONS = {
    "points": Option("int", 200, "interpolation points per axis (MD38000 "
                     "$MA_MM_ENC_COMP_MAX_POINTS of the control)", lo=2, hi=TABLE_MAX_POINTS),
    "axis_names": Option("axes", {"X": "X1", "Y": "Y1", "Z": "Z1"}, "machine axis names"),
}
SOURCES = ["SINUMERIK function manual Extended functions, K3 Compensations: interpolatory "
           "compensation, LEC/MSEC table parameters and the %_N_AX_EEC_INI example",
           "SINUMERIK 808D function manual, LEC: sign of the compensation value, 200 points"]


def round_grid(lo: float, step: float, n: int) -> tuple[np.ndarray, str, str, str]:
    """Knots as written: MIN, STEP text and MAX = MIN + (n - 1) STEP (all as parsed back)."""
    t_min, t_step = fmt(lo, POS_DECIMALS), fmt(step, POS_DECIMALS)
    k = float(t_min) + float(t_step) * np.arange(n)
    t_max = fmt(float(k[-1]), POS_DECIMALS)
    return k, t_min, t_step, t_max


def build(ctx: Context) -> Export:
    limit = int(ctx.options["points"])
    names = ctx.options["axis_names"]
    lines = ["%_N_AX_EEC_INI", "CHANDATA(1)",
             "; abbe export sinumerik-lec: value = axis error (mm); the axis moves by -value"]
    tabs: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    tables: list[dict[str, Any]] = []
    notes = []
    for a in AXES:
        lo, hi = ctx.volume.travel_mm[a]

        def err_um(q: np.ndarray, a: str = a) -> np.ndarray:
            return own_error(ctx.table, a, q, 0.0)

        # MIN + k STEP = MAX exactly in the written decimals.
        g = choose_grid(lo, hi, err_um, limit, quantum_mm=10.0 ** -POS_DECIMALS)
        step = float(fmt(g.spacing_mm, POS_DECIMALS))
        n = g.points
        k, t_min, t_step, t_max = round_grid(lo, step, n)
        vals = [fmt(v * 1e-3, DECIMALS) for v in err_um(k)]
        ax = names[a]
        lines += [f"$AA_ENC_COMP[0,{i},{ax}]={v}" for i, v in enumerate(vals)]
        lines += [f"$AA_ENC_COMP_STEP[0,{ax}]={t_step}", f"$AA_ENC_COMP_MIN[0,{ax}]={t_min}",
                  f"$AA_ENC_COMP_MAX[0,{ax}]={t_max}", f"$AA_ENC_COMP_IS_MODULO[0,{ax}]=0"]
        tabs[a] = (k, np.array([float(v) for v in vals]))
        tables.append({"name": f"$AA_ENC_COMP {ax} (axis {a})", **g.describe()})
        if has_reversal(ctx.table, a):
            R = reversal_um(ctx.table, a, np.linspace(lo, hi, 101))
            B = float(np.mean(R))
            notes.append(f"{ax}: backlash for MD32450 $MA_BACKLASH: |reversal| = {abs(B):.2f} um "
                         f"(model reversal B = {B:.3f} um, error moving + minus moving -: "
                         f"{OWN_SIGN[a] * B:+.3f} um along {a})" + reversal_range_note(R))
    lines.append("M17")

    def correction(pos: np.ndarray, state: np.ndarray) -> np.ndarray:
        out = np.zeros_like(pos, dtype=np.float64)
        for j, a in enumerate(AXES):
            k, v = tabs[a]
            out[:, j] = -np.interp(pos[:, j], k, v) * 1e3
        return out

    def cannot(item: Item) -> Unheld | None:
        if item.kind == "term" and item.part == "single":
            return Unheld("LEC corrects an axis from its own position only",
                          "".join(b for b in AXES if b != item.axis))
        if item.kind == "term":
            return Unheld("products with other axes' positions need more than one input")
        if item.kind == "squareness":
            return Unheld("cross-axis: use sinumerik-cec")
        if item.kind == "backlash":
            return Unheld("LEC is not direction dependent: enter the backlash in MD32450")
        return Unheld("no temperature input (Sinumerik has its own temperature compensation)")

    return Export(
        target=NAME, files={"EEC.INI": ("\n".join(lines) + "\n").encode()}, correction=correction,
        expressed=[f"{a} positioning along its own line, mean of both directions" for a in AXES],
        not_held=not_held(ctx, cannot), tables=tables, direction="none", notes=notes,
        assumptions=["machine axis positions are the model's machine coordinates (mm)"],
        sources=SOURCES)
