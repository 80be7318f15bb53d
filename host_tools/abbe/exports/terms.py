"""The model as a controller sees it: per-axis functions, the reversal, named parts.

Everything here is evaluated through the float64 reference
(:mod:`abbe.model.reference`): term values, backlash and Eq. 3 itself.

* :func:`model_error`: (dX, dY, dZ) at any points, = ``reference.spatial_error``
  (term values computed once per distinct coordinate, so product grids are cheap).
* :func:`line_error`: the error along the line through the reference point
  parallel to one axis (the other axes at the reference). On that line every
  Abbe product of an angular error with *another* axis' position vanishes, so
  component k of it is exactly the part of dk that depends on that axis alone:
  what a one-input compensation table (input axis -> output axis) can hold.
* :func:`reversal_um`: the model's reversal B(p) of an axis' own positioning
  term (ISO 230-2: mean + approach minus mean - approach), um: ``backlash_um``
  plus the axis' reversal block (format 1.1, position dependent;
  ``abbe.model.reference.reversal_values``). Every forward/reverse, BACKLASH,
  direction-table and bidirectional-pitch column takes it from here.
* :func:`items` / :func:`contribution`: the model split into named parts (each
  term's single-axis part and its products with other axes' positions,
  squareness, backlash, thermal) for the "what the target cannot hold" report.

Units: positions mm; errors um; angles urad.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from abbe.model.reference import combine_eq3, extra_values, reversal_values, term_values
from abbe.model.table import AXES, OWN_SIGN, OWN_TERM, TERMS, AxisTable, Table

ROLE = {"dx": "d_x", "dy": "d_y", "dz": "d_z", "ex": "eps_{a}x", "ey": "eps_{a}y",
        "ez": "eps_{a}z"}
SQUARENESS = ("S_xy", "S_xz", "S_yz")


def model_error(table: Table, pos_mm: np.ndarray, dir_state: np.ndarray | None = None,
                temp_c: np.ndarray | None = None) -> np.ndarray:
    """(N, 3) um: ``reference.spatial_error`` evaluated with the term values computed once
    per distinct axis coordinate. ``dir_state`` / ``temp_c`` (N, 3) or None."""
    pos = np.asarray(pos_mm, dtype=np.float64).reshape(-1, 3)
    n = pos.shape[0]
    ds = None if dir_state is None else np.broadcast_to(
        np.asarray(dir_state, dtype=np.float64).reshape(-1, 3), (n, 3))
    tc = None if temp_c is None else np.broadcast_to(
        np.asarray(temp_c, dtype=np.float64).reshape(-1, 3), (n, 3))
    e: dict[tuple[str, str], np.ndarray] = {}
    for j, a in enumerate(AXES):
        u, inv = np.unique(pos[:, j], return_inverse=True)
        for t in TERMS:
            e[(a, t)] = term_values(table, a, t, u)[inv]
        own = OWN_TERM[a]
        e[(a, own)] = e[(a, own)] + extra_values(
            table, a, pos[:, j], None if ds is None else ds[:, j],
            None if tc is None else tc[:, j])
    return combine_eq3(e, pos, table.reference_mm, table.tool_offset_mm, table.squareness_urad)


def line_positions(table: Table, axis: str, q_mm: np.ndarray) -> np.ndarray:
    """(N, 3) points on the line through the reference point along ``axis``."""
    q = np.asarray(q_mm, dtype=np.float64).reshape(-1)
    pos = np.tile(np.asarray(table.reference_mm, dtype=np.float64), (q.size, 1))
    pos[:, AXES.index(axis)] = q
    return pos


def line_error(table: Table, axis: str, q_mm: np.ndarray, s: float | np.ndarray = 0.0) -> np.ndarray:
    """(N, 3) um: the model error on the line along ``axis`` through the reference point,
    with direction state ``s`` of that axis (the other axes at rest, state 0)."""
    pos = line_positions(table, axis, q_mm)
    ds = np.zeros_like(pos)
    ds[:, AXES.index(axis)] = s
    return model_error(table, pos, ds)


def reversal_um(table: Table, axis: str, q_mm: np.ndarray) -> np.ndarray:
    """The reversal B(q) of ``axis``' own positioning term at positions ``q_mm`` (mm),
    um: the constant ``backlash_um`` plus the reversal block (module docstring)."""
    return reversal_values(table, axis, q_mm)


def reversal_range_note(r_um: np.ndarray) -> str:
    """For a target that takes one backlash value (the mean of B(q)): how far B(q)
    ranges along the travel, or "" for a constant reversal."""
    lo, hi = float(np.min(r_um)), float(np.max(r_um))
    if hi - lo < 1e-3:
        return ""
    return (f"; the mean of a position-dependent reversal, which ranges {lo:.3f} .. "
            f"{hi:.3f} um along the travel")


def own_error(table: Table, axis: str, q_mm: np.ndarray, s: float) -> np.ndarray:
    """(N,) um: the error along ``axis`` itself on its line, moving with state ``s``
    (+1 moving +, -1 moving -, 0 the mean of both): mean + OWN_SIGN s B(q) / 2."""
    j = AXES.index(axis)
    mean = line_error(table, axis, q_mm, 0.0)[:, j]
    return mean + OWN_SIGN[axis] * s * 0.5 * reversal_um(table, axis, q_mm)


def has_reversal(table: Table, axis: str) -> bool:
    """True if the model's reversal of ``axis`` is not zero anywhere on its travel."""
    lo, hi = table.axes[axis].travel_mm
    return bool(np.any(reversal_um(table, axis, np.linspace(lo, hi, 33)) != 0.0))


