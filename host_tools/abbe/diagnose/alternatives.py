"""A candidate's alternatives in one step of ``abbe diagnose``'s forward selection
(moved from :mod:`abbe.diagnose.selection`): the static effects a drift is judged beside
(docs/effects.md §3, drift and scale), the fit of one alternative (grid value / parameter
subset) on the step's residual, the warm-up time constant of a drift already named, and a
tool offset's components chosen by the evidence ratio that judges it.

Units: positions mm, linear values um, angles urad; RSS in noise units (whitened).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from abbe.diagnose.candidates import Cand, Engine, Selected
from abbe.diagnose.problem import contribution_rms, lstsq_rss, project_out, qr_basis
from abbe.diagnose.candidate_eval import _evidence


def _named_drift_tau(sel: list[Selected]) -> float | None:
    """The warm-up time constant of the thermal drift already named (drift-variable
    units; inf = linear), or None: a further axis is a component of the same drift."""
    for s in sel:
        if s.cand.spec.kind == "thermal":
            return math.inf if s.cand.scan_value is None else float(s.cand.scan_value)
    return None


def _static_free(eng: Engine, c: Cand, selected: list[Selected],
                 by_key_pool: dict[str, Cand]) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Columns (N, k) of the static effects a drift of ``c``'s axis is judged beside
    (docs/effects.md §3, drift and scale), or None: the axis' scale and its position-
    dependent reversal while they are not named (the reversal in its widest form searched:
    per target, else the highest degree, so that no static reversal the catalogue holds
    is taken as a change in time). Second: the scale's alone, for a held-out fold of a
    single bidirectional run, which cannot tell a drift from a reversal (within one cycle
    the drift's column is a constant plus a reversal's shape)."""
    if c.spec.kind != "thermal" or not c.spec.axis:
        return None, None
    named = {s.cand.spec.key for s in selected}
    ax = c.spec.axis.lower()
    sc = by_key_pool.get(f"scale_{ax}")
    scale = sc.cols if sc is not None and sc.spec.key not in named and sc.cols.shape[1] else None
    rv = by_key_pool.get(f"reversal_{ax}")
    rev = None
    if rv is not None and rv.spec.key not in named:
        rev = max(eng._alts.get(rv.spec.key) or [rv], key=lambda a: a.cols.shape[1]).cols
        rev = rev if rev.shape[1] else None
    if rev is None:
        return scale, scale
    return (rev if scale is None else np.hstack([scale, rev])), scale


def _alt_fit(a: Cand, W: np.ndarray, Qc: np.ndarray, rbc: np.ndarray, rss_c: float,
             rw: np.ndarray, rows: np.ndarray | None = None
             ) -> tuple[np.ndarray, np.ndarray, float]:
    """Fit of one alternative ``a`` (grid value / parameter subset) of a candidate on the
    whitened residual ``rbc`` (base ``Qc`` projected out; ``rw`` before projection, for an
    alternative whose grid value alone changes the prediction, ``a.offset``). Returns its
    projected columns Z, its coefficients and the RSS decrease d (noise units), on
    ``rows`` only when given (a drift's time constant on the checks that span it)."""
    Z = project_out(Qc, a.cols * W[:, None])
    ra = rbc if a.offset is None else project_out(Qc, (rw - a.offset * W)[:, None])[:, 0]
    if rows is None:
        coef, fit = lstsq_rss(Z, ra)
        return Z, coef, rss_c - (float(ra @ ra) - fit)
    coef, fit = lstsq_rss(Z[rows], ra[rows])
    return Z, coef, float(rbc[rows] @ rbc[rows]) - (float(ra[rows] @ ra[rows]) - fit)


