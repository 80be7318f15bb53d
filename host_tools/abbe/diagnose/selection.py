"""Decision engine of ``abbe diagnose``: name what the model misses, add it, show the gap shrink.

Steps (docs/effects.md):

1. **Simulate**: predict every check (:mod:`abbe.diagnose.checks`) with the
   current model through the C library.
2. **Compare**: residual = measured - predicted, sample by sample; the nuisance
   columns of each check (ballbar centre and radius, laser zeros and set-up
   slopes, per-run zeros) are always fitted.
3. **Candidates** (:mod:`abbe.diagnose.effects`): each is a set of extra model
   parameters; its signature on the checks is its sensitivity, computed by
   perturbing the parameter and re-predicting through the model (finite
   differences). Nonlinear parameters (cyclic period, backlash take-up) are
   searched on a grid.
4. **Decide**: forward stepwise selection on the whitened residual (weights =
   the noise of each channel, estimated from repeated runs / the scatter about
   a saturated smooth fit). A candidate is accepted by one rule
   (:mod:`abbe.diagnose.evidence`): its evidence ratio against the model without
   it, from that noise, the catalogue's prior ranges (and a declared quantity's
   prior), the model's own uncertainty along its signature and the look-elsewhere
   of a searched shape, must reach (1 - alpha) / alpha; the held-out data are the
   arbiter (:mod:`abbe.diagnose.heldout`: fit on one fold, e.g. angle sectors or
   early runs, judge on the other, and back). Selection stops when no
   candidate qualifies. Candidates whose signature on the given checks is
   (almost) reproduced by another's are reported as ambiguous, with the test
   that would separate them.
5. **Name** each effect with its value, 95 % interval and evidence.
6. **Add** it to the model: the table (blob, C, JSON) gets the term the C
   library evaluates; effects it cannot hold stay in the prediction model.
7. **Gap**: predict again through the C library with the updated model.

Units: positions mm, linear values um, angles urad; see each field.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from abbe.diagnose.blas import one_blas_thread
from abbe.diagnose.candidates import Cand, Engine, Selected, apply_selection, selection_residual
from abbe.diagnose.caps import cap_violations
from abbe.diagnose.checks import DEFAULT_TAKEUP_MM, Check, LaserCheck, check_travel
from abbe.diagnose.describe import describe_effects
from abbe.diagnose.entangled import first_of_entangled
from abbe.diagnose.heldout import heldout_gap, heldout_removal, heldout_rss
from abbe.diagnose.undecided import share_undecided
from abbe.diagnose.effects import PredParams, catalogue, copy_table, fold_reversal
from abbe.diagnose.evaluator import Evaluator
from abbe.diagnose.shape import refine_scans
from abbe.diagnose.outliers import OutlierRun, inconsistent_runs, screen
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
from abbe.diagnose.results import (LACK_OF_FIT_LIMIT, DiagnoseOptions, DiagnoseResult, FitState,
                                  GapStats)
from abbe.errors import AbbeInputError
from abbe.model.table import Table
from abbe.diagnose.candidate_eval import _eval_candidate, _evidence, _judge, _weights, heldout_need


_TERM_WRITERS = ("scale", "cyclic", "straightness", "reversal")


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
        ev = _evidence(eng, a, coef, Z, d / s2, s2, contribution_rms(prob, a.cols @ coef))
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
    from abbe.diagnose.candidate_eval import tool_lever_mm
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
    ev = log_evidence(coef, cov_w, drss, contrib, pr["half_width"], pr["sigma_model_um"],
                      eng.opts.prior_log_odds, pr["declared_cov"], max(f_c.n_scan, 1))
    return float(ev["log_evidence"])


@one_blas_thread
def diagnose(table: Table, checks: list[Check], options: DiagnoseOptions | None = None,
             pred_params: PredParams | None = None, evaluator: Evaluator | None = None,
             _outliers: list[OutlierRun] | None = None,
             table_cov: dict[tuple[str, str], np.ndarray] | None = None) -> DiagnoseResult:
    """Diagnose what ``table`` is missing to reproduce ``checks``; see the module doc.

    Outlier runs of repeated laser / positioning checks are found first (gross readings,
    model free) and, after the diagnosis, runs inconsistent with the others; they are
    excluded, named in ``DiagnoseResult.outliers`` and the rest is diagnosed.

    Returns a :class:`DiagnoseResult` with the named effects, the gap before/after
    (also on held-out data) and the updated table. Raises AbbeInputError for checks
    outside the model's travel or too little data to decide.

    ``table_cov``: the table's coefficient covariance (table_uncertainty.table_covariance),
    carried into every candidate's evidence (docs/effects.md §3); None / {}: not carried.
    """
    opts = options or DiagnoseOptions()
    if not checks:
        raise AbbeInputError("no check measurement given (--ballbar NAME / --laser AXIS / "
                             "--iso230-2 FILE)", field="checks")
    check_travel(checks, table)
    outl = list(_outliers or [])
    for c in checks:
        outl += [o for o in c.meta.pop("outliers_found", []) if o not in outl]
    checks, found = screen(checks)
    outl += found
    eng = Engine(table, checks, opts, pred_params, evaluator)
    if table_cov:
        from abbe.diagnose.table_uncertainty import table_factor
        eng.table_M = table_factor(eng, table, eng.pp, table_cov)
    prob = eng.prob
    by_key_spec = {s.key: s for s in catalogue()}
    specs = [s for s in catalogue() if opts.candidates is None
             or s.key in opts.candidates or s.family in opts.candidates]
    for c in checks:
        if isinstance(c, LaserCheck) and c.n_runs < 2:
            raise AbbeInputError(f"{c.name}: {c.n_runs} run: the noise cannot be estimated "
                                 "without repeated runs (ISO 230-2: 5 bidirectional runs; at "
                                 "least 2 needed)", file=c.source, field="run")
    # parameters of the largest candidate (a reversal's degree adapts to the targets: 1)
    max_k = max((1 if s.kind == "reversal" else len(s.params)) for s in specs) if specs else 1
    n_nuis = prob.nuis.shape[1]
    need = max(30, 3 * (n_nuis + 2 * max_k + 2))
    if prob.N < need:
        raise AbbeInputError(f"too few points to decide: {prob.N} samples for {n_nuis} nuisance "
                             f"terms; need at least {need}",
                             file=checks[0].source if len(checks) == 1 and checks[0].source
                             else None, field="checks")
    # Before.
    r0 = eng.r0
    clean0 = remove_nuisance(prob, r0)
    gap_before = gap_stats(prob, clean0)
    if gap_before is not None and gap_before.rms_um > 200.0:
        raise AbbeInputError(
            f"the model misses the measurement by {gap_before.rms_um:.0f} um RMS (after centre/zero "
            "removal): the model and the measurement do not belong to the same machine, or a "
            "unit/sign is wrong; nothing can be diagnosed", field="model")

    # Noise and weights from the base residual (re-estimated after each addition).
    sig, infl, noise_rep = estimate_noise(prob, clean0)
    W = _weights(prob, sig, infl)
    dof_noise = float(sum(v["dof"] for v in noise_rep.values())) or float(prob.N)
    Qn = qr_basis(prob.nuis * W[:, None])
    cands = eng.build_candidates(table, eng.pp, eng.y0, W, Qn, specs)
    not_obs = [f"{c.spec.key}: {c.why_not}" for c in cands if not c.observable]
    pool = [c for c in cands if c.observable]
    by_key_pool = {c.spec.key: c for c in pool}

    selected: list[Selected] = []
    tested: dict[str, dict[str, Any]] = {}
    notes: list[str] = []
    rw = eng.r0 * W
    while len(selected) < opts.max_effects:
        rw = selection_residual(eng, selected) * W
        X_sel = np.hstack([s.cand.cols for s in selected]) * W[:, None] if selected \
            else np.zeros((prob.N, 0))
        Qb = qr_basis(np.hstack([prob.nuis * W[:, None], X_sel]))
        rb = project_out(Qb, rw[:, None])[:, 0]
        rss_base = float(rb @ rb)
        remaining = [c for c in pool if c.spec.key not in {s.cand.spec.key for s in selected}]
        if not remaining:
            break
        results = []
        for c in remaining:
            Qc, rbc, rss_c, free = Qb, rb, rss_base, None
            static, static_ho = _static_free(eng, c, selected, by_key_pool)
            if static is not None:
                # A drift is named on its change in time (docs/effects.md §3, drift and
                # scale): the part of its signature that is the same in every run is a
                # static effect of the axis, a function of the position (its scale: with
                # the drift variable taken from the cold state, a warm machine's drift
                # column is mostly a scale) or of the position and the direction (its
                # reversal: within each bidirectional cycle the forward pass is read early
                # at the low targets, the backward pass late). The drift is judged, and
                # ranked, with those free in the base.
                Qc = qr_basis(np.hstack([Qb, project_out(Qb, static * W[:, None])]))
                rbc = project_out(Qc, rw[:, None])[:, 0]
                rss_c = float(rbc @ rbc)
                free = static
            alts = eng._alts.get(c.spec.key)
            if alts and c.spec.kind == "tool_offset":
                _tool_components(eng, c, alts, W, Qc, rbc, rss_c, rw)
                alts = None
            tau = _named_drift_tau(selected) if c.spec.kind == "thermal" else None
            if alts and tau is not None:
                # a further component of the one thermal drift: the same warm-up, the
                # same time constant (one effect, one entry: describe.merge_components)
                alts = [a for a in alts if a.scan_value == tau] or alts[:0]
                if not alts:
                    continue
            if alts:
                # nonlinear grid value / parameter subset: the alternative with the best BIC
                # (a drift's time constant on the checks that span it: Engine.tau_rows)
                best_c, best_b = None, math.inf
                rows = eng.tau_rows(alts[0].cols) if c.spec.kind == "thermal" \
                    and not eng.drift_on_table else None
                if rows is not None and not rows.any():
                    rows = None
                for a in alts:
                    Z, _, d = _alt_fit(a, W, Qc, rbc, rss_c, rw, rows)
                    n_obs = prob.N if rows is None else int(rows.sum())
                    b = -d + Z.shape[1] * math.log(n_obs)
                    if b < best_b:
                        best_c, best_b = a, b
                if best_c is not None:
                    c.cols, c.param_idx, c.scan_value = best_c.cols, best_c.param_idx, best_c.scan_value
                    c.offset = best_c.offset
            st = _eval_candidate(eng, c, selected, W, Qc, rbc, rss_c, dof_noise,
                                 len(remaining), table, rw, free)
            if st.get("ok") and st["heldout"]["split"] is None and static_ho is not free:
                # a fold of one bidirectional run cannot identify a drift beside a reversal:
                # the drift is judged there beside its scale alone (as before issue 36's
                # eleventh round); its evidence keeps the reversal free
                st["heldout"] = heldout_rss(eng, selected, c, W, st["s2"], static_ho)
            ok, why = _judge(st, opts)
            st["qualifies"], st["why_not"] = ok, why
            results.append((c, st))
            tested[c.spec.key] = _summ(st, c, opts)
        good = [(c, st) for c, st in results if st["qualifies"]]
        if not good:
            break
        # the BIC decrease orders the additions; of two entangled explanations the one
        # with the larger evidence ratio goes first (entangled.first_of_entangled)
        (c, st), why_first = first_of_entangled(good, W, Qb, opts.ambiguity_r2)
        if why_first:
            notes.append("ORDER: " + why_first)
        selected.append(Selected(c, st))
        tested[c.spec.key]["selected"] = True
        # re-estimate the noise with the effect in the model
        theta_lin = _linear_fit(prob, selection_residual(eng, selected), selected, W)
        rr = selection_residual(eng, selected) - sum((s.cand.cols @ th) for s, th in zip(selected, theta_lin))
        sig, infl, noise_rep = estimate_noise(prob, remove_nuisance(prob, rr))
        W = _weights(prob, sig, infl)
        dof_noise = float(sum(v["dof"] for v in noise_rep.values())) or float(prob.N)

    # Backward check: every selected effect must still be significant with the others.
    # Shape parameters (take-up, period): refined continuously, with 95 % intervals, before
    # the backward passes (an effect may only have absorbed a shape on the grid) and again
    # after them.
    refine_scans(eng, selected, W)
    selected = _backward(eng, selected, W, notes)
    selected = heldout_removal(eng, selected, W, notes)
    refine_scans(eng, selected, W)

    fin = _finish(eng, selected, W, clean0, notes)
    # The gap never grows: a combination whose residual, on the data used or held out,
    # is larger than before is rejected; the effect whose removal shrinks the gap most
    # goes first, until the gap no longer grows (at worst nothing is named).
    while fin["selected"] and _gap_grew(gap_before, fin):
        sel_now = fin["selected"]
        tries = [_finish(eng, sel_now[:i] + sel_now[i + 1:], W, clean0, [])
                 for i in range(len(sel_now))]
        best = min(tries, key=lambda f: (_gap_grew(gap_before, f), _gap_key(f)))
        gone = [x.cand.spec.key for x in sel_now if not any(x is y for y in best["selected"])]
        notes.append("REJECTED: " + ", ".join(x.cand.spec.key for x in sel_now)
                     + f" together made the gap larger ({_gap_text(gap_before, fin)}); "
                     + ", ".join(gone) + " removed")
        fin = _finish(eng, best["selected"], W, clean0, notes)
    # The table's caps: a term the named effects take out of abbe fit's guard (the
    # updated model.bin could not be written, or only with cancelling coefficients) is
    # not changed: the effect that writes into it goes, and the report says which term.
    while fin["selected"]:
        bad = cap_violations(table, fin["table"])
        if not bad:
            break
        axes = {a for a, _, _ in bad}
        culprits = [x for x in fin["selected"] if x.cand.spec.axis in axes
                    and x.cand.spec.kind in _TERM_WRITERS]
        if not culprits:
            break
        gone = culprits[-1]
        notes.append("REJECTED: " + gone.cand.spec.key + " would change the table beyond what "
                     "it holds (" + "; ".join(f"{a}.{t}: {why}" for a, t, why in bad)
                     + "); removed (the value, if real, needs a new abbe fit of the axis)")
        fin = _finish(eng, [x for x in fin["selected"] if x is not gone], W, clean0, notes)
    selected = fin["selected"]
    new_table, new_pp, values, cov, s2_final = (fin["table"], fin["pp"], fin["values"],
                                                fin["cov"], fin["s2"])
    r_after, clean_after, gap_after = fin["r_after"], fin["clean_after"], fin["gap_after"]
    ho_before, ho_after, ho_split = fin["ho_before"], fin["ho_after"], fin["ho_split"]

    effects = describe_effects(eng, selected, values, cov, s2_final, W, pool, new_table, new_pp)
    # undecided: the table holds the equal share of the explanations (what they agree on)
    shared = share_undecided(eng, selected, values, effects, pool)
    if shared is not None:
        new_table, new_pp = shared
        r_after = prob.y - prob.predict(eng.ev, new_table, new_pp)
        clean_after = remove_nuisance(prob, r_after)
        gap_after = gap_stats(prob, clean_after)
    # a candidate the named effects mostly reproduce, not preferred as a pair on held-out
    # data: reported as the alternative explanation of the effect that reproduces it
    by_key_e = {e.key: e for e in effects}
    for k, v in tested.items():
        e = by_key_e.get(v.get("redundant_with") or "")
        if e is not None and not v.get("selected") and v.get("significant") \
                and v.get("redundancy", 0.0) >= opts.ambiguity_r2 \
                and k not in {a["key"] for a in e.ambiguous_with}:
            e.ambiguous_with.append({"key": k, "id": by_key_spec[k].family,
                                     "r2": v["redundancy"], "reverse": True,
                                     "separating_test": "not preferred as a pair on held-out "
                                     f"data: {k} alone is mostly reproduced by {e.key}"})
    _companions(eng, effects, tested, by_key_spec)
    for e in effects:
        if e.undecided:
            notes.append("UNDECIDED: " + e.undecided["statement"] + " (values: " + ", ".join(
                f"{a['key']} {a['value']} {a['unit']}" for a in e.undecided["alternatives"]) + ")")
    lof = _lack_of_fit(eng, r_after)
    tentative = lof > LACK_OF_FIT_LIMIT
    if not effects and not tentative:
        obs = ", ".join(c.spec.key for c in pool) or "none"
        notes.insert(0, "Nothing is missing: no candidate effect is significant against the "
                        f"noise on these checks (tested: {obs}).")
    undecided = [k for k, v in tested.items() if not v.get("selected") and v.get("significant")
                 and k not in {e.key for e in effects}]
    if undecided:
        notes.append("Significant but not named (failed the held-out or size test): "
                     + ", ".join(f"{k} ({tested[k]['why_not']})" for k in undecided))
    if tentative:
        notes.insert(0, (
            f"LACK OF FIT: after the update the residual is still {lof:.1f} x the noise. "
            + ("The named effects are TENTATIVE: the model may not belong to this machine, or "
               "something outside the catalogue is present; check the model and the tests "
               "before using the update." if effects else
               "Nothing in the catalogue explains it: the model may not belong to this machine, "
               "or something outside the catalogue is present.")))
        for e in effects:
            e.tentative = True
    if evaluator is None:
        evaluator = eng.ev
    w_resid = remove_nuisance(prob, r_after) * _weights(prob, *estimate_noise(prob, clean_after)[:2])
    incons: list[OutlierRun] = []
    for i, c in enumerate(checks):
        if isinstance(c, LaserCheck):
            incons += inconsistent_runs(c, w_resid[prob.slice(i)])
    drop = {(o.check, o.run) for o in incons if o.excluded}
    if drop:
        new_checks = [c.without_runs({r for (n, r) in drop if n == c.name})
                      if isinstance(c, LaserCheck) and any(n == c.name for n, _ in drop) else c
                      for c in checks]
        # a run is "inconsistent" against this diagnosis' model; the drift's tie to the
        # campaign temperature (drift_temperature) is another explanation of the same
        # excess, so it is tested on the runs before that exclusion (gross outliers, found
        # model free, stay out): excluding them first would remove what it must explain
        for i, (old_c, new_c) in enumerate(zip(checks, new_checks)):
            if new_c is not old_c and isinstance(new_c, LaserCheck) and isinstance(old_c, LaserCheck):
                new_c.tie_source = old_c.tie_source or (old_c, clean0[prob.slice(i)])
        return diagnose(table, new_checks, opts, pred_params, evaluator, outl + incons,
                        table_cov)
    outl += incons
    for o in outl:
        notes.insert(0, ("OUTLIER: " if o.excluded else "OUTLIER (kept): ") + o.message())
    return DiagnoseResult(
        fit_state=FitState(eng, selected, values, cov, s2_final, W),
        outliers=outl,
        effects=effects,
        gap={"before": gap_before, "after": gap_after, "held_out_before": ho_before,
             "held_out_after": ho_after},
        table=new_table, pred_params=new_pp, base_table=table, checks=checks,
        residual_before=[clean0[prob.slice(i)] for i in range(len(checks))],
        residual_after=[clean_after[prob.slice(i)] for i in range(len(checks))],
        noise=noise_rep, tested=tested, not_observable=not_obs, notes=notes,
        backend=eng.ev.backend, drift_unit=eng.drift_unit, lack_of_fit=lof, tentative=tentative,
        heldout_split=ho_split)
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


def _summ(st: dict[str, Any], c: Cand, opts: DiagnoseOptions) -> dict[str, Any]:
    d = {"significant": bool(st.get("ok") and st["log_evidence"] >= opts.evidence_log_min),
         "qualifies": bool(st.get("qualifies")), "why_not": st.get("why_not", "")}
    if st.get("ok"):
        d.update({"p_value": float(f"{st['p_eff']:.3g}"), "delta_bic": round(st["dbic"], 2),
                  "F": round(st["F"], 3), "heldout_gain": (None if not np.isfinite(st["heldout"]["gain"])
                                                            else round(st["heldout"]["gain"], 2)),
                  "contribution_rms_um": round(st["contrib_rms_um"], 4),
                  "log_evidence": (None if not np.isfinite(st["log_evidence"])
                                   else round(st["log_evidence"], 2))})
        lt = st["evidence"].get("log_evidence_typical")
        if lt is not None and np.isfinite(lt):
            d["log_evidence_typical"] = round(float(lt), 2)
        d["heldout_need"] = round(heldout_need(st, opts), 2)
        if st["k"]:
            d["value"] = round(float(st["coef"][0]), 6)
            d["unit"] = c.spec.params[c.param_idx[0]].unit
        d["observable_rms_um"] = round(float(st["observable_rms_um"]), 4)
        if c.scan_value is not None:
            d["scan"] = {c.spec.scan or "scan": round(float(c.scan_value), 4)}
        d["heldout_in_time"] = bool(st.get("heldout_in_time"))
        if st.get("redundant_with"):
            d["redundancy"] = round(float(st["redundancy"]), 4)
            d["redundant_with"] = st["redundant_with"]
    return d
def _companions(eng: Engine, effects: list[Any], tested: dict[str, dict[str, Any]],
                by_key_spec: dict[str, Any]) -> None:
    """"A alone, or A + B" (docs/effects.md §3, "Undecided is an answer"): a candidate B not
    named whose held-out gain passes the arbiter, that a named effect A reproduces more
    than it leaves (redundancy >= 0.5), and whose evidence ratio the prior decides: strong
    against for any plausible size (the selection's prior), not strong against for an
    effect of typical size (log K_typical > -log 19). The data then cannot say whether B
    is present beside A; the named effect's entry becomes undecided with both. A drift
    qualifies only when its held-out gain comes from a split in time (a check with
    repeated runs, ``heldout_in_time``): a split by angle sectors has not checked that it
    changes in time."""
    from abbe.diagnose.describe import _unit, companion_undecided
    lo = eng.opts.evidence_log_min
    by_key = {e.key: e for e in effects}
    for k, v in tested.items():
        a = by_key.get(v.get("redundant_with") or "")
        if a is None or v.get("selected") or k in by_key or v.get("value") is None:
            continue
        lk, lt, g = v.get("log_evidence"), v.get("log_evidence_typical"), v.get("heldout_gain")
        if lk is None or lt is None or g is None or lk >= lo or lt <= -lo:
            continue
        if not g >= v["heldout_need"] or v.get("redundancy", 0.0) < 0.5:
            continue
        if any(x.get("key") == k for x in (a.undecided or {}).get("alternatives", [])):
            continue
        spec = by_key_spec[k]
        if spec.kind == "tool_offset":
            continue   # a declared quantity is judged by its own prior only (never "maybe")
        if spec.kind == "thermal" and not v.get("heldout_in_time"):
            continue   # a drift's held-out gain must come from a split in time (early / late runs)
        if {spec.kind, by_key_spec[a.key].kind} == {"thermal", "scale"} and spec.axis == a.axis:
            test = (f"the laser line of {spec.axis} again in the reverse time order of its runs "
                    "and targets, or after a dwell of about the warm-up time (a scale error "
                    "depends on the position only, a drift on when the reading is taken)")
        else:
            test = f"a test that sees {k} apart from {a.key} (docs/effects.md §3, Ambiguity)"
        companion_undecided(a, k, v["value"], _unit(v.get("unit", ""), spec, eng), test, lk, lt)


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
