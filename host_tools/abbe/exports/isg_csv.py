"""``isg-csv``: Beckhoff TwinCAT CNC TF5280 volumetric compensation (ISG CSV + list file).

Format (Beckhoff Information System, TF5280 Volumetric Compensation: "ISG CSV
format", "List of parameters supported", "Units of measure", "General
configuration"; TF5200 parameters P-VOLC-00001..00020): a table whose header
names arguments (X, Y, Z: axis values in mm) and error parameters (ISO 230-1
names), one record per row, ``//`` comments, ``#`` starts a new block with its
own header; values in mm (offsets) and rad (angles). Component errors E<d><j>:
error in direction d (X, Y, Z translation; A, B, C rotation about x, y, z) of
axis j; position (location) errors like ``C0Y``. The list file (``.lis``) names
the logical axes (``x 1`` ...), the kinematic chain (``chain``), the number of
workpiece axes (``workpiece_axes``), the interpolation (``interpolation GRID``:
linear on a grid) and up to 10 files (``file[j]``, ``file_format[j] ISG_CSV``).
The startup list bounds the records (``vol_comp[i].max_records``; the option
``max_records``).

Layouts (``--set layout=``):

* ``components`` (default): the 18 component errors as 1D tables, one block per
  axis (``X EXX EYX EZX EAX EBX ECX``...), and the squareness as location errors
  ``C0Y`` = S_xy, ``B0Z`` = -S_xz, ``A0Z`` = S_yz (the rotation of the Y / Z
  axis line about z / y / x that paper Table 3's d_x(y) - y S_xy, d_x(z) - z S_xz,
  d_y(z) - z S_yz describe). Name mapping one to one: E<D><J> = abbe's term of
  axis J in direction D (EXX = dx of X, EAX = ex of X = eps_xx, ...). Lever arms
  about the machine origin: the abbe terms are relative to the reference point,
  so each axis' angular errors times the reference point's coordinates are folded
  into that axis' translation columns (a function of that axis alone). Chain
  ``XYZ``, ``workpiece_axes 2`` (the VMC's X table on the Y carriage carries the
  workpiece, Z carries the tool).
* ``grid``: the full model error as a 3D map ``X Y Z EXX EYY EZZ`` (the tool's
  translation error as if every axis were on the tool side, ``workpiece_axes
  0``), trilinear on the grid. It depends on no kinematic convention; the
  records limit makes it coarse.

The reconstruction uses abbe's Eq. 3 (``reference.combine_eq3``) on the
interpolated columns: that TF5280 composes the ISO 230-1 errors of this chain
the same way is the assumption of the components layout (ISG's kinematic
equations, [FCT-C26], were not available to check). Not held: the reversal
(no direction argument; TwinCAT has backlash compensation per axis), thermal.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.interpolate import RegularGridInterpolator

from abbe.errors import AbbeInputError
from abbe.exports.grids import choose_grid
from abbe.exports.target import Context, Export, Option, Unheld, fmt, not_held
from abbe.exports.terms import (
    Item,
    has_reversal,
    model_error,
    reversal_range_note,
    reversal_um,
)
from abbe.formats.limits import COMPONENT_FILE_MAX_RECORDS
from abbe.model.reference import combine_eq3, term_values
from abbe.model.table import AXES, LINEAR_TERMS, OWN_SIGN, TERMS

NAME = "isg-csv"
SUMMARY = "Beckhoff TwinCAT TF5280 volumetric compensation: ISG CSV (ISO 230-1 names) + .lis"
MM_DECIMALS = 9  # 1 pm
RAD_DECIMALS = 12  # 1e-6 urad
POS_DECIMALS = 4
#: abbe term -> the direction letter of its ISO 230-1 name.
DIRECTION = {"dx": "X", "dy": "Y", "dz": "Z", "ex": "A", "ey": "B", "ez": "C"}
#: location error name -> (index into squareness_urad, sign): value = sign * S.
LOCATION = {"C0Y": (0, 1.0), "B0Z": (1, -1.0), "A0Z": (2, 1.0)}
#: sign with which each axis' linear terms enter Eq. 3 (workpiece side -1, tool side +1)
SIDE = {"X": -1.0, "Y": -1.0, "Z": 1.0}
OPTIONS = {
    "layout": Option("str", "components", "components (ISO 230-1 per axis) or grid (3D map)",
                     choices=("components", "grid")),
    "max_records": Option("int", 2000, "records the control reads (vol_comp[i].max_records)",
                          lo=8, hi=COMPONENT_FILE_MAX_RECORDS),
    "logical_axes": Option("axes", {"X": "1", "Y": "2", "Z": "3"}, "logical axis numbers",
                           item="int", lo=1, hi=65535),
    "file": Option("str", "volcomp.csv", "name of the error parameter file (in OUT)",
                   pattern=r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,63}"),
}
SOURCES = ["Beckhoff TF5280 Volumetric Compensation: ISG CSV format, List of parameters "
           "supported, Units of measure, General configuration, Updating (example .lis / .csv)",
           "Beckhoff TF5200 volumetric compensation parameters P-VOLC-00001..00007 (x, y, z, "
           "chain), P-VOLC-00012..00014 (file[j], file_format[j], interpolation GRID)"]


def iso_name(axis: str, term: str) -> str:
    return f"E{DIRECTION[term]}{axis}"


def folded_terms(ctx: Context, axis: str, q: np.ndarray) -> dict[str, np.ndarray]:
    """abbe's six terms of ``axis`` at positions q (um / urad) with the lever arms moved
    from the reference point to the machine origin (module docstring)."""
    t = ctx.table
    e = {term: term_values(t, axis, term, q) for term in TERMS}
    ref = np.asarray(t.reference_mm, dtype=np.float64)
    ang = {(axis, k): e[k] for k in ("ex", "ey", "ez")}
    n = q.size
    at0 = combine_eq3(ang, np.zeros((n, 3)), ref, t.tool_offset_mm, (0.0, 0.0, 0.0))
    atr = combine_eq3(ang, np.tile(ref, (n, 1)), ref, t.tool_offset_mm, (0.0, 0.0, 0.0))
    delta = at0 - atr  # the lever arm -ref times the angular errors, um per component
    for k, term in enumerate(LINEAR_TERMS):
        e[term] = e[term] + delta[:, k] / SIDE[axis]
    return e


def _components(ctx: Context) -> Export:
    budget = int(ctx.options["max_records"]) - 1
    per_axis = budget // 3
    if per_axis < 2:
        raise AbbeInputError("too few records for three axis tables", field="--set max_records")
    blocks = ["// abbe export isg-csv (components): ISO 230-1 component errors, mm and rad;",
              "// lever arms about the machine origin; location errors from the squareness",
              " ".join(LOCATION),
              " ".join(fmt(sign * ctx.table.squareness_urad[i] * 1e-6, RAD_DECIMALS)
                       for i, sign in LOCATION.values())]
    cols: dict[str, tuple[np.ndarray, dict[str, np.ndarray]]] = {}
    tables: list[dict[str, Any]] = []
    for a in AXES:
        lo, hi = ctx.volume.travel_mm[a]

        def f(q: np.ndarray, a: str = a) -> np.ndarray:
            e = folded_terms(ctx, a, q)
            # interpolation error of the angular columns in um at a 500 mm lever arm
            return np.column_stack([e[t] * (1.0 if t in LINEAR_TERMS else 0.5) for t in TERMS])

        g = choose_grid(lo, hi, f, per_axis, quantum_mm=10.0 ** -POS_DECIMALS)
        pos_txt = [fmt(v, POS_DECIMALS) for v in g.knots]
        k = np.array([float(v) for v in pos_txt])
        e = folded_terms(ctx, a, k)
        txt = {t: [fmt(v * 1e-3 if t in LINEAR_TERMS else v * 1e-6,
                       MM_DECIMALS if t in LINEAR_TERMS else RAD_DECIMALS) for v in e[t]]
               for t in TERMS}
        blocks += ["#", f"// component errors of {a}", " ".join([a] + [iso_name(a, t) for t in TERMS])]
        blocks += [" ".join([pos_txt[i]] + [txt[t][i] for t in TERMS]) for i in range(k.size)]
        cols[a] = (k, {t: np.array([float(v) for v in txt[t]]) * (1e3 if t in LINEAR_TERMS
                                                                    else 1e6) for t in TERMS})
        tables.append({"name": f"block {a} ({' '.join(iso_name(a, t) for t in TERMS)})",
                       **g.describe(), "residual_unit": "um (angular columns x 500 mm)"})
    sq = tuple(float(fmt(sign * ctx.table.squareness_urad[i] * 1e-6, RAD_DECIMALS)) * 1e6 / sign
               for i, sign in LOCATION.values())
    tool = ctx.table.tool_offset_mm

    def correction(pos: np.ndarray, state: np.ndarray) -> np.ndarray:
        e: dict[tuple[str, str], np.ndarray] = {}
        for j, a in enumerate(AXES):
            k, c = cols[a]
            for t in TERMS:
                e[(a, t)] = np.interp(pos[:, j], k, c[t])
        return -combine_eq3(e, pos, (0.0, 0.0, 0.0), tool, sq)

    lis = _lis(ctx, chain="XYZ", workpiece_axes=2)
    return _export(ctx, blocks, lis, correction, tables,
                   expressed=["all 18 component errors (ISO 230-1 names) and the squareness "
                              "(C0Y, B0Z, A0Z)"],
                   assumptions=["TF5280 composes the ISO 230-1 errors of chain XYZ with "
                                "workpiece_axes 2 as abbe's Eq. 3 does, lever arms = axis "
                                "positions in machine coordinates",
                                "the CNC's active tool is the model's tool offset "
                                f"{tuple(tool)} mm"])


def _grid(ctx: Context) -> Export:
    budget = int(ctx.options["max_records"])
    span = np.array([ctx.volume.travel_mm[a][1] - ctx.volume.travel_mm[a][0] for a in AXES])
    best = None
    probe = ctx.volume.grid({a: 17 for a in AXES})
    e_probe = model_error(ctx.table, probe)
    for scale in np.linspace(0.5, 1.5, 11):
        w = span ** scale
        n = np.maximum(2, np.floor((budget / np.prod(w)) ** (1 / 3) * w)).astype(int)
        while np.prod(n) > budget:
            n[np.argmax(span / n)] -= 1
        ks = [np.array([float(fmt(v, POS_DECIMALS)) for v in
                        np.linspace(*ctx.volume.travel_mm[a], int(n[j]))]) for j, a in enumerate(AXES)]
        G = np.stack(np.meshgrid(*ks, indexing="ij"), axis=-1).reshape(-1, 3)
        E = model_error(ctx.table, G).reshape(*n, 3)
        err = max(float(np.max(np.abs(RegularGridInterpolator(ks, E[..., c])(probe)
                                      - e_probe[:, c]))) for c in range(3))
        if best is None or err < best[0]:
            best = (err, n, ks, G, E)
    err, n, ks, G, E = best
    blocks = ["// abbe export isg-csv (grid): the model's tool error on a grid, mm",
              "X Y Z EXX EYY EZZ"]
    vals = np.round(E.reshape(-1, 3) * 1e-3, MM_DECIMALS)
    blocks += [" ".join([fmt(p, POS_DECIMALS) for p in G[i]] + [fmt(v, MM_DECIMALS) for v in vals[i]])
               for i in range(G.shape[0])]
    Eq = vals.reshape(*n, 3) * 1e3
    interp = [RegularGridInterpolator(ks, Eq[..., c], bounds_error=False, fill_value=None)
              for c in range(3)]

    def correction(pos: np.ndarray, state: np.ndarray) -> np.ndarray:
        p = np.column_stack([np.clip(pos[:, j], ks[j][0], ks[j][-1]) for j in range(3)])
        return -np.column_stack([f(p) for f in interp])

    tables = [{"name": "3D grid X Y Z EXX EYY EZZ", "points": int(np.prod(n)), "limit": budget,
               "per_axis": {a: int(n[j]) for j, a in enumerate(AXES)},
               "spacing_mm": {a: round(float(ks[j][1] - ks[j][0]), 4) for j, a in enumerate(AXES)},
               "interpolation_residual_um": round(err, 4),
               "limit_is_cause": bool(err > 0.05)}]
    lis = _lis(ctx, chain="XYZ", workpiece_axes=0)
    return _export(ctx, blocks, lis, correction, tables,
                   expressed=["the whole model error (all 21 errors, Abbe terms) as a 3D map"],
                   assumptions=["with workpiece_axes 0 TF5280 adds EXX, EYY, EZZ to the tool "
                                "position as given (translations need no lever arm)"])


def _lis(ctx: Context, chain: str, workpiece_axes: int) -> list[str]:
    la = ctx.options["logical_axes"]
    return ["# abbe export isg-csv: TF5280 configuration list (P-VOLC parameters)",
            f"x {la['X']}", f"y {la['Y']}", f"z {la['Z']}", f"chain {chain}",
            f"workpiece_axes {workpiece_axes}", "interpolation GRID",
            f"file[0] {ctx.options['file']}", "file_format[0] ISG_CSV"]


def _export(ctx: Context, blocks: list[str], lis: list[str], correction, tables,
            expressed: list[str], assumptions: list[str]) -> Export:
    records = sum(1 for b in blocks if b and not b.startswith(("//", "#"))
                  and not b[0].isalpha())
    if records > int(ctx.options["max_records"]):
        raise AbbeInputError(f"{records} records exceed max_records {ctx.options['max_records']}",
                             field="--set max_records")
    notes = [f"{records} records: set vol_comp[i].max_records >= {records} in the startup list"]
    for a in AXES:
        if has_reversal(ctx.table, a):
            lo, hi = ctx.volume.travel_mm[a]
            R = reversal_um(ctx.table, a, np.linspace(lo, hi, 101))
            B = float(np.mean(R))
            notes.append(f"{a}: reversal {OWN_SIGN[a] * B:+.3f} um along {a} (moving + minus "
                         "moving -): TwinCAT's backlash compensation per axis, not this file"
                         + reversal_range_note(R))

    def cannot(item: Item) -> Unheld | None:
        if item.kind == "backlash":
            return Unheld("ISG CSV has no direction argument")
        if item.kind == "thermal":
            return Unheld("no temperature argument")
        return None

    return Export(target=NAME,
                  files={ctx.options["file"]: ("\n".join(blocks) + "\n").encode(),
                         "volcomp.lis": ("\n".join(lis) + "\n").encode()},
                  correction=correction, expressed=expressed, not_held=not_held(ctx, cannot),
                  tables=tables, direction="none", notes=notes, assumptions=assumptions,
                  sources=SOURCES)


def build(ctx: Context) -> Export:
    if ctx.options["file"].lower() in ("volcomp.lis", "residual.json"):
        raise AbbeInputError(f"{ctx.options['file']!r} is the name of another output file",
                             field="--set file")
    return _components(ctx) if ctx.options["layout"] == "components" else _grid(ctx)
