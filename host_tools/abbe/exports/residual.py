"""What an export leaves uncompensated: the full model minus the target's reconstruction.

residual(p) = E_model(p, s) + C_target(p, s'), E the model error (dX, dY, dZ),
C the correction the target adds to the commanded position, s the model's
direction state and s' the target's own. Like the model itself (every term is 0
at the reference point) the residual is taken relative to the reference point:
the constant r(ref) (direction-averaged) is removed and reported as
``constant_offset_um`` -- a constant is a shift of the workpiece zero that the
work offset absorbs (a controller that zeroes its table at home, or applies a
matrix about the machine origin, differs from the model by such a constant).

* Work volume (:mod:`abbe.exports.volume`): every grid point with every
  axis at rest after moving + (s = s' = +1) and after moving - (s = s' = -1);
  per axis only its own state matters, so this covers every combination.
* Circles: CCW then CW along each ballbar circle of the machine file; the
  model's state follows its take-up rule, the target's state its own rule.

Reported per component (dX, dY, dZ), for the vector norm, and on circles also
radially (what a ballbar sees): max |r| and RMS, um. The uncompensated model
(C = 0) is given alongside.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from abbe.exports.target import Context, Export
from abbe.exports.terms import model_error
from abbe.exports.volume import circle_path
from abbe.model.backlash import backlash_state, direction_state
from abbe.model.table import AXES

FORMAT = "abbe-export-residual"


def _stats(r: np.ndarray, radial: np.ndarray | None = None) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, a in enumerate(AXES):
        v = r[:, k]
        out[f"d{a}"] = {"max_um": round(float(np.max(np.abs(v))), 4),
                        "rms_um": round(float(np.sqrt(np.mean(v ** 2))), 4)}
    n = np.linalg.norm(r, axis=1)
    out["norm"] = {"max_um": round(float(np.max(n)), 4),
                   "rms_um": round(float(np.sqrt(np.mean(n ** 2))), 4)}
    if radial is not None:
        out["radial"] = {"max_um": round(float(np.max(np.abs(radial))), 4),
                         "rms_um": round(float(np.sqrt(np.mean(radial ** 2))), 4),
                         "range_um": round(float(np.ptp(radial)), 4)}
    return out


def _sign_state(p: np.ndarray) -> np.ndarray:
    """Sign of the motion per sample, held while at rest (initially the first motion's)."""
    s = direction_state(p, 0.0)
    out = np.empty_like(s)
    last = s[0]
    for i, v in enumerate(s):
        if v != 0:
            last = v
        out[i] = last
    return out


def target_states(path_mm: np.ndarray, rule: Any) -> np.ndarray:
    """(N, 3) the target's direction state along a path by its rule (Export.direction)."""
    out = np.zeros_like(path_mm)
    if rule == "none":
        return out
    for j in range(3):
        p = path_mm[:, j]
        takeup = 0.0 if rule == "sign" else float(rule[1])
        s0 = float(_sign_state(p)[0])
        out[:, j] = backlash_state(p, takeup, s0) if takeup > 0 else _sign_state(p)
    return out


def model_states(ctx: Context, path_mm: np.ndarray) -> np.ndarray:
    """(N, 3) the model's direction state along a path (its take-up rule)."""
    out = np.zeros_like(path_mm)
    for j, a in enumerate(AXES):
        p = path_mm[:, j]
        tk = float(ctx.table.axes[a].backlash_takeup_mm)
        s0 = float(_sign_state(p)[0])
        out[:, j] = backlash_state(p, tk, s0) if tk > 0 else _sign_state(p)
    return out


def reference_offset(ctx: Context, exp: Export) -> np.ndarray:
    """(3,) residual at the reference point, averaged over both direction states."""
    ref = np.asarray(ctx.table.reference_mm, dtype=np.float64)[None, :]
    one = np.ones((1, 3))
    e0 = model_error(ctx.table, ref)[0]
    c = 0.5 * (exp.correction(ref, one) + exp.correction(ref, -one))[0]
    return e0 + c


def evaluate(ctx: Context, exp: Export) -> dict[str, Any]:
    """The residual report of one export (module docstring), as written to residual.json."""
    off = reference_offset(ctx, exp)
    P = ctx.volume.grid()
    res, unc = [], []
    for s in (1.0, -1.0):
        st = np.full(P.shape, s)
        e = model_error(ctx.table, P, st)
        res.append(e + exp.correction(P, st) - off)
        unc.append(e)
    vol = {**ctx.volume.describe(), "states": "every axis at rest after moving + and after moving -",
           "residual": _stats(np.vstack(res)), "uncompensated": _stats(np.vstack(unc))}
    circles: dict[str, Any] = {}
    for c in ctx.volume.circles:
        path = circle_path(c)
        sm = model_states(ctx, path.pos_mm)
        stt = target_states(path.pos_mm, exp.direction)
        e = model_error(ctx.table, path.pos_mm, sm)
        r = e + exp.correction(path.pos_mm, stt) - off
        m = path.data
        circles[c.name] = {
            "plane": c.plane, "center_mm": list(c.center_mm), "radius_mm": c.radius_mm,
            "runs": "CCW then CW, 0.1 deg steps, data arc [0, 360)",
            "residual": _stats(r[m], np.sum(r[m] * path.u_r[m], axis=1)),
            "uncompensated": _stats(e[m], np.sum(e[m] * path.u_r[m], axis=1))}
    return {
        "format": FORMAT, "version": 1, "target": exp.target,
        "model": ctx.model_source,
        "convention": ("residual = model error (dX, dY, dZ) + the target's correction, relative "
                       "to the reference point (constant_offset_um removed), um"),
        "constant_offset_um": [round(float(v), 4) for v in off],
        "volume": vol, "circles": circles,
        "expressed": exp.expressed, "not_held": exp.not_held, "tables": exp.tables,
        "notes": exp.notes, "assumptions": exp.assumptions, "sources": exp.sources,
        "files": sorted(exp.files),
    }


def summary(report: dict[str, Any]) -> str:
    """The lines ``abbe export`` prints."""
    v = report["volume"]["residual"]
    u = report["volume"]["uncompensated"]
    lines = [f"abbe export {report['target']}: wrote {', '.join(report['files'])}",
             "  residual over the work volume (max / RMS um): "
             + "  ".join(f"{k} {v[k]['max_um']:.3f} / {v[k]['rms_um']:.3f}"
                         for k in ("dX", "dY", "dZ", "norm"))
             + f"   (uncompensated |E| {u['norm']['max_um']:.3f} / {u['norm']['rms_um']:.3f})"]
    for name, c in report["circles"].items():
        r = c["residual"]
        lines.append(f"  residual on {name} (max / RMS um): "
                     + "  ".join(f"{k} {r[k]['max_um']:.3f} / {r[k]['rms_um']:.3f}"
                                 for k in ("dX", "dY", "dZ", "norm", "radial"))
                     + f"   (uncompensated radial {c['uncompensated']['radial']['max_um']:.3f})")
    for t in report["tables"]:
        if t.get("limit_is_cause"):
            r = t.get("interpolation_residual_um", t.get("staircase_residual_um", 0.0))
            extra = (f" ({t['twice_the_points_residual_um']:.3f} um with twice the points)"
                     if "twice_the_points_residual_um" in t else "")
            lines.append(f"  {t['name']}: the point limit ({t['limit']}) is the cause of "
                         f"{r:.3f} um table residual{extra}")
    if report["not_held"]:
        lines.append("  not held by this target (size over the work volume, |E| max / RMS um):")
        for d in sorted(report["not_held"], key=lambda d: -d["max_um"]):
            unit = " per K" if d.get("per_kelvin") else ""
            lines.append(f"    {d['item']}: {d['max_um']:.3f} / {d['rms_um']:.3f}{unit} "
                         f"({d['reason']})")
    for n in report["notes"]:
        lines.append(f"  note: {n}")
    return "\n".join(lines)
