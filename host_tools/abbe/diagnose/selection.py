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

Where the parts are: this module holds the selection loop (:func:`diagnose`); a
candidate's alternative (grid value, parameter subset) and the static effects a drift is
judged beside: :mod:`abbe.diagnose.alternatives`; each candidate's fit and judgement:
:mod:`abbe.diagnose.candidate_eval`; the final fit through the model, the backward check
and the gap after: :mod:`abbe.diagnose.final_fit`; the record of every candidate tested
and the companions read from it: :mod:`abbe.diagnose.tested`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from abbe.diagnose.alternatives import _alt_fit, _named_drift_tau, _static_free, _tool_components
from abbe.diagnose.backlash_pair import is_pair
from abbe.diagnose.blas import one_blas_thread
from abbe.diagnose.candidates import Engine, Selected, selection_residual
from abbe.diagnose.caps import cap_violations
from abbe.diagnose.checks import Check, LaserCheck, check_travel
from abbe.diagnose.describe import describe_effects
from abbe.diagnose.entangled import first_of_entangled
from abbe.diagnose.final_fit import (_backward, _final_contribution, _finish, _gap_grew, _gap_key,
                                     _gap_text, _lack_of_fit, _linear_fit)
from abbe.diagnose.heldout import heldout_removal, heldout_rss
from abbe.diagnose.tested import _companions, _summ, possibly_present
from abbe.diagnose.undecided import share_undecided
from abbe.diagnose.effects import PredParams, catalogue
from abbe.diagnose.evaluator import Evaluator
from abbe.diagnose.shape import refine_scans
from abbe.diagnose.outliers import OutlierRun, inconsistent_runs, screen
from abbe.diagnose.problem import (
    estimate_noise,
    gap_stats,
    project_out,
    qr_basis,
    remove_nuisance,
)
from abbe.diagnose.results import LACK_OF_FIT_LIMIT, DiagnoseOptions, DiagnoseResult, FitState
from abbe.errors import AbbeInputError
from abbe.model.table import Table
from abbe.diagnose.candidate_eval import _eval_candidate, _evidence, _judge, _weights

#: moved to alternatives / final_fit / candidate_eval, still imported from here (tests)
__all__ = ["diagnose", "_evidence", "_judge", "_named_drift_tau", "_gap_grew",
           "_final_contribution", "_companions", "_tool_components"]


_TERM_WRITERS = ("scale", "cyclic", "straightness", "reversal")


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
                    # a backlash's take-up pair: one shape parameter more than one take-up
                    b = -d + (Z.shape[1] + is_pair(a.scan_value)) * math.log(n_obs)
                    if b < best_b:
                        best_c, best_b = a, b
                if best_c is not None:
                    c.cols, c.param_idx, c.scan_value = best_c.cols, best_c.param_idx, best_c.scan_value
                    c.offset, c.n_scan = best_c.offset, best_c.n_scan
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
    possible = possibly_present(eng, effects, tested, by_key_spec)
    for p in possible:
        notes.append("POSSIBLY PRESENT: " + p["statement"] + "; to decide: " + p["test"])
    lof = _lack_of_fit(eng, r_after)
    tentative = lof > LACK_OF_FIT_LIMIT
    if not effects and not tentative and not possible:
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
        heldout_split=ho_split, possible=possible)
