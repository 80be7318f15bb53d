"""Thermal results with their expanded uncertainty U (k = 2): each term's gain and time
constant, the model's predicted drift and the held-out channel RMS; the Monte Carlo check.

The identification's covariance (``identify.refine``: the Jacobian of the joint parameters
offset, gains, log taus at the optimum, the residual variance inflated for the serial
correlation, n / n_eff) is recomputed here from the fitted terms and kept whole, so it can
be carried to the predicted drift d(t) = sum_k g_k lag(u_k, tau_k)(t): u(d)^2 = j C j^T,
j = dd/dp (first order). The held-out RMS of the compensated residual r = y - prediction on
the validation hours carries the same parameters (first order, -r.j / (n rms)).

The analytic U of the drift and the held-out RMS is not the first order: it is the
**degree-5 cubature** of the same Gaussian input distribution (parameters from N(p, C), every
sensor's sensitivity error from N(0, u)), a deterministic sigma-point propagation (the fully
symmetric rule of Stroud / McNamee-Stenger, 2 n^2 + 1 evaluations of the model, n inputs,
averaged over three fixed frames): exact for the mean and variance of any figure quadratic
in the inputs, cross terms included. The frames (the principal axes, and the same mixed by
the DCT-II and its transpose) were chosen after measuring that the principal axes alone put
each point's whole excursion along the most non-linear direction (docs/uncertainty.md). The first order (``U_first_order``, and the budget lines) is linear and underrates
the spread where a time constant's interval spans decades or the RMS sits near a minimum.

The check (GUM S1) draws the parameters from N(p, C) and evaluates the model with the
runtime's discretisation (:func:`abbe.model.thermal.lag_states`) unchanged; U_MC = 2 x the
standard deviation over the draws. It tests the propagation (first order or cubature), not
the covariance. Units: um (um per K, um per krpm for gains; urad for tilts), s, h.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from abbe.analysis.thermal.identify import ChannelFit, candidates_of
from abbe.model.thermal import lag_states

K = 2.0


def _states(t_s: np.ndarray, cands: list[Any], fit: ChannelFit, logtau: np.ndarray) -> np.ndarray:
    dyn = [j for j, t in enumerate(fit.terms) if t.tau_s > 0]
    taus = [t.tau_s for t in fit.terms]
    for j, lt in zip(dyn, logtau):
        taus[j] = float(np.exp(lt))
    cols = [np.ones(t_s.size)] + [lag_states(cands[t.input].rise, t_s, tau)
                                  for t, tau in zip(fit.terms, taus)]
    return np.column_stack(cols)


def params_of(fit: ChannelFit) -> np.ndarray:
    """(offset, gains, log taus of the dynamic terms), as ``refine`` solves them."""
    lt = [np.log(t.tau_s) for t in fit.terms if t.tau_s > 0]
    return np.array([fit.offset_um, *[t.gain for t in fit.terms], *lt], dtype=float)


def prediction(t_s: np.ndarray, cands: list[Any], fit: ChannelFit, p: np.ndarray,
               with_offset: bool = True) -> np.ndarray:
    """The model's prediction at every sample for parameters ``p`` (um / urad)."""
    ng = len(fit.terms) + 1
    S = _states(t_s, cands, fit, p[ng:])
    g = p[:ng].copy()
    if not with_offset:
        g[0] = 0.0
    return S @ g


