"""``abbe import``: ISO 230-1 component errors (a controller's table, a LaserTRACER
result) -> an abbe table, fitted with the laser path's model selection.

Per axis with curves:

1. one set of positions: those of the densest curve, the others interpolated onto
   it (held ends; reported when a curve is shorter), at most ``max_points`` kept
   (evenly, ends included);
2. lever arms moved from the machine origin to the reference point (the inverse of
   the ``isg-csv`` export's folding: the axis' angular errors times the reference
   point's coordinates leave its translation columns);
3. the linear terms taken relative to the reference point (a constant per
   component is a workpiece-zero shift); angular terms are kept as they are (a
   constant angle is a real rotation of the axis) and their value at the
   reference point is reported;
4. the fit of ``abbe fit`` (:func:`abbe.analysis.fit.select.fit_axis`): period
   search, orders by cross-validation, the paper's models for comparison,
   in-sample and held-out metrics per term (the diagnostics); the stored model is
   that selection unless it misses the samples by more than FAITHFUL_UM, then the
   closest of the structures at each term's own period (:func:`faithful_model`);
   the stored linear terms are shifted to be exactly zero at the reference point;
5. quantisation into the table format; the largest difference between the file's
   samples and the stored table (the conversion residual) per term.

Squareness from the location errors (C0Y, B0Z, A0Z). No reversal or thermal
terms: the formats have none. Units: mm, um, urad.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from abbe import __version__
from abbe.analysis.fit.options import FitOptions
from abbe.analysis.fit.scan import make_design, one_se_choice, scan
from abbe.analysis.fit.select import AxisModel, fit_axis, fit_structure, select_auto
from abbe.errors import AbbeInputError
from abbe.formats.blob import read_blob, write_blob
from abbe.formats.components import ComponentData
from abbe.formats.table_json import table_to_json
from abbe.model.reference import combine_eq3, term_values
from abbe.model.table import (
    AXES,
    LINEAR_TERMS,
    TERMS,
    AxisTable,
    Table,
    TableError,
    basis_matrix,
)

SIDE = {"X": -1.0, "Y": -1.0, "Z": 1.0}
#: a stored model within this of the samples is faithful (um; urad x 0.5 mm/urad)
FAITHFUL_UM = 0.02
ISO = {"dx": "X", "dy": "Y", "dz": "Z", "ex": "A", "ey": "B", "ez": "C"}
JSON_FORMAT = "abbe-import"


@dataclass
class ImportResult:
    table: Table
    blob: bytes
    model_json: dict[str, Any] = field(default_factory=dict)


def _common_positions(data: ComponentData, axis: str, max_points: int
                      ) -> tuple[np.ndarray, dict[str, np.ndarray], list[str]]:
    curves = {t: c for (a, t), c in data.curves.items() if a == axis}
    dense = max(curves.values(), key=lambda c: c.pos_mm.size)
    p = dense.pos_mm
    notes = []
    if p.size > max_points:
        idx = np.unique(np.round(np.linspace(0, p.size - 1, max_points)).astype(int))
        notes.append(f"{p.size} positions, {idx.size} kept (evenly, ends included)")
        p = p[idx]
    vals = {}
    for t, c in curves.items():
        if c.pos_mm[0] > p[0] + 1e-9 or c.pos_mm[-1] < p[-1] - 1e-9:
            notes.append(f"{axis} {t}: its samples ({c.source}) cover [{c.pos_mm[0]:g}, "
                         f"{c.pos_mm[-1]:g}] mm, the axis [{p[0]:g}, {p[-1]:g}] mm: end values held")
        vals[t] = np.interp(p, c.pos_mm, c.values)
    return p, vals, notes


def _fidelity(m: AxisModel, p: np.ndarray, Y: np.ndarray, scale: np.ndarray) -> float:
    return float(np.max(np.abs(m.predict(p) - Y) * scale[None, :]))


def faithful_model(p: np.ndarray, Y: np.ndarray, opts: FitOptions, scale: np.ndarray):
    """The laser path's selection (:func:`fit_axis`, with its metrics), and the stored
    model: that one, or -- when it leaves more than FAITHFUL_UM of the samples (a
    controller's table is a noise-free function, where the cross-validated choice of one
    shared period can miss a term's wave) -- the structure at the period one term selects
    alone, orders by the lowest CV, whichever follows the samples closest."""
    af = fit_axis(p, Y, opts)
    best = (_fidelity(af.model, p, Y, scale), af.model, "the laser path's selection")
    if best[0] <= FAITHFUL_UM:
        return af, best
    design = make_design(p, opts)
    for i in range(Y.shape[1]):
        mi = select_auto(design, p, Y[:, [i]], opts.one_se)
        if mi.period_mm is None:
            continue
        s = scan(design, p, Y, np.array([1.0 / mi.period_mm]))
        orders = [one_se_choice(s.cv[0, :, :, j], s.se[0, :, :, j], False) for j in range(Y.shape[1])]
        m = fit_structure(design, p, Y, orders, mi.period_mm)
        e = _fidelity(m, p, Y, scale)
        if e < best[0]:
            best = (e, m, f"the period of term {i} alone ({mi.period_mm:.6g} mm), lowest CV orders")
    if best[0] > FAITHFUL_UM and design.freqs.size:
        # least squares over the candidate periods at the largest admissible structure
        d = int(min(design.max_wave_degree, design.max_degree))

        def at(f: float) -> AxisModel:
            per = 1.0 / f
            h = int(min(design.max_harmonics,
                        per // (design.samples_per_wavelength * design.spacing_mm)))
            h = max(1, min(h, (p.size - d - 3) // 2))
            return fit_structure(design, p, Y, [(d, h)] * Y.shape[1], per)

        coarse = np.arange(design.freqs[0], design.freqs[-1] + 1e-12, design.step / 4.0)
        errs = np.array([_fidelity(at(f), p, Y, scale) for f in coarse])
        f1, e1 = float(coarse[int(np.argmin(errs))]), float(np.min(errs))
        for f0 in coarse[np.argsort(errs)[:6]]:  # refine around the six best
            fine = np.linspace(f0 - design.step / 4.0, f0 + design.step / 4.0, 41)
            fine = fine[fine > 0]
            ef = np.array([_fidelity(at(f), p, Y, scale) for f in fine])
            if float(np.min(ef)) < e1:
                f1, e1 = float(fine[int(np.argmin(ef))]), float(np.min(ef))
        m = at(f1)
        e = _fidelity(m, p, Y, scale)
        if e < best[0]:
            best = (e, m, f"least squares over the periods (degree {d} + the most harmonics "
                          f"resolvable at {1.0 / f1:.6g} mm)")
    return af, best


def _unfold(axis: str, p: np.ndarray, vals: dict[str, np.ndarray], ref: np.ndarray,
            tool: tuple[float, float, float]) -> None:
    ang = {(axis, t): vals.get(t, np.zeros(p.size)) for t in ("ex", "ey", "ez")}
    n = p.size
    delta = (combine_eq3(ang, np.zeros((n, 3)), ref, tool, (0.0, 0.0, 0.0))
             - combine_eq3(ang, np.tile(ref, (n, 1)), ref, tool, (0.0, 0.0, 0.0)))
    for k, t in enumerate(LINEAR_TERMS):
        if t in vals or np.any(delta[:, k] != 0):
            vals[t] = vals.get(t, np.zeros(n)) - delta[:, k] / SIDE[axis]


def _encode(table: Table, data: ComponentData) -> bytes:
    """The blob of ``table``; a table the format cannot hold is an input error located at
    the curve of the term that does not fit (file, line of its block, ISO name)."""
    try:
        return write_blob(table)
    except TableError as exc:
        fld = exc.field or ""
        parts = fld.split(".")
        if len(parts) >= 4 and parts[0] == "axes" and parts[2] == "coef":
            a, t = parts[1], parts[3]
            c = data.curves.get((a, t))
            if c is not None:
                raise AbbeInputError(f"the fitted {t} of axis {a} does not fit in a table: "
                                     f"{exc.message}", file=c.file or data.file, line=c.line,
                                     field=f"E{ISO[t]}{a}") from None
        if len(parts) >= 2 and parts[0] == "axes" and parts[1] in AXES:
            c = next((c for (a, _), c in data.curves.items() if a == parts[1]), None)
            if c is not None:
                raise AbbeInputError(f"axis {parts[1]} does not fit in a table: {exc.message}",
                                     file=c.file or data.file, line=c.line,
                                     field=parts[1]) from None
        if fld.startswith("squareness"):
            raise AbbeInputError(f"the squareness does not fit in a table: {exc.message}",
                                 file=data.file, field="C0Y B0Z A0Z") from None
        raise AbbeInputError(f"the imported table cannot be written: {exc.message}",
                             file=data.file, field=fld or None) from None


def import_components(data: ComponentData, reference_mm: tuple[float, float, float],
                      tool_offset_mm: tuple[float, float, float] = (0.0, 0.0, 0.0),
                      travel_mm: dict[str, tuple[float, float]] | None = None,
                      opts: FitOptions | None = None, unfold: bool = True,
                      max_points: int = 201) -> ImportResult:
    """The table of ``data`` (module docstring)."""
    data.check()
    opts = opts or FitOptions()
    ref = np.asarray(reference_mm, dtype=np.float64)
    axes: dict[str, AxisTable] = {}
    diag: dict[str, Any] = {}
    notes: list[str] = []
    for j, a in enumerate(AXES):
        if a not in data.axes():
            tr = (travel_mm or {}).get(a, (float(ref[j]) - 1.0, float(ref[j]) + 1.0))
            axes[a] = AxisTable(travel_mm=tuple(tr))  # type: ignore[arg-type]
            continue
        p, vals, n_ = _common_positions(data, a, max_points)
        notes += n_
        if not p[0] - 1e-6 <= ref[j] <= p[-1] + 1e-6:
            raise AbbeInputError(f"the reference point's {a.lower()} = {ref[j]:g} mm lies outside "
                                 f"the samples [{p[0]:g}, {p[-1]:g}] mm of axis {a}",
                                 file=data.file, field="reference")
        if p.size < 5:
            raise AbbeInputError(f"axis {a}: {p.size} positions, the fit needs at least 5",
                                 file=data.file, field=f"E?{a}")
        raw = {t: v.copy() for t, v in vals.items()}
        if unfold:
            _unfold(a, p, vals, ref, tool_offset_mm)
        present = [t for t in TERMS if t in vals]
        Y = np.column_stack([vals[t] for t in present])
        scale = np.array([1.0 if t in LINEAR_TERMS else 0.5 for t in present])
        af, (_, model, how) = faithful_model(p, Y, opts, scale)
        tab = model.table
        bref = basis_matrix(tab, np.array([ref[j]]))[0]
        coefs: dict[str, np.ndarray] = {}
        for i, t in enumerate(present):
            c = model.coef[i].copy()
            if t in LINEAR_TERMS:
                c[0] -= float(bref @ c)  # T_0 == 1: zero at the reference point
            coefs[t] = c
        axes[a] = AxisTable(travel_mm=tab.travel_mm, trend_degree=tab.trend_degree,
                            blocks=tab.blocks, coef=coefs)
        diag[a] = {"positions": int(p.size), "span_mm": [float(p[0]), float(p[-1])],
                   "stored_model": how,
                   "period_mm": model.period_mm,
                   "terms": {t: {"iso_name": f"E{ISO[t]}{a}", "in_file": t in raw,
                                 "metrics": af.metrics[i], "order": list(model.orders[i]),
                                 "laser_path_order": list(af.model.orders[i])}
                             for i, t in enumerate(present)},
                   "_samples": (p, vals)}
    sq = tuple(data.squareness_urad) if data.squareness_urad is not None else (0.0, 0.0, 0.0)
    table = Table(axes=axes, reference_mm=tuple(float(v) for v in ref),  # type: ignore[arg-type]
                  tool_offset_mm=tuple(tool_offset_mm), squareness_urad=sq)  # type: ignore[arg-type]
    blob = _encode(table, data)
    qt = read_blob(blob)
    for a, d in diag.items():
        p, vals = d.pop("_samples")
        for t, dd in d["terms"].items():
            v = vals[t]
            if t in LINEAR_TERMS:
                v = v - float(np.interp(ref[AXES.index(a)], p, v))
            fitted = term_values(qt, a, t, p)
            u = "um" if t in LINEAR_TERMS else "urad"
            dd[f"conversion_residual_{u}"] = round(float(np.max(np.abs(fitted - v))), 5)
            dd[f"value_at_reference_{u}"] = round(float(term_values(qt, a, t, ref[AXES.index(a)])[0]), 5)
            dd["metrics"] = {m: {k: {n: (round(float(x), 6) if np.isfinite(x) else None)
                                     for n, x in s.items()}
                                 for k, s in kinds.items()} for m, kinds in dd["metrics"].items()}
    res = ImportResult(table=qt, blob=blob)
    res.model_json = {
        "format": JSON_FORMAT,
        "units": {"position": "mm", "linear": "um", "angular": "urad"},
        "source": {"file": Path(data.file).name, "sha256": data.sha256},
        "provenance": {"tool": "abbe", "version": __version__},
        "options": {"unfold_lever_arms": unfold, "max_points": max_points,
                    "model": opts.model, "folds": opts.folds},
        "squareness": {"S_xy_urad": sq[0], "S_xz_urad": sq[1], "S_yz_urad": sq[2],
                       "in_file": data.squareness_urad is not None},
        "ignored": list(data.ignored),
        "notes": list(data.notes) + notes,
        "table": {"crc32": f"0x{int.from_bytes(blob[-4:], 'little'):08X}",
                  "size_bytes": len(blob), **table_to_json(qt)},
        "axes": diag,
    }
    return res
