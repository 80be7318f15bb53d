"""U (k = 2) of ``abbe diagnose``'s named effects and gaps, with the budget and a Monte Carlo.

Each named effect's value (the headline: an amplitude, a norm, a rate, a single parameter;
:func:`abbe.diagnose.describe._headline`) and the gap figures (RMS and max |residual| of the
um-valued samples, each check's set-up nuisance removed) get ``u``, ``U`` = 2 u and the
lines they come from (docs/uncertainty.md, "Diagnosis"):

* **the fit's statistical part** (Type A): the final fit's covariance s^2 (X^T W^2 X)^-1
  (the noise of every check, its serial correlation inflated, s^2 >= 1 carrying the lack
  of fit), through the headline's gradient. For a gap: the readings' noise of a
  re-measurement, sigma^2 = s^2 / W^2 per reading, through the residual (first order plus
  the quadratic form's own variance, exact for normal noise);
* **the instruments' budget** (Type B; ``[uncertainty.*]``, else the class defaults): a
  laser line's scale errors (ppm of the distance from the reference point), linearity and
  resolution; a ballbar's scale, drift ramp, resolution and length calibration. The
  selection held fixed, the final fit is linear in the readings (theta = theta0 + L dy),
  so each line is |s . p| u_t; a laser's scale-like ramp: :mod:`abbe.diagnose.scale_free`.

The Monte Carlo (GUM S1) is independent of these formulas: each draw makes new readings
(normal noise + one draw of every instrument input) and fits them again through the
nonlinear model (:func:`_refitter`: Gauss-Newton, every residual through the C library)
and evaluates the headline and gap figures; U_MC = 2 x the draws' standard deviation. Beyond 10 %
the Monte Carlo's U is stated (``U_from``), as in the rest of abbe.

Where the parts are: this module holds the whole (:func:`diagnosis_uncertainty`) and what
is attached to the result; the instrument inputs and budgets:
:mod:`abbe.diagnose.uncertainty_inputs`; the linear propagation (the final fit's design,
a headline's gradient, each input's line): :mod:`abbe.diagnose.uncertainty_linear`; the
gap figures' lines: :mod:`abbe.diagnose.uncertainty_gap`; the Monte Carlo:
:mod:`abbe.diagnose.uncertainty_mc`.
"""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from abbe.diagnose.candidates import apply_selection
from abbe.diagnose.problem import remove_nuisance
from abbe.diagnose.results import FitState
from abbe.diagnose.scale_free import free_scale_axes, free_scale_L, freed_columns, freed_with
from abbe.diagnose.uncertainty_gap import _gap_lines, _max_abs_variance, _nuisance_removal_T
from abbe.diagnose.uncertainty_inputs import (K, Grouped, Inputs, PerReading, Systematic,
                                              budget_of_positioning_file, budgets_of_machine,
                                              instrument_inputs)
from abbe.diagnose.uncertainty_linear import _final_design, _grad, _headline_fn, _line_u
from abbe.diagnose.uncertainty_mc import AGREEMENT, _monte_carlo

#: moved to uncertainty_inputs / _linear / _gap / _mc, still imported from here
__all__ = ["diagnosis_uncertainty", "budgets_of_machine", "budget_of_positioning_file",
           "instrument_inputs", "Systematic", "Grouped", "PerReading", "Inputs", "K",
           "AGREEMENT", "TABLE_LINE", "_grad", "_max_abs_variance"]


#: the budget line of the table's own fit error along the effect
TABLE_LINE = "table (fit) uncertainty"


