"""``sinumerik-cec``: Siemens Sinumerik sag / angularity compensation tables (CEC).

Format (SINUMERIK function manual "Extended functions", K3 Compensations, sag
and angularity error compensation; example %_N_NC_CEC_INI): ``%_N_NC_CEC_INI`` /
``CHANDATA(1)``; per table t: ``$AN_CEC[t,N]=value`` (mm) for N = 0..k,
``$AN_CEC_INPUT_AXIS[t]=(AXi)`` (base axis, its setpoint is the input),
``$AN_CEC_OUTPUT_AXIS[t]=(AXj)`` (compensation axis), ``$AN_CEC_STEP[t]``,
``$AN_CEC_MIN[t]``, ``$AN_CEC_MAX[t]`` (mm; first and last value held outside),
``$AN_CEC_DIRECTION[t]`` (0 both, 1 only moving +, -1 only moving -),
``$AN_CEC_MULT_BY_TABLE[t]``, ``$AN_CEC_IS_MODULO[t]``; ``M17``. Linear
interpolation; the values of all tables of one output axis add. Points per table:
MD18342 $MN_MM_CEC_MAX_POINTS[t]; an 828D has 8 tables of 200 points that
cannot be extended (the defaults here).

Sign: as LEC (the value is the output axis' error; the axis moves by -value).
The manual's sign statement is for LEC; that CEC shares it is our reading of the
common "interpolatory compensation" -- check one table on the machine.

What it holds: every part of the model that depends on one axis position alone:
for input X and output Y, the error dY on the X line through the reference point
(straightness, x eps_xz, squareness slopes, own positioning for input = output),
one table each; the reversal as a pair of direction-dependent tables of the own
axis. With more candidate tables than the limit, the largest (RMS over the travel)
are kept and the rest named. Products of an angular error with another axis'
position are not held (the multiplication of tables adds the product to a table
that itself applies, so it cannot represent them alone).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from abbe.errors import AbbeInputError
from abbe.exports.grids import choose_grid
from abbe.exports.sinumerik_lec import POS_DECIMALS, round_grid
from abbe.exports.target import (
    TABLE_MAX_POINTS,
    Context,
    Export,
    Option,
    Unheld,
    fmt,
    not_held,
)
from abbe.exports.terms import Item, has_reversal, line_error, own_error, reversal_um
from abbe.model.table import AXES

NAME = "sinumerik-cec"
SUMMARY = "Siemens Sinumerik CEC: %_N_NC_CEC_INI with $AN_CEC input -> output tables"
DECIMALS = 6
OPTIONS = {
    "tables": Option("int", 8, "number of compensation tables (828D: 8)", lo=1, hi=128),
    "points": Option("int", 200, "points per table (MD18342; 828D: 200)", lo=2,
                     hi=TABLE_MAX_POINTS),
    "axis_names": Option("axes", {"X": "X1", "Y": "Y1", "Z": "Z1"}, "machine axis names"),
    "own": Option("str", "cec", "own-axis tables: 'cec' (here) or 'lec' (left to sinumerik-lec)",
                  choices=("cec", "lec")),
}
SOURCES = ["SINUMERIK function manual Extended functions, K3 Compensations: sag and angularity "
           "compensation, $AN_CEC* table parameters, %_N_NC_CEC_INI example, direction-dependent "
           "tables, MD18342; 828D: 8 tables x 200 points"]


@dataclass
class Candidate:
    inp: str
    out: str
    direction: int  # 0, +1, -1
    benefit: float  # RMS over the travel, um


def _function(ctx: Context, c: Candidate):
    j = AXES.index(c.out)

    def f(q: np.ndarray) -> np.ndarray:
        if c.inp == c.out:
            return own_error(ctx.table, c.inp, q, float(c.direction))
        return line_error(ctx.table, c.inp, q)[:, j]
    return f


def candidates(ctx: Context) -> tuple[list[Candidate], list[Candidate]]:
    """All useful tables, ranked; and the directional pairs for own axes with a reversal.

    Returns (tables, pairs): a pair (moving + and moving -) replaces the
    bidirectional own table of its axis.
    """
    cands, pairs = [], []
    own = ctx.options["own"] == "cec"
    for a in AXES:
        lo, hi = ctx.volume.travel_mm[a]
        q = np.linspace(lo, hi, 401)
        for b in AXES:
            if a == b and not own:
                continue
            c = Candidate(a, b, 0, 0.0)
            v = _function(ctx, c)(q)
            c.benefit = float(np.sqrt(np.mean(v ** 2)))
            if c.benefit > 1e-4:
                cands.append(c)
            if a == b and has_reversal(ctx.table, a):
                up = _function(ctx, Candidate(a, a, +1, 0.0))(q)
                dn = _function(ctx, Candidate(a, a, -1, 0.0))(q)
                pairs.append(Candidate(a, a, +1, float(np.sqrt(np.mean(up ** 2)))))
                pairs.append(Candidate(a, a, -1, float(np.sqrt(np.mean(dn ** 2)))))
    return sorted(cands, key=lambda c: -c.benefit), pairs


def select(ctx: Context, limit: int) -> tuple[list[Candidate], list[Candidate]]:
    """Tables within the limit, greedily by benefit (RMS over the travel): a bidirectional
    table costs one table; turning an own-axis table into its direction pair costs one
    more and gains the reversal (RMS of |B(q)| / 2); a reversal that outranks its base
    table brings the base along (two tables for the pair at once)."""
    cands, pairs = candidates(ctx)
    upgrades = {a: [p for p in pairs if p.inp == a] for a in {p.inp for p in pairs}}
    units = [("table", c, c.benefit) for c in cands]
    for a in upgrades:
        lo, hi = ctx.volume.travel_mm[a]
        b = float(np.sqrt(np.mean((0.5 * reversal_um(ctx.table, a, np.linspace(lo, hi, 101))) ** 2)))
        units.append(("pair", a, b))
    chosen: list[Candidate] = []
    dropped: list[Candidate] = []
    paired: set[str] = set()
    for kind, obj, _ in sorted(units, key=lambda u: -u[2]):
        if kind == "table":
            if obj.inp == obj.out and obj.inp in paired:
                continue  # its direction pair came first (a reversal larger than the mean)
            (chosen if len(chosen) < limit else dropped).append(obj)
            continue
        base = next((c for c in chosen if c.inp == obj and c.out == obj and not c.direction), None)
        if base is not None and len(chosen) < limit:
            chosen.remove(base)
            chosen += upgrades[obj]
            paired.add(obj)
        elif base is None and any(c.inp == obj and c.out == obj for c in cands) \
                and len(chosen) + 2 <= limit:
            # the pair holds the base table's mean as well: take both tables now
            chosen += upgrades[obj]
            paired.add(obj)
    return chosen, dropped


def build(ctx: Context) -> Export:
    limit_t, limit_p = int(ctx.options["tables"]), int(ctx.options["points"])
    names = ctx.options["axis_names"]
    chosen, dropped = select(ctx, limit_t)
    if not chosen:
        raise AbbeInputError("the model has no single-axis part for a CEC table", field="model")
    lines = ["%_N_NC_CEC_INI", "CHANDATA(1)",
             "; abbe export sinumerik-cec: value = error of the output axis (mm); "
             "it moves by -value"]
    tabs: list[tuple[Candidate, np.ndarray, np.ndarray]] = []
    tables: list[dict[str, Any]] = []
    for t, c in enumerate(chosen):
        lo, hi = ctx.volume.travel_mm[c.inp]
        f = _function(ctx, c)
        g = choose_grid(lo, hi, f, limit_p, quantum_mm=10.0 ** -POS_DECIMALS)
        k, t_min, t_step, t_max = round_grid(lo, float(fmt(g.spacing_mm, POS_DECIMALS)), g.points)
        vals = [fmt(v * 1e-3, DECIMALS) for v in f(k)]
        lines += [f"$AN_CEC[{t},{i}]={v}" for i, v in enumerate(vals)]
        lines += [f"$AN_CEC_INPUT_AXIS[{t}]=({names[c.inp]})",
                  f"$AN_CEC_OUTPUT_AXIS[{t}]=({names[c.out]})",
                  f"$AN_CEC_STEP[{t}]={t_step}", f"$AN_CEC_MIN[{t}]={t_min}",
                  f"$AN_CEC_MAX[{t}]={t_max}", f"$AN_CEC_DIRECTION[{t}]={c.direction}",
                  f"$AN_CEC_MULT_BY_TABLE[{t}]=0", f"$AN_CEC_IS_MODULO[{t}]=0"]
        tabs.append((c, k, np.array([float(v) for v in vals])))
        d = {0: "both directions", 1: "moving +", -1: "moving -"}[c.direction]
        tables.append({"name": f"table {t}: {c.out} = f({c.inp}), {d}", "rms_um": round(c.benefit, 4),
                       **g.describe()})
    lines.append("M17")

    def correction(pos: np.ndarray, state: np.ndarray) -> np.ndarray:
        out = np.zeros_like(pos, dtype=np.float64)
        for c, k, v in tabs:
            i, j = AXES.index(c.inp), AXES.index(c.out)
            val = np.interp(pos[:, i], k, v) * 1e3
            if c.direction:
                val = np.where(np.sign(state[:, i]) == c.direction, val, 0.0)
            out[:, j] -= val
        return out

    held = {(c.inp, c.out) for c in chosen}
    held_dir = {c.inp for c in chosen if c.direction}
    drop_txt = {(c.inp, c.out) for c in dropped}

    def cannot(item: Item) -> Unheld | None:
        if item.kind == "term" and item.part == "single":
            miss = "".join(b for b in AXES if (item.axis, b) not in held)
            if not miss:
                return None
            why = ("beyond the table limit" if any((item.axis, b) in drop_txt for b in miss)
                   else "not tabulated")
            return Unheld(f"{why}: no table {item.axis} -> {', '.join(miss)}", miss)
        if item.kind == "term":
            return Unheld("products with other axes' positions need more than one input")
        if item.kind == "squareness":
            inp = {"S_xy": ("Y", "X"), "S_xz": ("Z", "X"), "S_yz": ("Z", "Y")}[item.name]
            return None if inp in held else Unheld(f"no table {inp[0]} -> {inp[1]}", inp[1])
        if item.kind == "backlash":
            return None if item.axis in held_dir else Unheld(
                "no table left for the direction-dependent pair" if ctx.options["own"] == "cec"
                else "own-axis tables left to sinumerik-lec (backlash: MD32450)")
        return Unheld("no temperature input")

    notes = [f"{len(chosen)} of {limit_t} tables used"]
    if dropped:
        notes.append("dropped for the table limit: " + ", ".join(
            f"{c.out} = f({c.inp}) ({c.benefit:.3f} um RMS)" for c in dropped))
    return Export(
        target=NAME, files={"CEC.INI": ("\n".join(lines) + "\n").encode()}, correction=correction,
        expressed=[f"{c.out} = f({c.inp})" + ({1: " moving +", -1: " moving -"}.get(c.direction, ""))
                   for c in chosen],
        not_held=not_held(ctx, cannot), tables=tables, direction="sign", notes=notes,
        assumptions=["CEC values have the sign of LEC values (error; the axis moves by -value)",
                     "machine axis positions are the model's machine coordinates (mm)"],
        sources=SOURCES)