def _tool_components(eng: Engine, c: Cand, alts: list[Cand], W: np.ndarray, Qc: np.ndarray,
                     rbc: np.ndarray, rss_c: float, rw: np.ndarray) -> None:
    """Choose a tool offset's components (t_z alone, or with t_x, t_y) by the evidence ratio
    that judges it, not by the BIC: its model-angle uncertainty depends on the change's
    direction (candidate_eval.tool_lever_mm), which the BIC does not see (issue 36,
    ``clean_3``). The optional (lateral) components are a further effect beside t_z, kept
    only when they add strong evidence: their own log evidence ratio with t_z in the base
    (their RSS decrease beyond t_z's, their own contribution and their own lever along the
    lateral change: :func:`_lateral_evidence`) >= the selection's level
    (``evidence_log_min``, log 19). Updates ``c``'s columns and components in place."""
    prob = eng.prob
    k_min = min(len(a.param_idx) for a in alts)
    fits = []
    for a in alts:
        Z, coef, d = _alt_fit(a, W, Qc, rbc, rss_c, rw)
        s2 = max(1.0, (rss_c - d) / max(prob.N - Qc.shape[1] - Z.shape[1], 1))
        ev = _evidence(eng, a, coef, Z, d / s2, s2, contribution_rms(prob, a.cols @ coef), W)
        fits.append((a, coef, d, s2, float(ev["log_evidence"]), Z.shape[1]))
    base = next(f for f in fits if len(f[0].param_idx) == k_min)
    best_c = None
    if np.isfinite(base[4]):
        best_c, best_lk = base[0], -math.inf
        for f in fits:
            if not np.isfinite(f[4]) or not set(base[0].param_idx) < set(f[0].param_idx):
                continue
            lk = _lateral_evidence(eng, base, f, W, Qc)
            if lk >= eng.opts.evidence_log_min and lk > best_lk:
                best_c, best_lk = f[0], lk
    else:
        # no evidence for t_z alone: the evidence, else the BIC (as for other candidates)
        best_b: tuple[int, float] = (2, math.inf)
        for a, coef, d, s2, lk, k in fits:
            b = (0, -lk) if np.isfinite(lk) else (1, -d + k * math.log(prob.N))
            if b < best_b:
                best_c, best_b = a, b
    if best_c is not None:
        c.cols, c.param_idx, c.scan_value = best_c.cols, best_c.param_idx, best_c.scan_value
        c.offset = best_c.offset


def _lateral_evidence(eng: Engine, base: tuple[Any, ...], full: tuple[Any, ...],
                      W: np.ndarray, Qc: np.ndarray) -> float:
    """Log evidence ratio of a tool offset's further components (those of ``full`` not in
    ``base``, each a tuple (cand, coef, rss decrease, s², log K, k)) as an effect beside
    the base components: the RSS decrease they add, their covariance with the base's
    columns projected out, their own contribution and lever (the model-angle uncertainty
    along the lateral change, candidate_eval.tool_lever_mm) and the +/- 300 mm range of
    each. The declared value's blunder odds are paid once, by the tool change itself.
    Comparing each alternative with "no change" instead (the seventh round) let the base
    win whenever the further components made the whole change's contribution smaller
    (a lateral change cancelling part of t_z's: the team suite's `tool_offset+scale_x`,
    seed 759937823, t_x -37.5 mm dropped and t_z 172 mm for 140.2, docs/diagnose-validation.md)."""
    from abbe.diagnose.evidence import candidate_prior, log_evidence
    from abbe.diagnose.candidate_eval import table_cov_of, tool_lever_mm
    b_c, f_c = base[0], full[0]
    extra = [j for j, i in enumerate(f_c.param_idx) if i not in b_c.param_idx]
    idx = [f_c.param_idx[j] for j in extra]
    coef = np.asarray(full[1], dtype=float)[extra]
    Qb = qr_basis(np.hstack([Qc, project_out(Qc, b_c.cols * W[:, None])]))
    Z = project_out(Qb, f_c.cols[:, extra] * W[:, None])
    s2 = full[3]
    drss = (full[2] - base[2]) / s2
    cov_w = s2 * np.linalg.pinv(Z.T @ Z)
    contrib = contribution_rms(eng.prob, f_c.cols[:, extra] @ coef)
    declared = np.asarray(eng.table.tool_offset_mm, dtype=float)
    pr = candidate_prior(f_c.spec, idx, declared, tool_lever_mm(eng, idx, coef), eng.opts)
    cov_t = table_cov_of(eng, Z, W)
    ev = log_evidence(coef, cov_w, drss, contrib, pr["half_width"],
                      pr["sigma_model_um"] if cov_t is None else 0.0,
                      eng.opts.prior_log_odds, pr["declared_cov"], max(f_c.n_scan, 1),
                      cov_table=cov_t)
    return float(ev["log_evidence"])