def diagnosis_uncertainty(res: Any, laser_budget: Any, ballbar_budget: Any,
                          draws: int = 0, seed: int = 20241,
                          model_from_the_data: bool = False,
                          table_cov: dict[tuple[str, str], np.ndarray] | None = None
                          ) -> dict[str, Any] | None:
    """u, U (k = 2) and the budget of each named effect's value and of the gap figures of a
    :class:`~abbe.diagnose.results.DiagnoseResult` (its ``fit_state`` kept by diagnose);
    with ``draws``, the Monte Carlo check. Sets ``u``, ``U``, ``budget_u`` (and the Monte
    Carlo's) on each effect and component and ``res.uncertainty`` (the JSON section), and
    returns that section.

    ``model_from_the_data``: the model was built from the same readings (``abbe diagnose
    --iso230-2`` without ``--model``: the position-only model is each target's mean), so an
    error per target (the sensor's linearity) moves the model with the readings and
    cancels in every residual: it is left out (stated in the assumptions).

    ``table_cov``: the table's coefficient covariance (abbe.diagnose.table_uncertainty):
    each effect gets a line "table (fit) uncertainty" (a tool offset: the model's angular
    uncertainty its interval already carries, describe.tool_model_cov), and each effect's
    95 % interval grows in quadrature by 2 u of the lines it did not carry yet (the
    instruments', the table's), so it contains the whole budget (:func:`_widen`)."""
    st: FitState | None = getattr(res, "fit_state", None)
    if st is None:
        return None
    eng, prob = st.eng, st.eng.prob
    inp = instrument_inputs(prob, laser_budget, ballbar_budget)
    if model_from_the_data:
        # every input that is a function of the target alone (the scale errors, a
        # target's linearity) moves the position-only model with the readings
        inp.grouped = []
        inp.systematic = [x for x in inp.systematic if x.name.startswith("ballbar")]
    sig2 = st.s2 / np.maximum(st.W, 1e-300) ** 2
    per_key: dict[str, dict[str, Any]] = {}
    fns: list[tuple[str, Callable[[np.ndarray], float], slice]] = []
    u_time_constant: dict[str, float] = {}   # a drift's time-constant line (not simulated)
    extra_u: dict[str, float] = {}   # u of the lines the describe interval does not carry
    whole: set[int] = set()   # the ramps some effect takes with the selection fixed
    if st.selected:
        X, L, _ = _final_design(st)
        _, p_fin = apply_selection(eng, st.selected, st.values)
        # a drift's rate under the grid's other warm-up time constants (the same mixture its
        # 95 % interval is: shape.drift_tau_average): the spread about the value reported
        from abbe.diagnose.shape import drift_tau_average
        tau_avg = drift_tau_average(eng, st.selected, st.values, st.W, st.s2)
        L_free = {a: free_scale_L(st, X, freed_columns(st, freed_with(inp, st, a)))
                  for a in free_scale_axes(inp, st)}
        table_M: np.ndarray | None = None   # the table line's factor, made once (table_u)
        k0 = 0
        for s, v in zip(st.selected, st.values):
            n = len(v)
            C = st.cov[k0:k0 + n, k0:k0 + n]
            fn = _headline_fn(eng, s, C)
            g = _grad(fn, np.asarray(v, dtype=np.float64), C)
            sens = g @ L[k0:k0 + n]
            s_free = {a: g @ Lf[k0:k0 + n] for a, Lf in L_free.items()}
            u_fit = math.sqrt(max(float(g @ C @ g), 0.0))
            whole |= {i for i, x in enumerate(inp.systematic) if x.ramp_axis in s_free and (
                abs(float(s_free[x.ramp_axis] @ x.pattern)) - abs(float(sens @ x.pattern)))
                * x.sd > 0.1 * u_fit}   # beyond a tenth of the fit's own part
            lines = {"fit (Type A: noise, lack of fit)": u_fit, **_line_u(sens, inp, s_free)}
            extra = sum(x * x for x in lines.values()) - u_fit ** 2
            if s.cand.spec.kind == "tool_offset":
                # the model's angular uncertainty along the lever (the selection's sigma_m),
                # already in the interval (describe.tool_model_cov)
                from abbe.diagnose.describe import tool_model_cov
                _, f = tool_model_cov(eng, s.cand, np.asarray(v, dtype=np.float64), C)
                lines[TABLE_LINE] = math.sqrt(max(f * f - 1.0, 0.0)) * u_fit
            elif table_cov:
                from abbe.diagnose.table_uncertainty import table_factor, table_u
                # the derivative by the model's own coefficients (the table as loaded: the
                # effects may add rows), at the final prediction parameters: one factor
                # for every effect
                if table_M is None:
                    table_M = table_factor(eng, eng.table, p_fin, table_cov)
                lines[TABLE_LINE] = table_u(table_M, sens)
                extra += lines[TABLE_LINE] ** 2
            extra_u[s.cand.spec.key] = math.sqrt(max(extra, 0.0))
            ta = tau_avg.get(s.cand.spec.key)
            u_tau = 0.0
            if ta is not None:
                v0 = fn(np.asarray(v))
                u_tau = math.sqrt(sum(a["weight"] * (a["value"] - v0) ** 2
                                      for a in ta["alternatives"]))
                lines["drift time constant (the grid's alternatives, BIC weights)"] = u_tau
            u = math.sqrt(sum(x * x for x in lines.values()))
            per_key[s.cand.spec.key] = {"value": fn(np.asarray(v)), "u": u, "U": K * u,
                                        "budget_u": lines}
            # the Monte Carlo's draws simulate neither line: added to its U in quadrature
            u_time_constant[s.cand.spec.key] = math.hypot(u_tau, lines.get(TABLE_LINE, 0.0))
            fns.append((s.cand.spec.key, fn, slice(k0, k0 + n)))
            k0 += n
    else:
        X = np.zeros((prob.N, 0))
        L = np.zeros((0, prob.N))
    # gaps. Before: the base model is fixed, r_b(y') = P_n (y' - y0): M^T = P_n.
    clean_b = np.concatenate(res.residual_before)
    clean_a = np.concatenate(res.residual_after)
    # no um-valued sample (angular channels only): no gap figure, no U
    no_gap = res.gap.get("before") is None or res.gap.get("after") is None
    gaps: dict[str, Any] = {} if no_gap else {"before": _gap_lines(
        prob, clean_b, lambda a: _nuisance_removal_T(prob, a), sig2, inp,
        lambda p: remove_nuisance(prob, p))}

    def back_after(a: np.ndarray) -> np.ndarray:
        # r_a(y') = P_n (y' - X L y'): M^T a = (I - L^T X^T) P_n a
        pa = _nuisance_removal_T(prob, a)
        return pa - L.T @ (X.T @ pa)
    if not no_gap:
        gaps["after"] = _gap_lines(prob, clean_a, back_after, sig2, inp,
                                   lambda p: remove_nuisance(prob, p - X @ (L @ p)))
    out: dict[str, Any] = {
        "k": K, "method": "GUM first order: the final fit's covariance (Type A) and the "
                          "instruments' inputs through the fit's linear operator (Type B)",
        "budgets": inp.budgets,
        "assumptions": [
            "the selection (which effects, their grid values) held fixed; a drift's warm-up "
            "time constant has its own line (the rate under the grid's other time constants)",
            *(["the position-only model is built from these readings (each target's mean): "
               "an error that depends on the target alone (the scale errors, a target's "
               "linearity) moves it too and cancels; left out"]
              if model_from_the_data else
              ["the model held fixed: an instrument error shared by the model's own "
               "measurement and this check (the same laser file) is counted as independent "
               "(conservative)"]),
            "laser lines: instrument inputs on the own positioning channel only (the budget "
            "has no figure for straightness and angular optics); results not normalised to "
            "20 deg C (temp_deviation_c)",
            "gap max |r|: first order at the sample that makes it (the samples compete for "
            "the max; the Monte Carlo states its U where they part)"],
        "effects": per_key, "gap": gaps,
    }
    if draws:
        out["monte_carlo"] = _monte_carlo(res, st, inp, sig2, fns, draws, seed, per_key, gaps,
                                          u_time_constant, whole)
    _attach(res, per_key, gaps)
    _widen(res, extra_u)
    res.uncertainty = _round(out)
    return res.uncertainty