def covariance(t_s: np.ndarray, y: np.ndarray, cands: list[Any], fit: ChannelFit,
               mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(p, C): the joint parameters and their covariance on the identification samples
    (``refine``'s, recomputed: forward differences, s^2 inflated by n / n_eff)."""
    p = params_of(fit)
    r0 = y[mask] - prediction(t_s, cands, fit, p)[mask]
    J = np.empty((r0.size, p.size))
    for k in range(p.size):
        h = 1e-6 * max(1.0, abs(p[k]))
        dp = p.copy()
        dp[k] += h
        J[:, k] = (y[mask] - prediction(t_s, cands, fit, dp)[mask] - r0) / h
    n = r0.size
    rho = float(np.clip(np.corrcoef(r0[:-1], r0[1:])[0, 1], 0.0, 0.999)) if n > 2 else 0.0
    n_eff = max(n * (1 - rho) / (1 + rho), p.size + 1.0)
    s2 = float(r0 @ r0) / max(n - p.size, 1) * (n / n_eff)
    return p, s2 * np.linalg.pinv(J.T @ J)


def _jac(fn, p: np.ndarray) -> np.ndarray:
    f0 = fn(p)
    J = np.empty((np.size(f0), p.size))
    for k in range(p.size):
        h = 1e-6 * max(1.0, abs(p[k]))
        dp = p.copy()
        dp[k] += h
        J[:, k] = (fn(dp) - f0) / h
    return J


def _sqrt_cov(C: np.ndarray) -> np.ndarray:
    """A square root L (L L^T = C) along C's principal axes, negative round-off clipped."""
    w, V = np.linalg.eigh(C)
    return V * np.sqrt(np.clip(w, 0.0, None))


def _frames(C: np.ndarray) -> list[np.ndarray]:
    """The square roots of C the rule is averaged over: the principal axes, and the same
    axes mixed by the orthonormal DCT-II (and its transpose), which spreads each principal
    direction over every sigma point (any orthogonal mix of a square root is one)."""
    from scipy.fft import dct
    L = _sqrt_cov(C)
    Q = dct(np.eye(C.shape[0]), type=2, norm="ortho", axis=0)
    return [L, L @ Q.T, L @ Q]


def cubature5(fn, p: np.ndarray, C: np.ndarray, frames: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """(mean, standard deviation) of fn(x), x ~ N(p, C), by the fully symmetric cubature rule
    of degree 5 for a Gaussian weight (Stroud 1971, rule E_n^r2 5-2; McNamee & Stenger 1967):
    the centre, the 2n points p +- sqrt(n + 2) L_i and the 2n(n - 1) points
    p + sqrt((n + 2) / 2) (+-L_i +- L_j), for a square root L of C. Exact for polynomials of
    degree <= 5, so the variance is exact when fn is quadratic in x, in any frame L. For
    other fn the result depends on the frame: the rule's first and second moments are
    averaged over ``frames`` fixed frames (:func:`_frames`; 1 = the principal axes only).
    fn returns a vector (each figure)."""
    n = p.size
    a, b = np.sqrt(n + 2.0), np.sqrt((n + 2.0) / 2.0)
    m1 = m2 = 0.0
    Ls = _frames(C)[:max(1, frames)]
    for L in Ls:
        pts = [p]
        w = [2.0 / (n + 2.0)]
        for i in range(n):
            for s in (1.0, -1.0):
                pts.append(p + s * a * L[:, i])
                w.append((4.0 - n) / (2.0 * (n + 2.0) ** 2))
        for i in range(n):
            for j in range(i + 1, n):
                for si in (1.0, -1.0):
                    for sj in (1.0, -1.0):
                        pts.append(p + b * (si * L[:, i] + sj * L[:, j]))
                        w.append(1.0 / (n + 2.0) ** 2)
        W = np.asarray(w)
        F = np.array([np.atleast_1d(fn(x)) for x in pts], dtype=float)
        m1 = m1 + W @ F / len(Ls)
        m2 = m2 + W @ F ** 2 / len(Ls)
    mean = np.asarray(m1)
    return mean, np.sqrt(np.clip(m2 - mean ** 2, 0.0, None))


def type_b_inputs(res: Any, sig: Any) -> list[tuple[str, str, float, np.ndarray]]:
    """The Type B inputs of one signal: (name, what, standard relative u, dy), where dy is
    the change of the signal's samples per unit relative error of that sensor's
    sensitivity (a channel: its own samples; a tilt: each of its two channels' rise over
    the spacing, with the tilt's sign)."""
    spec = res.spec
    rec = res.record
    chans = spec.channels
    if sig.unit != "urad":
        c = chans.get(sig.name)
        U = c.calibration_U_pct if c is not None else 0.0
        src = "declared" if c is not None and c.calibration_declared else "class default"
        return [(f"{sig.name} sensitivity", f"displacement sensor calibration, U = {U:g} % "
                 f"(k = 2, {src})", U / 100.0 / K, np.asarray(sig.measured, dtype=float))]
    out = []
    for p in spec.tilt_pairs():
        if f"tilt_{p.output}" != sig.name:
            continue
        sign = 1.0 if p.output == "b" else -1.0
        for name, side in ((p.upper, 1.0), (p.lower, -1.0)):
            k = rec.channel_names.index(name)
            rise = rec.disp_um[:, k] - rec.disp_um[0, k]
            c = chans[name]
            src = "declared" if c.calibration_declared else "class default"
            out.append((f"{name} sensitivity", f"displacement sensor calibration, U = "
                        f"{c.calibration_U_pct:g} % (k = 2, {src}), over the "
                        f"{p.spacing_mm:g} mm spacing", c.calibration_U_pct / 100.0 / K,
                        side * sign * rise / p.spacing_mm * 1e3))
    return out


def _refit_map(t_s: np.ndarray, cands: list[Any], fit: ChannelFit, p: np.ndarray,
               mask: np.ndarray, dy: np.ndarray) -> np.ndarray:
    """The change of (offset, gains) when the identification data change by dy, the time
    constants held: exact, the gains are a least-squares fit linear in the data."""
    ng = len(fit.terms) + 1
    S = _states(t_s, cands, fit, p[ng:])
    return np.linalg.lstsq(S[mask], dy[mask], rcond=None)[0]


def _augmented(p: np.ndarray, C: np.ndarray, type_b: list[dict[str, Any]]
               ) -> tuple[np.ndarray, np.ndarray]:
    """The augmented inputs: the parameters (covariance C), then each sensor's relative
    sensitivity error (mean 0, variance u_rel^2, independent); what the cubature and the
    Monte Carlo evaluate."""
    npar = p.size
    pa = np.concatenate([p, np.zeros(len(type_b))])
    Ca = np.zeros((pa.size, pa.size))
    Ca[:npar, :npar] = C
    for i, b in enumerate(type_b):
        Ca[npar + i, npar + i] = b["u_rel"] ** 2
    return pa, Ca


def _figure_entry(value: float, uA: float, key: str, u_c: float, type_b: list[dict[str, Any]],
                  n_inputs: int, type_a_name: str) -> dict[str, Any]:
    """One figure's value (um), its U (k = 2) from the cubature's u_c, and its budget: the
    Type A line (uA) and each sensor's first-order line (``b[key]``)."""
    budget = [{"name": type_a_name, "u": uA}]
    budget += [{"name": b["name"], "what": b["what"], "u": b[key]} for b in type_b]
    return {"value": value, "U": K * u_c,
            "U_first_order": K * float(np.sqrt(sum(c["u"] ** 2 for c in budget))),
            "U_typeA": K * uA, "budget": budget,
            "method": f"degree-5 cubature averaged over 3 frames ({3 * (2 * n_inputs ** 2 + 1)} "
                      "model evaluations); the budget lines are first order"}


def signal_uncertainty(res: Any, sig: Any, draws: int = 0, seed: int = 1) -> dict[str, Any]:
    """One signal's terms, its largest predicted drift on the validation hours and its
    held-out RMS, each with U (k = 2); with ``draws`` the Monte Carlo beside each."""
    rec = res.record
    t = rec.time_s
    cands = candidates_of(rec.temps_c, list(rec.temp_names), rec.speed_rpm)
    fit = sig.fit
    if not fit.terms:
        return {"name": sig.name, "terms": [], "note": "no term: nothing predicted"}
    y = sig.measured
    p, C = covariance(t, y, cands, fit, res.ident_mask)
    sd = np.sqrt(np.maximum(np.diag(C), 0.0))
    valid = res.valid_mask
    d = prediction(t, cands, fit, p, with_offset=False)
    iv = np.flatnonzero(valid)
    i_max = int(iv[np.argmax(np.abs(d[iv]))])

    def drift_at(q: np.ndarray) -> np.ndarray:
        return np.array([prediction(t, cands, fit, q, with_offset=False)[i_max]])

    def rms_valid(q: np.ndarray) -> np.ndarray:
        r = (y - prediction(t, cands, fit, q))[valid]
        return np.array([np.sqrt(np.mean(r ** 2))])

    jd = _jac(drift_at, p)[0]
    jr = _jac(rms_valid, p)[0]
    ng = len(fit.terms) + 1
    # Type B: each sensor's sensitivity error changes the data by e * dy; the gains follow
    # linearly (refit map), so do the drift and the held-out residual
    r0 = (y - prediction(t, cands, fit, p))[valid]
    rms0 = float(rms_valid(p)[0])
    S = _states(t, cands, fit, p[ng:])
    type_b = []
    for name, what, u_rel, dy in type_b_inputs(res, sig):
        db = _refit_map(t, cands, fit, p, res.ident_mask, dy)
        dd = float((S[:, 1:] @ db[1:])[i_max])
        dr = (dy - S @ db)[valid]
        type_b.append({"name": name, "what": what, "u_rel": u_rel, "d_gain": db[1:],
                       "d_drift": dd, "d_resid": dr,
                       "u_drift": abs(dd) * u_rel,
                       "u_rms": abs(float(r0 @ dr) / (r0.size * rms0)) * u_rel if rms0 > 0 else 0.0})
    t_u = res.spec.temperature_calibration_U_pct / 100.0 / K
    t_src = "declared" if res.spec.temperature_calibration_declared else "class default"
    dyn = [j for j, tt in enumerate(fit.terms) if tt.tau_s > 0]
    terms = []
    for j, tt in enumerate(fit.terms):
        uA = sd[j + 1]
        uB2 = sum((b["u_rel"] * b["d_gain"][j]) ** 2 for b in type_b)
        if cands[tt.input].name != "spindle":
            # a temperature sensor reading a rise (1 + e) times too large: the gain per K
            # is that much smaller; the prediction is unchanged (the same sensor runs it)
            uB2 += (t_u * tt.gain) ** 2
        row = {"input": res.input_names[tt.input], "gain": tt.gain,
               "gain_U": K * float(np.sqrt(uA ** 2 + uB2)), "gain_U_typeA": K * uA,
               "tau_s": tt.tau_s, "tau_U_s": None}
        if j in dyn:
            s_lt = sd[ng + dyn.index(j)]
            # log tau's interval mapped to tau: the larger half-width (as identify's)
            row["tau_U_s"] = float(tt.tau_s * np.expm1(K * s_lt)) if K * s_lt < 20 else None
        terms.append(row)

    # the augmented inputs (parameters, then each sensor's relative sensitivity error) and
    # both figures as one function of them: what the cubature and the Monte Carlo evaluate
    npar = p.size
    pa, Ca = _augmented(p, C, type_b)

    def figures(q: np.ndarray) -> np.ndarray:
        e = q[npar:]
        pred = prediction(t, cands, fit, q[:npar])  # once: the drift has no offset
        dv = pred[i_max] - q[0] + sum(ek * b["d_drift"] for ek, b in zip(e, type_b))
        r = (y - pred)[valid]
        for ek, b in zip(e, type_b):
            r = r + ek * b["d_resid"]
        return np.array([dv, np.sqrt(np.mean(r ** 2))])

    _, u_cub = cubature5(figures, pa, Ca)

    def figure(value: float, uA: float, key: str, u_c: float) -> dict[str, Any]:
        return _figure_entry(value, uA, key, u_c, type_b, pa.size, "identification residuals (Type A)")

    out: dict[str, Any] = {
        "name": sig.name, "unit": sig.unit, "terms": terms,
        "drift": {"hours": float(rec.hours[i_max]),
                  **figure(float(d[i_max]), float(np.sqrt(max(jd @ C @ jd, 0.0))), "u_drift",
                           float(u_cub[0]))},
        "heldout_rms": figure(rms0, float(np.sqrt(max(jr @ C @ jr, 0.0))), "u_rms",
                              float(u_cub[1])),
        "temperature_calibration": f"U = {res.spec.temperature_calibration_U_pct:g} % (k = 2, "
                                   f"{t_src}): in the gains per K only",
        "n_eff": float(fit.n_eff)}
    return _with_monte_carlo(out, figures, pa, Ca, draws, seed)


def monte_carlo_figures(fn, p: np.ndarray, C: np.ndarray, draws: int, seed: int) -> np.ndarray:
    """fn at ``draws`` random draws x ~ N(p, C) (GUM S1), one row per draw; independent of
    :func:`cubature5` but for the distribution it samples."""
    rng = np.random.default_rng(seed)
    L = np.linalg.cholesky(C + 1e-12 * np.eye(C.shape[0]) * max(float(np.max(np.diag(C))), 1e-30))
    return np.array([np.atleast_1d(fn(p + L @ rng.standard_normal(p.size)))
                     for _ in range(draws)], dtype=float)


#: Analytic (cubature) and Monte Carlo further apart than this: the first order is not adequate
#: (GUM S1 validation) and the Monte Carlo's U is the one stated.
AGREEMENT = 0.10


def _state(d: dict[str, Any]) -> None:
    """The U a certificate states: the analytic (cubature) U when the Monte Carlo confirms it
    within AGREEMENT, else the Monte Carlo's (the figure is not near enough a quadratic in
    the inputs over their interval: the held-out RMS near its minimum, docs/uncertainty.md)."""
    ok = d["U"] > 0 and abs(d["U_mc"] / d["U"] - 1.0) <= AGREEMENT
    d["U_stated"] = d["U"] if ok else d["U_mc"]
    d["U_from"] = ("degree-5 cubature (the Monte Carlo agrees within 10 %)" if ok else
                   "Monte Carlo (the cubature is more than 10 % off: the figure is not near a "
                   "quadratic in the parameters over their interval)")


def _with_monte_carlo(out: dict[str, Any], figures, pa: np.ndarray, Ca: np.ndarray,
                      draws: int, seed: int) -> dict[str, Any]:
    """Add the Monte Carlo's U (k = 2) and 95 % interval of the drift and the held-out RMS
    (um) to ``out`` and state the U per the 10 % rule (:func:`_state`); with no draws, the
    cubature's U is the one stated."""
    if draws:
        F = monte_carlo_figures(figures, pa, Ca, draws, seed)
        for i, key in enumerate(("drift", "heldout_rms")):
            lo, hi = np.percentile(F[:, i], [2.5, 97.5])
            out[key]["U_mc"] = K * float(F[:, i].std(ddof=1))
            out[key]["interval95_mc"] = [float(lo), float(hi)]
        out["monte_carlo"] = {"draws": draws, "seed": seed}
        for key in ("drift", "heldout_rms"):
            _state(out[key])
    else:
        for key in ("drift", "heldout_rms"):
            out[key]["U_stated"] = out[key]["U"]
            out[key]["U_from"] = "degree-5 cubature (no Monte Carlo run)"
    return out


def thermal_uncertainty(res: Any, draws: int = 0, seed: int = 1) -> dict[str, Any]:
    """Every channel's and tilt's figures with U (k = 2) (module docstring), in the order
    the fit report lists them."""
    return {"method": ("the identification's covariance (offset, gains, log taus; s^2 inflated "
                       "for serial correlation) and the sensors' calibration, propagated by the "
                       "degree-5 cubature rule averaged over three frames (deterministic sigma "
                       "points; the budget lines and "
                       "U_first_order are the GUM first order); U = k u, k = 2"),
            "k": K,
            "budget": ("Type A: the residuals on the identification hours; Type B: each "
                       "displacement sensor's sensitivity (calibration_U_pct, refit linearly: "
                       "the gains are least squares in the data) and the temperature sensors' "
                       "sensitivity (gains per K only); both drawn in the Monte Carlo"),
            "signals": [(composed_uncertainty(res, s, draws, seed) if s.composed else
                         signal_uncertainty(res, s, draws, seed)) for s in
                        res.channels + [s for s in res.outputs if s.unit == "urad"]]}


def composed_uncertainty(res: Any, sig: Any, draws: int = 0, seed: int = 1) -> dict[str, Any]:
    """A channel predicted as its partner's model plus ``scale`` times the pair's tilt model
    (docs/thermal.md, "Issue 35, fifth round"): the drift and the held-out RMS with U
    (k = 2) from both fits' parameters (each fit's covariance as :func:`covariance`; the
    two fits taken as independent: they are fitted on different signals, the partner's
    displacement and the pair's difference) and every displacement sensor's sensitivity
    (the partner's data, the tilt's two channels and the channel's own samples), by the
    same cubature and Monte Carlo as :func:`signal_uncertainty`. The terms' U are their
    fits' (:attr:`ThermalTerm.gain_u95` at k = 2)."""
    rec = res.record
    t = rec.time_s
    cands = candidates_of(rec.temps_c, list(rec.temp_names), rec.speed_rpm)
    partner_name, tilt_name, scale = sig.composed
    by = {s.name: s for s in res.channels + res.outputs}
    partner, tilt = by[partner_name], by[tilt_name]
    f1 = partner.direct if partner.direct is not None else partner.fit
    f2 = tilt.fit
    p1, C1 = covariance(t, partner.measured, cands, f1, res.ident_mask)
    p2, C2 = covariance(t, tilt.measured, cands, f2, res.ident_mask)
    n1 = p1.size
    y = sig.measured
    valid = res.valid_mask

    def pred_of(q: np.ndarray, with_offset: bool = True) -> np.ndarray:
        return (prediction(t, cands, f1, q[:n1], with_offset)
                + scale * prediction(t, cands, f2, q[n1:], with_offset))

    p = np.concatenate([p1, p2])
    C = np.zeros((p.size, p.size))
    C[:n1, :n1], C[n1:, n1:] = C1, C2
    d = pred_of(p, with_offset=False)
    iv = np.flatnonzero(valid)
    i_max = int(iv[np.argmax(np.abs(d[iv]))])
    S1 = _states(t, cands, f1, p1[len(f1.terms) + 1:])
    S2 = _states(t, cands, f2, p2[len(f2.terms) + 1:])
    r0 = (y - pred_of(p))[valid]
    rms0 = float(np.sqrt(np.mean(r0 ** 2)))
    tilt_b = {name: (u_rel, what, dy) for name, what, u_rel, dy in type_b_inputs(res, tilt)}
    type_b = []
    for name, u_rel, what in [(f"{n} sensitivity", c.calibration_U_pct / 100.0 / K,
                               f"displacement sensor calibration, U = {c.calibration_U_pct:g} % "
                               f"(k = 2, {'declared' if c.calibration_declared else 'class default'})")
                              for n, c in res.spec.channels.items()
                              if n in (sig.name, partner_name)]:
        db1 = _refit_map(t, cands, f1, p1, res.ident_mask,
                         partner.measured if name == f"{partner_name} sensitivity"
                         else np.zeros(t.size))
        dy2 = tilt_b[name][2] if name in tilt_b else np.zeros(t.size)
        db2 = _refit_map(t, cands, f2, p2, res.ident_mask, dy2)
        dpred = S1 @ db1 + scale * (S2 @ db2)
        dd = float((S1[:, 1:] @ db1[1:] + scale * (S2[:, 1:] @ db2[1:]))[i_max])
        dy_me = y if name == f"{sig.name} sensitivity" else np.zeros(t.size)
        dr = (dy_me - dpred)[valid]
        type_b.append({"name": name, "what": what, "u_rel": u_rel, "d_drift": dd,
                       "d_resid": dr, "u_drift": abs(dd) * u_rel,
                       "u_rms": abs(float(r0 @ dr) / (r0.size * rms0)) * u_rel if rms0 > 0 else 0.0})

    def drift_at(q: np.ndarray) -> np.ndarray:
        return np.array([pred_of(q, with_offset=False)[i_max]])

    def rms_valid(q: np.ndarray) -> np.ndarray:
        return np.array([np.sqrt(np.mean((y - pred_of(q))[valid] ** 2))])

    jd = _jac(drift_at, p)[0]
    jr = _jac(rms_valid, p)[0]
    npar = p.size
    pa, Ca = _augmented(p, C, type_b)

    def figures(q: np.ndarray) -> np.ndarray:
        e = q[npar:]
        dv = pred_of(q[:npar], with_offset=False)[i_max] + sum(
            ek * b["d_drift"] for ek, b in zip(e, type_b))
        r = (y - pred_of(q[:npar]))[valid]
        for ek, b in zip(e, type_b):
            r = r + ek * b["d_resid"]
        return np.array([dv, np.sqrt(np.mean(r ** 2))])

    _, u_cub = cubature5(figures, pa, Ca)

    def figure(value: float, uA: float, key: str, u_c: float) -> dict[str, Any]:
        return _figure_entry(value, uA, key, u_c, type_b, pa.size,
                             "identification residuals of both fits (Type A)")

    terms = [{"input": res.input_names[tt.input], "gain": tt.gain,
              "gain_U": None if tt.gain_u95 is None else K / 1.96 * tt.gain_u95,
              "gain_U_typeA": None if tt.gain_u95 is None else K / 1.96 * tt.gain_u95,
              "tau_s": tt.tau_s,
              "tau_U_s": None if tt.tau_u95_s is None else K / 1.96 * tt.tau_u95_s}
             for tt in sig.fit.terms]
    out: dict[str, Any] = {
        "name": sig.name, "unit": sig.unit, "terms": terms,
        "composed": f"{partner_name} + {scale:g} x {tilt_name} (the two fits independent)",
        "drift": {"hours": float(rec.hours[i_max]),
                  **figure(float(d[i_max]), float(np.sqrt(max(jd @ C @ jd, 0.0))), "u_drift",
                           float(u_cub[0]))},
        "heldout_rms": figure(rms0, float(np.sqrt(max(jr @ C @ jr, 0.0))), "u_rms",
                              float(u_cub[1])),
        "temperature_calibration": "the partner's and the tilt's gains per K; the prediction "
                                   "does not change (the same sensors run it)",
        "n_eff": float(min(f1.n_eff, f2.n_eff))}
    return _with_monte_carlo(out, figures, pa, Ca, draws, seed)
