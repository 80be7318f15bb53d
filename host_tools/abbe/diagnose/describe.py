"""What ``abbe diagnose`` says about each named effect: value, interval, ambiguity.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy import stats

from abbe.diagnose.backlash_pair import scan_entries
from abbe.diagnose.candidates import Cand, Engine, Selected, apply_selection
from abbe.diagnose.checks import BallbarCheck
from abbe.diagnose.effects import REVERSAL_MAX_DEGREE, EffectSpec, NotRepresentable, PredParams
from abbe.diagnose.problem import gap_stats, lstsq_rss, project_out, qr_basis, remove_nuisance
from abbe.diagnose.results import EffectResult, round_to
from abbe.diagnose.shape import drift_headline_weights, drift_tau_average
from abbe.diagnose.undecided import misfit_log_lr
from abbe.model.table import AXES, Table


def describe_effects(eng: Engine, sel: list[Selected], values: list[np.ndarray], cov: np.ndarray,
              s2: float, W: np.ndarray, pool: list[Cand], table: Table,
              pp: PredParams) -> list[EffectResult]:
    """EffectResult per selected effect: value, 95 % interval, evidence, ambiguity."""
    prob = eng.prob
    out: list[EffectResult] = []
    dof = max(prob.N - prob.nuis.shape[1] - sum(len(v) for v in values), 1)
    tq = float(stats.t.ppf(0.975, dof))
    # a drift's rate under every warm-up time constant the data cannot rule out
    tau_avg = drift_tau_average(eng, sel, values, W, s2)
    k0 = 0
    for i, (s, v) in enumerate(zip(sel, values)):
        spec = s.cand.spec
        n = len(v)
        C = cov[k0:k0 + n, k0:k0 + n]
        k0 += n
        model_infl = None
        if spec.kind == "tool_offset":
            C, model_infl = tool_model_cov(eng, s.cand, v, C)
        params = []
        for jj, pi in enumerate(s.cand.param_idx):
            ps = spec.params[pi]
            sd = math.sqrt(max(C[jj, jj], 0.0))
            params.append({"name": ps.name, "value": round_to(v[jj]), "unit": _unit(ps.unit, spec, eng),
                           "ci95": [round_to(v[jj] - tq * sd), round_to(v[jj] + tq * sd)]})
        value, unit, ci = _headline(spec, s.cand.param_idx, v, C, tq, eng)
        ta = tau_avg.get(spec.key)
        if ta is not None:
            # the interval carries the time constant's uncertainty: the mixture over the
            # grid's time constants (shape.drift_tau_average), never narrower than its own
            ci = (min(ci[0], ta["ci95"][0]), max(ci[1], ta["ci95"][1]))
            for p_ in params:
                if p_["name"] == spec.params[0].name and 2 not in s.cand.param_idx:
                    p_["ci95"] = [round_to(ci[0]), round_to(ci[1])]
        # evidence: residual before/after adding this effect (through the model)
        t_b, p_b = apply_selection(eng, sel[:i], values[:i])
        t_a, p_a = apply_selection(eng, sel[:i + 1], values[:i + 1])
        rb_ = remove_nuisance(prob, prob.y - prob.predict(eng.ev, t_b, p_b))
        ra_ = remove_nuisance(prob, prob.y - prob.predict(eng.ev, t_a, p_a))
        gb, ga = gap_stats(prob, rb_), gap_stats(prob, ra_)
        st = s.stats
        ho = st["heldout"]
        ev = {
            "residual_before": None if gb is None else gb.to_json(),
            "residual_after": None if ga is None else ga.to_json(),
            "delta_bic": round(st["dbic"], 2),
            "F": round(st["F"], 3),
            "p_value": float(f"{st['p_eff']:.3g}"),
            "log_evidence": round(float(st["log_evidence"]), 2),
            "heldout_split": ho["split"],
            "heldout_rss_before": round(ho.get("rss_without", float("nan")), 2),
            "heldout_rss_after": round(ho.get("rss_with", float("nan")), 2),
            "heldout_change_percent": round(100.0 * (ho["rss_with"] - ho["rss_without"])
                                            / max(ho["rss_without"], 1e-300), 2),
            "contribution_rms_um": round(st["contrib_rms_um"], 4),
            "checks": _per_check_contrib(eng, s, v),
        }
        if model_infl is not None:
            ev["interval_model_inflation"] = round(model_infl, 3)
        if ta is not None:
            ev["tau_alternatives"] = [{k: (round(x, 6) if isinstance(x, float) else x)
                                       for k, x in a.items()} for a in ta["alternatives"]]
        if spec.kind == "backlash":
            b0 = eng.table.axes[spec.axis]  # type: ignore[index]
            if b0.backlash_um:
                ev["model_before"] = {"backlash_um": float(b0.backlash_um),
                                      "takeup_mm": float(b0.backlash_takeup_mm)}
                ev["note"] = ("the model already had a backlash term: the value is the change of "
                              "the reversal; the take-up is the one that fits the checks")
        amb = _ambiguity(eng, sel, i, v, W, pool, table, pp, s2)
        me = model_error_ambiguity(eng, spec)
        if me is not None:
            amb.append(me)
        undecided = _undecided(spec.key, value, unit, amb, eng.opts.evidence_log_min)
        scan = scan_ci = None
        if s.cand.scan_value is not None and spec.scan:
            name = spec.scan if spec.kind != "thermal" else f"tau_{eng.drift_unit or 'h'}"
            scan = scan_entries(s.cand.scan_value, name)
            if spec.kind == "reversal" and s.cand.scan_value < 0:
                scan = {"per_target": float(-s.cand.scan_value)}
            sci = s.stats.get("scan_ci")
            if sci is not None:
                scan_ci = {name: [sci[0] if sci[2] else None, sci[1] if sci[3] else None]}
            for k2, ci2 in s.stats.get("scan_ci_pair", {}).items():
                scan_ci = dict(scan_ci or {}, **{k2: [ci2[0] if ci2[2] else None,
                                                      ci2[1] if ci2[3] else None]})
        where = "table" if spec.compensable and not (spec.kind == "thermal" and not eng.drift_on_table) \
            else "prediction model only"
        remedy = spec.remedy
        if spec.kind == "reversal":
            remedy = spec.remedy + "; " + _reversal_in_table(table, pp, spec.axis)  # type: ignore[arg-type]
        if spec.kind == "thermal" and not eng.drift_on_table:
            remedy = ("not compensable by the table without a temperature input: warm the machine "
                      "up before measuring / machining, or log the temperature (laser temp_c) so "
                      "the table's thermal term can be fitted")
        shape, shape_notes = _shape_statements(spec, s.cand.param_idx, v, C, tq, eng, table, pp)
        if spec.kind == "backlash":
            ends = _lost_motion_at_ends(eng, sel, i, values, W, tq, table, pp)
            if ends is not None:
                shape, shape_notes = ends
        out.append(EffectResult(
            id=spec.family, key=spec.key, value=value, unit=unit, ci95=ci, params=params,
            compensable=where == "table", where=where, physics=spec.physics, remedy=remedy,
            evidence=ev, axis=spec.axis, plane=spec.plane, scan=scan, scan_ci95=scan_ci,
            ambiguous_with=amb, undecided=undecided,
            shape=shape, shape_notes=shape_notes,
            stage_before=[rb_[prob.slice(k)] for k in range(len(prob.checks))],
            stage_after=[ra_[prob.slice(k)] for k in range(len(prob.checks))]))
    return merge_components(out)


def tool_model_cov(eng: Engine, cand: Cand, v: np.ndarray, C: np.ndarray
                   ) -> tuple[np.ndarray, float]:
    """A tool offset's covariance (mm²) with the model's angular uncertainty in it, and the
    factor f its standard deviations grew by (docs/effects.md §3, "The model's own
    uncertainty"). A tool offset is a lever: it is estimated through the model's angular
    terms, whose error (``model_angle_sigma_urad``) times the lever along the change
    (candidate_eval.tool_lever_mm) gives the same signature with an RMS of sigma_m (um).
    The fitted amplitude's variance is then the white part c² / D plus sigma_m² (c the
    contribution's RMS, um; D = v' C^-1 v its RSS decrease in noise units), so every
    variance of the change is inflated by f² = 1 + sigma_m² D / c², the factor its
    evidence ratio uses (evidence.log_evidence). For one component this is
    sd² = sd_w² + (sigma_m / g)², g = c / |v| the contribution per mm of change: the
    angular uncertainty times the lever, over the angular motion the change is seen
    through."""
    from abbe.diagnose.candidate_eval import tool_lever_mm
    from abbe.diagnose.problem import contribution_rms
    v = np.asarray(v, dtype=float).reshape(-1)
    sigma_m = tool_lever_mm(eng, cand.param_idx, v) * eng.opts.model_angle_sigma_urad * 1e-3
    c = contribution_rms(eng.prob, cand.cols @ v)
    if not (sigma_m > 0 and c > 0 and v.size):
        return C, 1.0
    D = float(v @ np.linalg.pinv(C) @ v)
    f2 = 1.0 + sigma_m ** 2 * D / c ** 2
    return C * f2, math.sqrt(f2)


def merge_components(effects: list[EffectResult]) -> list[EffectResult]:
    """One effect, one entry: the thermal drift components of several axes (one warm-up,
    one time constant: selection.py) become the components of the first one's entry
    (the one named first, with the most evidence); the others are removed. A single
    drift still lists its one component, so a reader finds the per-axis values in one
    place whatever their number."""
    th = [e for e in effects if e.id == "thermal_drift"]
    if not th:
        return effects
    head = th[0]
    head.components = [{"key": e.key, "axis": e.axis, "value": round_to(e.value),
                        "unit": e.unit, "ci95": [round_to(e.ci95[0]), round_to(e.ci95[1])],
                        "parameters": e.params,
                        "contribution_rms_um": e.evidence.get("contribution_rms_um")}
                       for e in th]
    if len(th) > 1:
        head.stage_after = th[-1].stage_after
        for e in th[1:]:
            head.ambiguous_with += [a for a in e.ambiguous_with if a not in head.ambiguous_with]
        head.evidence = {**head.evidence, "components_named_after": [e.key for e in th[1:]]}
    return [e for e in effects if e.id != "thermal_drift" or e is head]


def _shape_statements(spec: EffectSpec, idx: list[int], v: np.ndarray, C: np.ndarray, tq: float,
                      eng: Engine | None = None, table: Table | None = None,
                      pp: PredParams | None = None) -> tuple[dict[str, Any] | None, list[str]]:
    """Derived shape of an effect: the servo model (pure delay or first-order loops with
    their mean time constant), the positioning bow of a scale error."""
    if spec.kind == "servo":
        if 1 not in idx:
            return ({"servo_model": "not resolved (no feed-squared oval)"},
                    ["servo model: only the lag mismatch is resolved; the oval along the axes "
                     "that the loops' mean lag gives (growing with the feed squared) is not: "
                     "the same circle at a second, higher feed would show it"])
        i0, i1 = idx.index(0), idx.index(1)
        dt, q = float(v[i0]), float(v[i1])
        if abs(dt) < 1e-9:
            return None, []
        g = np.zeros(len(v))
        out: dict[str, Any] = {"servo_model": "mean lag resolved; pure delays and first-order "
                                              "loops give the same signature on circles"}
        txt = []
        for name, kappa in (("delay", 1.0), ("first_order", 1.5)):
            tm = q / (kappa * dt)
            g[i0], g[i1] = -q / (kappa * dt ** 2), 1.0 / (kappa * dt)
            sd = math.sqrt(max(float(g @ C @ g), 0.0))
            ci = [round_to(tm - tq * sd), round_to(tm + tq * sd)]
            out[f"tau_mean_ms_if_{name}"] = round_to(tm)
            out[f"tau_mean_ms_if_{name}_ci95"] = ci
            txt.append(f"{tm:.2f} ms [{ci[0]:.2f}, {ci[1]:.2f}] as "
                       + ("pure delays" if name == "delay" else "first-order lags (1 / Kv)"))
        return out, ["servo model: mean lag of the plane's loops " + " or ".join(txt)
                     + f" (from q = {q:.4g} ms^2; circles cannot tell the two loop models "
                       "apart, the controller settings can)"]
    if spec.kind == "reversal" and eng is not None:
        per_target = bool(idx) and idx[0] >= REVERSAL_MAX_DEGREE
        form = ("per target (linear between the targets: the ISO 230-2 reversal values, as "
                "per-point forward/reverse compensation tables hold them)" if per_target
                else f"a smooth series of degree {len(idx)} over the travel")
        d: dict[str, Any] = {"form": "per_target" if per_target else "chebyshev",
                             "degree": None if per_target else len(idx)}
        pts = eng.reversal_points(spec.axis)  # type: ignore[arg-type]
        if pts.size and pts.size <= 64:
            j = AXES.index(spec.axis)  # type: ignore[arg-type]
            at = table.axes[spec.axis]  # type: ignore[index]
            # the table's backlash + reversal block, and what the prediction model holds
            # beside them (a per-target form's remainder, fold_reversal)
            rev = at.reversal_um(pts) + pp.reversal_at(j, at.travel_mm, pts)  # type: ignore[union-attr]
            i_lo, i_hi = int(np.argmin(rev)), int(np.argmax(rev))
            d.update({"targets_mm": [round_to(x) for x in pts],
                      "total_reversal_um": [round_to(x) for x in rev]})
            return d, [f"total reversal (backlash + position-dependent part) from "
                       f"{rev[i_lo]:.2f} um at {pts[i_lo]:g} mm to {rev[i_hi]:.2f} um at "
                       f"{pts[i_hi]:g} mm; form: {form}"]
        return d, [f"form: {form}"]
    if spec.kind == "scale" and 1 in idx:
        b = float(v[idx.index(1)])
        return {"positioning_bow_um": round_to(b)}, [f"with a positioning bow of {b:.3f} um "
                                                       "(sag at mid-travel relative to the ends)"]
    return None, []


def _lost_motion_at_ends(eng: Engine, sel: list[Selected], i: int, values: list[np.ndarray],
                         W: np.ndarray, tq: float, table: Table, pp: PredParams
                         ) -> tuple[dict[str, Any], list[str]] | None:
    """Lost motion at each reversal end of the circles that move a backlash's axis (the
    step where the axis reverses at its + end and at its - end, Renishaw's "backlash X+ /
    X-"), with 95 % intervals: the backlash and a linear position dependence of the
    reversal fitted together (the other effects and the nuisance refitted). None without
    a circle moving the axis."""
    from abbe.diagnose.checks import BallbarCheck
    from abbe.diagnose.effects import by_key
    s = sel[i]
    axis = s.cand.spec.axis
    j = AXES.index(axis)  # type: ignore[arg-type]
    circles = [c for c in eng.prob.checks if isinstance(c, BallbarCheck) and j in
               {"XY": (0, 1), "YZ": (1, 2), "ZX": (2, 0)}[c.plane]]
    if not circles:
        return None
    lo_p = min(float(c.center_mm[j] - c.radius_mm) for c in circles)
    hi_p = max(float(c.center_mm[j] + c.radius_mm) for c in circles)
    prob = eng.prob
    y = prob.predict(eng.ev, table, pp)
    rev = by_key()[f"reversal_{axis.lower()}"]  # type: ignore[union-attr]
    c1 = eng.sensitivity(rev, None, table, pp, y, [0])[:, 0]
    cb = eng.sensitivity(s.cand.spec, s.cand.scan_value, table, pp, y, [0])[:, 0]
    others = [o.cand.cols for k, o in enumerate(sel) if k != i]
    X = np.hstack([prob.nuis] + others + [cb[:, None], c1[:, None]]) * W[:, None]
    r = (prob.y - y) * W
    coef, *_ = np.linalg.lstsq(X, r, rcond=None)
    e = r - X @ coef
    dof = max(prob.N - X.shape[1], 1)
    s2 = max(1.0, float(e @ e) / dof)
    cov = s2 * np.linalg.pinv(X.T @ X)[-2:, -2:]
    at = table.axes[axis]  # type: ignore[index]
    t_lo, t_hi = at.travel_mm
    out: dict[str, Any] = {}
    txt = []
    for name, pos in (("minus_end", lo_p), ("plus_end", hi_p)):
        u = (2.0 * min(max(pos, t_lo), t_hi) - t_lo - t_hi) / (t_hi - t_lo)
        g = np.array([1.0, u])
        # the model's reversal there (backlash + block) plus the fitted change
        val = float(at.reversal_um(np.array([pos]))[0]) + float(coef[-2]) + float(coef[-1]) * u
        sd = math.sqrt(max(float(g @ cov @ g), 0.0))
        out[f"reversal_at_{name}_um"] = round_to(val)
        out[f"reversal_at_{name}_um_ci95"] = [round_to(val - tq * sd), round_to(val + tq * sd)]
        out[f"{name}_mm"] = round_to(pos)
        txt.append(f"{val:.2f} um [{val - tq * sd:.2f}, {val + tq * sd:.2f}] at the "
                   f"{'-' if name == 'minus_end' else '+'} end ({pos:g} mm)")
    return out, [f"lost motion at the circle's reversal points of {axis}: " + ", ".join(txt)]


def _reversal_in_table(table: Table, pp: PredParams, axis: str) -> str:
    """Where the updated model holds ``axis``' reversal: the reversal block written into
    model.bin (format 1.1) and any per-target remainder kept by the prediction model."""
    at = table.axes[axis]
    j = AXES.index(axis)
    blk = at.reversal_cheb_um
    out = ("written into model.bin as backlash "
           f"{at.backlash_um:.2f} um plus a reversal block of degree "
           f"{0 if blk is None else len(blk) - 1} (table format 1.1)")
    left = pp.reversal_knot_um[j]
    if left is not None and np.any(left):
        out += (f"; the block leaves up to {float(np.max(np.abs(left))):.2f} um of the per-target "
                "values, which only the prediction model holds (diagnose.json gives the "
                "total reversal per target, for a controller's per-point forward/reverse "
                "table)")
    return out


def _unit(u: str, spec: EffectSpec, eng: Engine) -> str:
    if spec.kind == "thermal":
        per = eng.drift_unit or "h"
        return f"{u}/{per}"
    return u


def _headline(spec: EffectSpec, idx: list[int], v: np.ndarray, C: np.ndarray, tq: float,
              eng: Engine) -> tuple[float, str, tuple[float, float]]:
    """The effect's value, unit and 95 % interval (amplitude for cyclic, norm for the tool
    offset, offset rate for the drift: else the single parameter)."""
    if spec.kind == "cyclic":
        a = float(np.hypot(v[0], v[1]))      # the fundamental's amplitude (the harmonic's
        g = np.zeros(len(v))                 # two amplitudes are in the parameters)
        g[:2] = np.array([v[0], v[1]]) / max(a, 1e-300)
        sd = math.sqrt(max(float(g @ C @ g), 0.0))
        return a, "um", (max(0.0, a - tq * sd), a + tq * sd)
    if spec.kind == "reversal":
        # RMS over the targets of the position-dependent part about its mean: the mean is a
        # constant reversal, the backlash's (B = mean(+) - mean(-) over the targets); the
        # per-target form sums to zero already, a Chebyshev form (T2, T4 ...) need not
        pts, Phi = eng.reversal_design(spec.axis, idx)  # type: ignore[arg-type]
        Phi = Phi - Phi.mean(axis=0) if Phi.size else Phi
        f = Phi @ v
        a = float(np.sqrt(np.mean(f * f)))
        g = Phi.T @ f / (f.size * max(a, 1e-300))
        sd = math.sqrt(max(float(g @ C @ g), 0.0))
        return a, "um", (max(0.0, a - tq * sd), a + tq * sd)
    if spec.kind == "tool_offset":
        a = float(np.linalg.norm(v))
        g = v / max(a, 1e-300)
        sd = math.sqrt(max(float(g @ C @ g), 0.0))
        return a, "mm", (max(0.0, a - tq * sd), a + tq * sd)
    if spec.kind == "thermal":
        i = 0 if 0 in idx else None
        if i is None:
            jj = 0
            return float(v[jj]), _unit(spec.params[idx[0]].unit, spec, eng), \
                (float(v[jj] - tq * math.sqrt(C[jj, jj])), float(v[jj] + tq * math.sqrt(C[jj, jj])))
        # the rate at the reference point (with a bow the rate varies along the travel)
        g = drift_headline_weights(eng, spec, idx)
        val = float(g @ v)
        sd = math.sqrt(max(float(g @ C @ g), 0.0))
        return val, _unit("um", spec, eng), (val - tq * sd, val + tq * sd)
    sd = math.sqrt(max(C[0, 0], 0.0))
    return float(v[0]), spec.params[idx[0]].unit, (float(v[0] - tq * sd), float(v[0] + tq * sd))


def _undecided(key: str, value: float, unit: str, amb: list[dict[str, Any]],
               log_min: float) -> dict[str, Any] | None:
    """Undecided is an answer (issue 36): an alternative B fitted to this effect A's
    signature (the ambiguity already computed) whose misfit, in the estimated noise, is
    too small for the data to prefer A: the log likelihood ratio of A over B,
    ``log_lr`` = (the part of A's fitted signature B cannot reproduce, whitened RSS in s^2
    units) / 2, is below ``log_min`` = log((1 - alpha) / alpha), the same level an effect
    needs to be named (docs/effects.md §3, "Undecided is an answer"). The result states
    both with their values and the test that separates them; what the checks constrain
    is what every alternative reproduces (the fitted signature). The misfit is compared
    with the noise and the model's own relative error of the signature
    (undecided.misfit_log_lr), so a large signature reproduced to a small share is
    undecided by the same rule, with no second threshold."""
    alts = [a for a in amb if a.get("log_lr") is not None and a["log_lr"] < log_min]
    if not alts:
        return None
    entries = [{"key": key, "value": round(float(value), 6), "unit": unit}]
    for a in alts:
        v = a.get("value") or [None]
        u = a.get("unit") or [None]
        entries.append({"key": a["key"], "value": v[0] if len(v) == 1 else v,
                        "unit": u[0] if len(u) == 1 else u, "r2": a["r2"],
                        "log_lr": a["log_lr"]})
    tests = [a["separating_test"] for a in alts]
    return {"alternatives": entries, "separating_test": tests[0] if len(tests) == 1 else tests,
            "statement": " or ".join(e["key"] for e in entries) +
            ", indistinguishable on these checks; to separate them run: " + "; ".join(tests),
            "constrained": "the combination the checks see (the fitted signature): every "
                           "alternative reproduces it; the table holds it as " + key}


def companion_undecided(effect: EffectResult, key: str, value: float, unit: str,
                        separating_test: str, log_k: float, log_k_typical: float) -> None:
    """Undecided between "A alone" and "A + B" (issue 36): a candidate B that the named
    effect A mostly reproduces, which the held-out data prefer but whose evidence ratio
    is decided by the prior alone (strong against under the catalogue's plausible range
    ``log_k``, not strong against under a prior of the typical magnitude
    ``log_k_typical``): the data cannot say whether B is present beside A. The entry
    says so with both values; the table keeps A alone (what the evidence requires)."""
    entry = {"key": key, "value": round(float(value), 6), "unit": unit, "with": effect.key,
             "log_evidence": round(float(log_k), 2),
             "log_evidence_typical": round(float(log_k_typical), 2)}
    stmt = (f"{effect.key} alone, or {effect.key} + {key}: indistinguishable on these checks "
            f"(the evidence for {key} beside {effect.key} depends on the prior: log K "
            f"{log_k:.1f} for any plausible size, {log_k_typical:.1f} for a typical one; the "
            f"held-out data prefer the pair); to separate them run: {separating_test}")
    if effect.undecided is None:
        effect.undecided = {"alternatives": [{"key": effect.key, "value": round(float(effect.value), 6),
                                              "unit": effect.unit}],
                            "separating_test": separating_test, "statement": stmt,
                            "constrained": f"{effect.key}: its signature is in the data either "
                                           "way; the table holds it alone",
                            "companion": True}
    else:
        effect.undecided["statement"] += "; " + stmt
    effect.undecided["alternatives"].append(entry)
    effect.undecided.setdefault("companions", []).append(key)
    unknown = f"whether {key} is present beside {effect.key} (not written into the table)"
    if effect.undecided.get("companion") and "table_holds" not in effect.undecided:
        effect.undecided["table_holds"] = {effect.key: round_to(effect.value)}
    effect.undecided["unknown"] = (effect.undecided["unknown"] + "; " + unknown
                                   if effect.undecided.get("unknown") else unknown)


def _per_check_contrib(eng: Engine, s: Selected, v: np.ndarray) -> dict[str, float]:
    prob = eng.prob
    contrib = s.cand.cols @ v
    if s.cand.offset is not None:
        contrib = contrib + s.cand.offset
    out = {}
    for i, c in enumerate(prob.checks):
        sl = prob.slice(i)
        out[c.name] = round(float(np.sqrt(np.mean(contrib[sl] ** 2))), 4)
    return out


def model_error_ambiguity(eng: Engine, spec: EffectSpec) -> dict[str, Any] | None:
    """The ambiguity of an effect with an error of the model itself on these checks, or
    None: the flag the report carries (the selection counts the model's uncertainty in
    the effect's evidence ratio: abbe.diagnose.evidence.candidate_prior).
    Known today: a tool offset seen at one Z height only (it multiplies the model's
    angular terms, so a scaled angular fit error gives the same signature)."""
    if spec.kind == "tool_offset":
        zs = {round(float(c.center_mm[2]), 3) for c in eng.prob.checks
              if isinstance(c, BallbarCheck)}
        if len(zs) <= 1:
            return {"key": "model_angular_error", "id": "model error", "r2": None,
                    "separating_test": "a circle at another Z height or with another "
                                       "tool length (a tool offset scales with the "
                                       "tool length, an error of the model's angular "
                                       "terms with the height)"}
    return None


def _ambiguity(eng: Engine, sel: list[Selected], i: int, v: np.ndarray, W: np.ndarray,
               pool: list[Cand], table: Table, pp: PredParams,
               s2: float = 1.0) -> list[dict[str, Any]]:
    """Other candidates that reproduce >= ambiguity_r2 of this effect's fitted signature,
    or whose misfit to it is within the noise and the model's error (``log_lr``,
    undecided.misfit_log_lr, below the evidence level: then undecided)."""
    prob = eng.prob
    s = sel[i]
    others = [o for j, o in enumerate(sel) if j != i]
    X_o = np.hstack([o.cand.cols for o in others]) * W[:, None] if others else np.zeros((prob.N, 0))
    Qb = qr_basis(np.hstack([prob.nuis * W[:, None], X_o]))
    sig = project_out(Qb, (s.cand.cols @ v * W)[:, None])[:, 0]
    nrm = float(sig @ sig)
    if nrm <= 0:
        return []
    out = []
    sel_keys = {o.cand.spec.key for o in sel}
    for c in pool:
        if c.spec.key in sel_keys or c.cols.shape[1] == 0:
            continue
        cols = c.cols
        if c.spec.kind == "cyclic":
            per, _ = eng.cyclic_scan(c.spec.axis, table, W, Qb, sig)  # type: ignore[arg-type]
            if not np.isfinite(per):
                continue
            cols = eng.cyclic_cols(c.spec.axis, per, table)  # type: ignore[arg-type]
        Z = project_out(Qb, cols * W[:, None])
        coef, d = lstsq_rss(Z, sig)
        r2 = d / nrm
        ps = [c.spec.params[i] for i in c.param_idx] if c.spec.kind != "cyclic" else \
            list(c.spec.params)[:cols.shape[1]]
        if any(abs(x) > p.limit for x, p in zip(coef, ps)):
            continue  # only with an implausible value
        log_lr = misfit_log_lr(nrm - d, nrm, s2, eng.opts.model_rel_sigma)
        if r2 >= eng.opts.ambiguity_r2 or (r2 > 0 and log_lr < eng.opts.evidence_log_min):
            out.append({"key": c.spec.key, "id": c.spec.family, "r2": round(r2, 4),
                        "log_lr": round(log_lr, 3),
                        "value": [round(float(x), 4) for x in coef],
                        "unit": [p.unit for p in ps],
                        "separating_test": _separating_test(eng, s, v, c, coef, table)})
    return out


def _separating_test(eng: Engine, s: Selected, v: np.ndarray, other: Cand, coef: np.ndarray,
                     table: Table) -> str:
    """The standard test (ballbar in each plane, CW + CCW; laser line per axis) on which the
    two explanations differ most, computed through the model on hypothetical checks. A
    thermal drift and a scale error of one axis differ in time, not in the standard
    tests' positions: the test that separates them repeats the run in another order."""
    from abbe.diagnose.recommend import faster_circles, standard_checks
    kinds = {s.cand.spec.kind, other.spec.kind}
    if kinds == {"thermal", "scale"} and s.cand.spec.axis == other.spec.axis:
        return (f"the laser line of {s.cand.spec.axis} again in the reverse time order of "
                "its runs and targets, or after a dwell of about the warm-up time (a scale "
                "error depends on the position only, a drift on when the reading is taken; "
                "abbe diagnose judges the two on held-out runs taken at other times)")
    best, best_d = "a test in another plane or a laser line of the axis", 0.0
    try:
        hyp = standard_checks(table) + faster_circles(eng.prob.checks)
    except Exception:  # pragma: no cover - defensive
        return best
    for hc in hyp:
        sub = eng.on_checks([hc], table)
        y0 = sub.y0
        try:
            a = sub.sensitivity(s.cand.spec, s.cand.scan_value, table, eng.pp, y0)[:, s.cand.param_idx] @ v
            if other.spec.kind == "cyclic":
                continue
            b = sub.sensitivity(other.spec, other.scan_value, table, eng.pp, y0)[:, other.param_idx] @ coef
        except NotRepresentable:
            continue
        Q = qr_basis(sub.prob.nuis)
        d = project_out(Q, (a - b)[:, None])[:, 0]
        dn = float(np.sqrt(np.mean(d * d)))
        if dn > best_d:
            best, best_d = (f"{hc.name} (the two explanations differ by {dn:.2f} um RMS there)",
                            dn)
    if best_d < 0.1:
        return ("none of the standard tests (ballbar XY/YZ/ZX CW+CCW, laser X/Y/Z) separates "
                "them by 0.1 um or more")
    return best