def _attach(res: Any, per_key: dict[str, Any], gaps: dict[str, Any]) -> None:
    def put(d: Any, u: dict[str, Any]) -> None:
        keys = ("u", "U", "budget_u", "U_first_order", "U_mc", "mc_agreement", "U_from")
        src = {k: u[k] for k in keys if k in u}
        if isinstance(d, dict):
            d.update(_round(src))
        else:
            d.uncertainty = _round(src)
    for e in res.effects:
        if e.key in per_key:
            put(e, per_key[e.key])
        for c in e.components:
            if c["key"] in per_key:
                put(c, per_key[c["key"]])
    res.gap_uncertainty = _round(gaps)


def _widen(res: Any, extra_u: dict[str, float]) -> None:
    """Each named effect's 95 % interval (describe: Student t on the fit's covariance, a
    tool offset's model inflation, a drift's time-constant mixture) with the budget lines
    it did not carry (the instruments', the table's) added in quadrature to each
    half-width at k = 2: the interval the report states then contains the whole budget."""
    def wid(v: float, ci: Any, u: float) -> list[float]:
        lo, hi = float(ci[0]), float(ci[1])
        return [float(f"{v - math.hypot(v - lo, K * u):.6g}"),
                float(f"{v + math.hypot(hi - v, K * u):.6g}")]
    for e in res.effects:
        u = extra_u.get(e.key, 0.0)
        if u > 0 and e.ci95 is not None:
            # the fit's part alone, kept for the reader who compares with earlier reports
            e.evidence["ci95_fit_only"] = [float(e.ci95[0]), float(e.ci95[1])]
            e.evidence["u_not_in_fit_interval"] = float(f"{u:.6g}")
            e.ci95 = wid(float(e.value), e.ci95, u)
            if len(e.params) == 1:
                e.params[0]["ci95"] = wid(float(e.params[0]["value"]), e.params[0]["ci95"], u)
        for c in e.components:
            uc = extra_u.get(c["key"], 0.0)
            if uc > 0 and c.get("ci95") is not None:
                c["ci95"] = wid(float(c["value"]), c["ci95"], uc)


def _round(o: Any) -> Any:
    if isinstance(o, float):
        return float(f"{o:.6g}") if math.isfinite(o) else None
    if isinstance(o, dict):
        return {k: _round(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_round(v) for v in o]
    return o
