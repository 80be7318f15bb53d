"""The Monte Carlo (GUM S1) of ``abbe diagnose``'s uncertainty (moved from
:mod:`abbe.diagnose.uncertainty`), independent of the first-order formulas: each draw makes
new readings (normal noise + one draw of every instrument input), fits them again through
the nonlinear model (:func:`_refitter`: Gauss-Newton, every residual through the C
library) and evaluates the headline and gap figures; U_MC = 2 x the draws' standard
deviation. Beyond ``AGREEMENT`` (10 %) the Monte Carlo's U is stated (``U_from``).
"""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from abbe.diagnose.candidates import apply_selection
from abbe.diagnose.problem import remove_nuisance
from abbe.diagnose.results import FitState
from abbe.diagnose.scale_free import absorbed, free_scale_axes, freed_columns, freed_with
from abbe.diagnose.uncertainty_inputs import K, Inputs
from abbe.diagnose.uncertainty_linear import _final_design


#: beyond this relative difference the Monte Carlo's U is stated
AGREEMENT = 0.10


def _refitter(st: FitState, iterations: int = 4) -> Callable[[np.ndarray], list[np.ndarray]]:
    """The final fit of new readings, nonlinear: Gauss-Newton from the solution, each step's
    residual through the model (the C library, every effect applied), the Jacobian at the
    solution steering the steps (as the chain's and the trunnion's Monte Carlo do); the
    set-up nuisance refitted with it. Its fixed point is the weighted least squares of the
    model on the new readings (to the Jacobian's change over the draws' spread)."""
    eng, prob = st.eng, st.eng.prob
    X, _, _ = _final_design(st)
    A = np.hstack([prob.nuis, X]) * st.W[:, None]
    P = np.linalg.pinv(A)
    k0 = prob.nuis.shape[1]
    sizes = [len(v) for v in st.values]
    theta0 = np.concatenate([np.asarray(v, dtype=np.float64) for v in st.values])

    def refit(y_new: np.ndarray) -> list[np.ndarray]:
        theta = theta0.copy()
        for _ in range(iterations):
            vals = np.split(theta, np.cumsum(sizes)[:-1])
            t, p = apply_selection(eng, st.selected, vals)
            r = (y_new - prob.predict(eng.ev, t, p)) * st.W
            step = (P @ r)[k0:]
            theta = theta + step
            if np.max(np.abs(step)) <= 1e-6 * max(float(np.max(np.abs(theta))), 1e-9):
                break
        return list(np.split(theta, np.cumsum(sizes)[:-1]))
    return refit


def _monte_carlo(res: Any, st: FitState, inp: Inputs, sig2: np.ndarray,
                 fns: list[tuple[str, Callable[[np.ndarray], float], slice]], draws: int,
                 seed: int, per_key: dict[str, Any], gaps: dict[str, Any],
                 u_time_constant: dict[str, float] | None = None,
                 whole: set[int] | None = None) -> dict[str, Any]:
    from abbe.diagnose.effects import fold_reversal
    from abbe.diagnose.checks import DEFAULT_TAKEUP_MM
    from abbe.diagnose.problem import gap_stats
    eng, prob = st.eng, st.eng.prob
    rng = np.random.default_rng(seed)
    refit = _refitter(st) if st.selected else None
    # a ramp moves the effects through the scales it would name: their refit takes each draw
    # without the part those scales take (scale_free.absorbed) where the first order did so
    # for every effect (else whole: one that parts states the MC's U); the gaps take it whole
    free = free_scale_axes(inp, st) if st.selected else []
    X = _final_design(st)[0] if free else np.zeros((prob.N, 0))
    eff_pattern = {i: -absorbed(st, X, freed_columns(st, freed_with(inp, st, str(x.ramp_axis))),
                                x.pattern) for i, x in enumerate(inp.systematic)
                   if x.ramp_axis in free and i not in (whole or set())}
    sd = np.sqrt(sig2)
    names = [k for k, _, _ in fns] + ["before.rms_um", "before.max_um", "after.rms_um",
                                      "after.max_um"]
    F = np.full((draws, len(names)), np.nan)
    for d in range(draws):
        dy = rng.normal(0.0, 1.0, prob.N) * sd
        dy_eff = np.zeros(prob.N)   # what the scales the ramps would name take back
        for i, x in enumerate(inp.systematic):
            t_x = x.draw(rng)
            dy += t_x * x.pattern
            dy_eff += t_x * eff_pattern.get(i, 0.0)
        for g in inp.grouped:
            m = g.labels >= 0
            e = rng.uniform(-g.half_um, g.half_um, int(g.labels[m].max()) + 1)
            dy[m] += e[g.labels[m]]
        for r in inp.per_reading:
            dy += rng.uniform(-1.0, 1.0, prob.N) * r.half_um
        y_new = prob.y + dy
        row = []
        if refit is not None:
            vals = refit(y_new + dy_eff)
            row += [fn(np.asarray(v)) for (_, fn, _), v in zip(fns, vals)]
            if eff_pattern:
                vals = refit(y_new)
            t, pp = apply_selection(eng, st.selected, vals)
            t, pp = fold_reversal(t, pp, DEFAULT_TAKEUP_MM)
            r_after = y_new - prob.predict(eng.ev, t, pp)
        else:
            r_after = y_new - eng.y0
        gb = gap_stats(prob, remove_nuisance(prob, y_new - eng.y0))
        ga = gap_stats(prob, remove_nuisance(prob, r_after))
        row += [gb.rms_um, gb.max_um, ga.rms_um, ga.max_um] if gb and ga else [np.nan] * 4
        F[d] = row
    out: dict[str, Any] = {"draws": draws, "seed": seed, "figures": {}}
    n_ok = 0
    for j, name in enumerate(names):
        col = F[:, j][np.isfinite(F[:, j])]
        U_mc = K * float(np.std(col, ddof=1)) if col.size > 1 else float("nan")
        which, _, fig = name.partition(".")
        tgt = per_key.get(name) if not fig else gaps.get(which, {}).get(fig)
        if tgt is None:
            continue
        # the draws hold the selection and the table fixed: they check the first order's
        # propagation of the noise and the instruments, not a drift's time-constant line nor
        # the table's line, which are added to either in quadrature
        U_sel = K * float((u_time_constant or {}).get(name, 0.0)) if not fig else 0.0
        U_fo = math.sqrt(max(tgt["U"] ** 2 - U_sel ** 2, 0.0))
        ratio = U_mc / U_fo - 1.0 if U_fo > 0 else float("nan")
        agree = bool(abs(ratio) <= AGREEMENT)
        n_ok += agree
        tgt["U_first_order"] = tgt["U"]
        tgt["U_mc"] = U_mc
        tgt["mc_agreement"] = ratio
        tgt["mc_interval95"] = [float(np.percentile(col, 2.5)), float(np.percentile(col, 97.5))]
        if not agree:
            U_new = math.sqrt(U_mc ** 2 + U_sel ** 2)
            tgt["U"], tgt["u"] = U_new, U_new / K
        tgt["U_from"] = "first order" if agree else "Monte Carlo"
        out["figures"][name] = {"U": tgt["U_first_order"], "U_mc": U_mc, "agreement": ratio}
    out["agree_within_10pct"] = n_ok
    out["of"] = len(out["figures"])
    return out
