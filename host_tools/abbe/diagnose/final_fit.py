"""The end of ``abbe diagnose``'s selection (moved from :mod:`abbe.diagnose.selection`):
the backward check (every selected effect still significant with the others), the final
fit of the selection through the model (Gauss-Newton, values and covariance; an effect
too small once the others are in dropped), the gap after it on the data used and held
out, whether the gap grew, and the lack of fit in units of the noise.

Units: positions mm, linear values um, angles urad; RMS figures um.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from abbe.diagnose.candidates import Engine, Selected, apply_selection, selection_residual
from abbe.diagnose.checks import DEFAULT_TAKEUP_MM
from abbe.diagnose.heldout import heldout_gap
from abbe.diagnose.effects import PredParams, copy_table, fold_reversal
from abbe.diagnose.problem import (
    Problem,
    contribution_rms,
    effect_size_um,
    estimate_noise,
    gap_stats,
    lstsq_rss,
    project_out,
    qr_basis,
    remove_nuisance,
)
from abbe.diagnose.results import GapStats
from abbe.model.table import Table
from abbe.diagnose.candidate_eval import _evidence, _weights


def _finish(eng: Engine, selected: list[Selected], W: np.ndarray, clean0: np.ndarray,
            notes: list[str]) -> dict[str, Any]:
    """Final fit of ``selected`` through the model (Gauss-Newton), values, intervals, and
    the gap after it, on the data used and held out. An effect whose final contribution
    is below the size threshold is dropped (noted) and the rest refitted."""
    prob, opts = eng.prob, eng.opts
    new_table, new_pp, values, cov, s2_final = _final_fit(eng, selected, W)
    while len(selected) > 1:
        small = [(i, _final_contribution(prob, s, v)) for i, (s, v) in enumerate(zip(selected, values))]
        small = [(i, c) for i, c in small if c < opts.min_effect_um]
        if not small:
            break
        i, c = min(small, key=lambda x: x[1])
        notes.append(f"{selected[i].cand.spec.key} dropped: its contribution in the final fit "
                     f"is {c:.3f} um RMS (< {opts.min_effect_um:g} um) once the others are in")
        selected = selected[:i] + selected[i + 1:]
        new_table, new_pp, values, cov, s2_final = _final_fit(eng, selected, W)
    # the reversal found along the travel goes into the table's reversal blocks (format
    # 1.1): model.bin carries it, the prediction below evaluates it through the library
    new_table, new_pp = fold_reversal(new_table, new_pp, DEFAULT_TAKEUP_MM)
    y_after = prob.predict(eng.ev, new_table, new_pp)
    r_after = prob.y - y_after
    clean_after = remove_nuisance(prob, r_after)
    # Held-out gap through the model: fit on one fold, judge the other (and back).
    ho_before, ho_after, ho_split = heldout_gap(eng, selected, W, clean0)
    return {"selected": selected, "table": new_table, "pp": new_pp, "values": values,
            "cov": cov, "s2": s2_final, "r_after": r_after, "clean_after": clean_after,
            "gap_after": gap_stats(prob, clean_after), "ho_before": ho_before,
            "ho_after": ho_after, "ho_split": ho_split}


def _gap_grew(before: GapStats | None, fin: dict[str, Any]) -> bool:
    """True if the residual after the update is larger than before, on the data used
    or on held-out data (RMS, um; a relative 1e-9 for rounding)."""
    pairs = [(before, fin["gap_after"]), (fin["ho_before"], fin["ho_after"])]
    return any(b is not None and a is not None and a.rms_um > b.rms_um * (1 + 1e-9)
               for b, a in pairs)


def _gap_key(fin: dict[str, Any]) -> float:
    a = fin["ho_after"] or fin["gap_after"]
    return a.rms_um if a is not None else math.inf


def _gap_text(before: GapStats | None, fin: dict[str, Any]) -> str:
    parts = []
    for label, b, a in (("used", before, fin["gap_after"]),
                        ("held out", fin["ho_before"], fin["ho_after"])):
        if b is not None and a is not None:
            parts.append(f"{label}: {b.rms_um:.3f} -> {a.rms_um:.3f} um RMS")
    return "; ".join(parts)


def _linear_fit(prob: Problem, r: np.ndarray, sel: list[Selected], W: np.ndarray) -> list[np.ndarray]:
    """Coefficients of the selected effects (with nuisance) on residual r, whitened LS."""
    if not sel:
        return []
    X = np.hstack([prob.nuis] + [s.cand.cols for s in sel]) * W[:, None]
    coef, *_ = np.linalg.lstsq(X, r * W, rcond=None)
    out, k = [], prob.nuis.shape[1]
    for s in sel:
        n = s.cand.cols.shape[1]
        out.append(coef[k:k + n])
        k += n
    return out
def _backward(eng: Engine, sel: list[Selected], W: np.ndarray,
              notes: list[str]) -> list[Selected]:
    prob = eng.prob
    changed = True
    while changed and len(sel) > 1:
        changed = False
        for i, s in enumerate(sel):
            others = sel[:i] + sel[i + 1:]
            X_o = np.hstack([o.cand.cols for o in others]) * W[:, None]
            Qb = qr_basis(np.hstack([prob.nuis * W[:, None], X_o]))
            rb = project_out(Qb, (selection_residual(eng, others) * W)[:, None])[:, 0]
            rb_s = project_out(Qb, (selection_residual(eng, sel) * W)[:, None])[:, 0]
            Z = project_out(Qb, s.cand.cols * W[:, None])
            coef, fit = lstsq_rss(Z, rb_s)
            dr = float(rb @ rb) - (float(rb_s @ rb_s) - fit)
            k = Z.shape[1]
            dof_res = prob.N - Qb.shape[1] - k
            s2 = max(1.0, (float(rb_s @ rb_s) - fit) / max(dof_res, 1))
            contrib = s.cand.cols @ coef + (0.0 if s.cand.offset is None else s.cand.offset)
            ev = _evidence(eng, s.cand, coef, Z, dr / s2, s2, contribution_rms(prob, contrib), W)
            # the same rule as the forward step: the evidence ratio with the others in
            if not ev["log_evidence"] >= eng.opts.evidence_log_min:
                notes.append(f"{s.cand.spec.key} dropped: no longer significant once "
                             + ", ".join(o.cand.spec.key for o in others) + " are in the model"
                             f" (log evidence ratio {ev['log_evidence']:.1f})")
                sel = others
                changed = True
                break
    return sel
def _final_contribution(prob: Problem, s: Selected, v: np.ndarray) -> float:
    """RMS (um, um-valued samples) of a named effect's part of the final prediction that the
    checks see (each check's nuisance removed; a tool offset's at the tool tip:
    problem.effect_size_um)."""
    c = s.cand.cols @ v
    if s.cand.offset is not None:
        c = c + s.cand.offset
    return effect_size_um(prob, s.cand.spec.kind, c) if np.any(prob.um_rows) else math.inf


def _final_fit(eng: Engine, sel: list[Selected], W: np.ndarray
               ) -> tuple[Table, PredParams, list[np.ndarray], np.ndarray, float]:
    """Gauss-Newton through the model: values of the selected parameters, covariance."""
    prob = eng.prob
    if not sel:
        return copy_table(eng.table), eng.pp.copy(), [], np.zeros((0, 0)), 1.0
    values = _linear_fit(prob, selection_residual(eng, sel), sel, W)
    for it in range(3):
        t, p = apply_selection(eng, sel, values)
        y = prob.predict(eng.ev, t, p)
        r = prob.y - y
        # re-linearise (columns at the current point)
        cols = []
        for s, v in zip(sel, values):
            c = eng.sensitivity(s.cand.spec, s.cand.scan_value, t, p, y, s.cand.param_idx)
            cols.append(c[:, s.cand.param_idx])
        X = np.hstack([prob.nuis] + cols) * W[:, None]
        d, *_ = np.linalg.lstsq(X, r * W, rcond=None)
        k = prob.nuis.shape[1]
        step_norm = 0.0
        new_vals = []
        for s, v, c in zip(sel, values, cols):
            n = c.shape[1]
            dv = d[k:k + n]
            k += n
            new_vals.append(v + dv)
            step_norm = max(step_norm, float(np.max(np.abs(dv) / np.array(
                [s.cand.spec.params[i].typical for i in s.cand.param_idx]))))
        values = new_vals
        if step_norm < 1e-4:
            break
    t, p = apply_selection(eng, sel, values)
    y = prob.predict(eng.ev, t, p)
    r = (prob.y - y) * W
    Q = qr_basis(prob.nuis * W[:, None])
    Xe = project_out(Q, np.hstack(cols) * W[:, None])
    re = project_out(Q, r[:, None])[:, 0]
    dof = max(prob.N - Q.shape[1] - Xe.shape[1], 1)
    s2 = max(1.0, float(re @ re) / dof)
    cov = s2 * np.linalg.pinv(Xe.T @ Xe)
    return t, p, values, cov, s2
def _lack_of_fit(eng: Engine, r_after: np.ndarray) -> float:
    """RMS of the residual after the update in units of the noise (with the
    autocorrelation inflation), about 1 when the updated model explains the checks."""
    prob = eng.prob
    clean = remove_nuisance(prob, r_after)
    sig, infl, _ = estimate_noise(prob, clean)
    w = _weights(prob, sig, infl)
    return float(np.sqrt(np.nanmean((clean * w) ** 2)))