# --- named parts of the model ---------------------------------------------------------

@dataclass(frozen=True)
class Item:
    """A named part of the model.

    kind: "term" (a fitted term; part "single" = what depends on its own axis alone,
    "product" = its products with the other axes' positions, Abbe lever arms),
    "squareness" (name in SQUARENESS), "backlash" (axis), "thermal" (axis; size per
    kelvin).
    """

    kind: str
    axis: str = ""
    term: str = ""
    part: str = ""
    name: str = ""

    @property
    def label(self) -> str:
        if self.kind == "term":
            sym = ROLE[self.term].format(a=self.axis.lower())
            what = f"{self.axis} {self.term} ({sym}({self.axis.lower()}))"
            if self.part == "single":
                return f"{what}, the part that depends on {self.axis.lower()} alone"
            others = ", ".join(b.lower() for b in AXES if b != self.axis)
            return f"{what} times the other axes' positions ({others}; Abbe lever arms)"
        if self.kind == "squareness":
            return f"squareness {self.name}"
        if self.kind == "backlash":
            return f"{self.axis} backlash / reversal of its positioning"
        return f"{self.axis} thermal terms (per kelvin from T_ref)"


def _only(table: Table, axis: str | None = None, term: str | None = None,
          squareness: int | None = None, backlash: str | None = None,
          thermal: str | None = None) -> Table:
    """A copy of ``table`` holding just one thing (the others zero)."""
    axes = {}
    for a in AXES:
        src = table.axes[a]
        ax = AxisTable(travel_mm=src.travel_mm, trend_degree=src.trend_degree,
                       blocks=copy.deepcopy(src.blocks))
        if a == axis and term in src.coef:
            ax.coef[term] = np.array(src.coef[term], dtype=np.float64)
        if a == backlash:
            ax.backlash_um, ax.backlash_takeup_mm = src.backlash_um, src.backlash_takeup_mm
            ax.reversal_cheb_um = src.reversal_cheb_um
        if a == thermal:
            ax.thermal_expansion_ppm_per_k = src.thermal_expansion_ppm_per_k
            ax.thermal_offset_um_per_k = src.thermal_offset_um_per_k
            ax.thermal_tref_c = src.thermal_tref_c
        axes[a] = ax
    sq = [0.0, 0.0, 0.0]
    if squareness is not None:
        sq[squareness] = float(table.squareness_urad[squareness])
    return Table(axes=axes, reference_mm=table.reference_mm, tool_offset_mm=table.tool_offset_mm,
                 squareness_urad=(sq[0], sq[1], sq[2]))


def items(table: Table) -> list[Item]:
    """Every non-zero part of the model."""
    out: list[Item] = []
    for a in AXES:
        ax = table.axes[a]
        for t in ax.present_terms():
            if not np.any(np.asarray(ax.coef[t]) != 0):
                continue
            out.append(Item("term", a, t, "single"))
            out.append(Item("term", a, t, "product"))
    for k, name in enumerate(SQUARENESS):
        if table.squareness_urad[k] != 0:
            out.append(Item("squareness", name=name))
    for a in AXES:
        if has_reversal(table, a):
            out.append(Item("backlash", a))
        ax = table.axes[a]
        if ax.thermal_expansion_ppm_per_k or ax.thermal_offset_um_per_k:
            out.append(Item("thermal", a))
    return out


def contribution(table: Table, item: Item, pos_mm: np.ndarray, s: float = 1.0) -> np.ndarray:
    """(N, 3) um: what ``item`` adds to (dX, dY, dZ) at the points (backlash with all
    axes in state ``s``; thermal at T_ref + 1 K)."""
    pos = np.asarray(pos_mm, dtype=np.float64).reshape(-1, 3)
    if item.kind == "term":
        only = _only(table, axis=item.axis, term=item.term)
        j = AXES.index(item.axis)
        single = model_error(only, line_positions(table, item.axis, pos[:, j]))
        if item.part == "single":
            return single
        return model_error(only, pos) - single
    if item.kind == "squareness":
        return model_error(_only(table, squareness=SQUARENESS.index(item.name)), pos)
    if item.kind == "backlash":
        j = AXES.index(item.axis)
        out = np.zeros_like(pos)
        out[:, j] = OWN_SIGN[item.axis] * s * 0.5 * reversal_um(table, item.axis, pos[:, j])
        return out
    only = _only(table, thermal=item.axis)
    t = np.full(pos.shape, table.axes[item.axis].thermal_tref_c + 1.0)
    return model_error(only, pos, None, t)
