"""Pre-processing of one axis' term data before fitting (steps 3-5 of ``abbe fit``).

* :func:`average_runs`: bidirectional mean per target, reversal per target (the
  backlash estimate) and run-to-run spread (the noise estimate);
* :func:`detrend_line`: least-squares straightness detrending (paper Eq. 1);
* :func:`relative_to_reference`: values relative to the reference point;
* :func:`estimate_thermal`: thermal offset (um/K) and expansion (ppm/K) of the own
  positioning term from the run-to-run variation with the logged temperature;
* :func:`assess_reversal`: position dependence of the reversal (Chebyshev series over
  the travel, degree by BIC, significance by a chi-square test against the noise).

Arrays of runs have shape (n_runs, 2, T): axis 1 is the approach direction
(0 = ``+``, 1 = ``-``); T targets ascending. Units follow the term: um for
dx/dy/dz, urad for ex/ey/ez; positions mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Why squareness stays zero in a fit from 6D laser lines (notes.md §2).
SQUARENESS_NOTE = (
    "Squareness S_xy, S_xz, S_yz is unobservable from these lines: the least-squares "
    "line removed from each straightness (paper Eq. 1) also removes any squareness, so "
    "a model fitted from single 6D laser lines has none. It is left at zero; a circular "
    "(ballbar) or diagonal test reveals it.")


@dataclass
class RunStats:
    """Run averaging of one term (shape (T,) unless noted).

    mean: bidirectional mean per target (mean over runs and both directions).
    mean_up, mean_down: per-direction means. reversal: mean_up - mean_down per
    target (ISO 230-2 B_i; for the own positioning term, the backlash estimate).
    s_up, s_down: run-to-run standard deviations (n - 1). noise: pooled
    run-to-run standard deviation over all targets and both directions (scalar),
    the noise estimate.
    """

    mean: np.ndarray
    mean_up: np.ndarray
    mean_down: np.ndarray
    reversal: np.ndarray
    s_up: np.ndarray
    s_down: np.ndarray
    noise: float
    n_runs: int


def average_runs(runs: np.ndarray) -> RunStats:
    """Step 3: average the runs of one term. ``runs``: (n_runs, 2, T)."""
    r = np.asarray(runs, dtype=np.float64)
    if r.ndim != 3 or r.shape[1] != 2:
        raise ValueError(f"runs must be (n_runs, 2, T), got {r.shape}")
    n = r.shape[0]
    up, dn = r[:, 0, :].mean(axis=0), r[:, 1, :].mean(axis=0)
    if n > 1:
        s = r.std(axis=0, ddof=1)  # (2, T)
        noise = float(np.sqrt(np.mean(s ** 2)))
    else:
        s = np.zeros(r.shape[1:])
        noise = float("nan")
    return RunStats(mean=0.5 * (up + dn), mean_up=up, mean_down=dn, reversal=up - dn,
                    s_up=s[0], s_down=s[1], noise=noise, n_runs=n)


def detrend_line(pos_mm: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Step 4 (paper Eq. 1): remove the least-squares line k * p + b.

    ``pos_mm`` (T,), ``values`` (T,) in um. Returns (values - (k p + b), k, b)
    with k in um/mm (= mrad; x 1000 for urad) and b in um.
    """
    p = np.asarray(pos_mm, dtype=np.float64)
    y = np.asarray(values, dtype=np.float64)
    A = np.column_stack([p, np.ones_like(p)])
    (k, b), *_ = np.linalg.lstsq(A, y, rcond=None)
    return y - (k * p + b), float(k), float(b)


def value_at(pos_mm: np.ndarray, values: np.ndarray, at_mm: float) -> float:
    """Linear interpolation of ``values`` at ``at_mm`` (held at the ends)."""
    return float(np.interp(at_mm, np.asarray(pos_mm, float), np.asarray(values, float)))


def relative_to_reference(pos_mm: np.ndarray, values: np.ndarray, ref_mm: float,
                          value_at_ref: float | None = None) -> tuple[np.ndarray, float]:
    """Step 5: each term minus its value at the reference point's coordinate.

    ``value_at_ref`` defaults to the linear interpolation of ``values`` at
    ``ref_mm``; ``abbe fit`` passes the fitted model's value there, so the stored
    term is exactly zero at the reference point. Returns (values - v, v).
    """
    v = value_at(pos_mm, values, ref_mm) if value_at_ref is None else float(value_at_ref)
    return np.asarray(values, dtype=np.float64) - v, v


def estimate_thermal(runs: np.ndarray, temp_c: np.ndarray, pos_mm: np.ndarray, ref_mm: float,
                     tref_c: float, sigma: float = 3.0) -> dict:
    """Thermal offset o (um/K) and expansion alpha (ppm/K) of the own positioning term.

    ``runs`` (n_runs, 2, T) readings of the term (um), ``temp_c`` the same shape (deg C).
    Within-cell regression (a cell = one target and direction over the runs, so the
    geometric term cancels): dev(y) = o dev(dT) + alpha 1e-3 dev(dT (p - ref)), dT = T -
    tref_c. Significant when the temperature varies by >= 0.1 K and o or alpha exceeds
    ``sigma`` standard errors. Returns the estimates, standard errors, the correction
    to subtract from the readings (``correction_um``, same shape as ``runs``) and flags.
    """
    y = np.asarray(runs, dtype=np.float64)
    T = np.asarray(temp_c, dtype=np.float64)
    dT = T - float(tref_c)
    lever = (np.asarray(pos_mm, dtype=np.float64) - float(ref_mm))[None, None, :] * 1e-3
    cols = [dT, dT * lever]
    X = np.stack([(c - c.mean(axis=0, keepdims=True)).reshape(-1) for c in cols], axis=1)
    yd = (y - y.mean(axis=0, keepdims=True)).reshape(-1)
    out = {"tref_c": float(tref_c), "temp_range_k": float(np.ptp(T)), "significant": False,
           "offset_um_per_k": 0.0, "expansion_ppm_per_k": 0.0, "threshold_sigma": sigma}
    n_cells = y.shape[1] * y.shape[2]
    dof = yd.size - n_cells - 2
    if y.shape[0] < 2 or dof < 3 or out["temp_range_k"] < 0.1:
        out["note"] = "temperature constant or too few runs: no thermal term"
        out["correction_um"] = np.zeros_like(y)
        return out
    coef, *_ = np.linalg.lstsq(X, yd, rcond=None)
    e = yd - X @ coef
    s2 = float(e @ e) / dof
    try:
        cov = s2 * np.linalg.inv(X.T @ X)
    except np.linalg.LinAlgError:
        cov = np.full((2, 2), np.inf)
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    z = np.abs(coef) / np.where(se > 0, se, np.inf)
    sig = bool(np.any(z > sigma))
    out.update({"offset_um_per_k": float(coef[0]), "expansion_ppm_per_k": float(coef[1]),
                "se_offset_um_per_k": float(se[0]), "se_expansion_ppm_per_k": float(se[1]),
                "significant": sig})
    out["correction_um"] = (coef[0] * cols[0] + coef[1] * cols[1]) if sig else np.zeros_like(y)
    return out


def assess_reversal(stats: RunStats, pos_mm: np.ndarray, travel_mm: tuple[float, float],
                    sigma: float = 3.0, max_degree: int = 7) -> dict:
    """Is the reversal position dependent? The per-target reversals B_i (um) have the
    standard error s sqrt(2 / n) (s the run-to-run noise); a Chebyshev series of degree
    d = 1..min(max_degree, T - 2) over the travel is fitted to them (degree by BIC), and
    it is significant when its chi-square reduction has a p-value below the two-sided
    normal tail of ``sigma``. Returns the series (T0..Td, um, T0 = the mean level), its
    residual, the per-target values and flags."""
    from scipy import stats as st
    B = np.asarray(stats.reversal, dtype=np.float64)
    T = B.size
    n = stats.n_runs
    out: dict = {"per_target_um": [float(x) for x in B], "targets_mm": [float(x) for x in pos_mm],
                 "position_dependent": False, "degree": 0, "chebyshev_um": [float(B.mean())]}
    dmax = min(max_degree, T - 2)
    if n < 2 or not np.isfinite(stats.noise) or dmax < 1:
        out["note"] = "too few runs or targets to tell"
        return out
    se = max(float(stats.noise) * np.sqrt(2.0 / n), 1e-9)
    lo, hi = travel_mm
    u = (2.0 * np.clip(pos_mm, lo, hi) - lo - hi) / (hi - lo)
    rss0 = float(np.sum((B - B.mean()) ** 2)) / se ** 2
    best = (rss0, 0, np.array([B.mean()]))
    best_bic = rss0
    for d in range(1, dmax + 1):
        c = np.polynomial.chebyshev.chebfit(u, B, d)
        r = float(np.sum((B - np.polynomial.chebyshev.chebval(u, c)) ** 2)) / se ** 2
        bic = r + d * np.log(T)
        if bic < best_bic:
            best, best_bic = (r, d, c), bic
    r, d, c = best
    p = float(st.chi2.sf(rss0 - r, d)) if d else 1.0
    out.update({"se_per_target_um": se, "chi2_constant": rss0, "p_value": p,
                "threshold_sigma": sigma})
    if d and p < 2.0 * st.norm.sf(sigma):
        out.update({"position_dependent": True, "degree": int(d),
                    "chebyshev_um": [float(x) for x in c],
                    "residual_rms_um": float(np.sqrt(np.mean(
                        (B - np.polynomial.chebyshev.chebval(u, c)) ** 2)))})
    return out


def bin_targets(pos_mm: np.ndarray, runs: dict[str, np.ndarray], max_targets: int
                ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """A dense line reduced to at most ``max_targets`` bins of consecutive targets.

    ``pos_mm`` (T,) ascending; ``runs[t]`` (n_runs, 2, T). Bin k holds targets
    [k*T/B, (k+1)*T/B) (B bins of equal count, +-1); each bin is the mean of its
    positions and of its readings per run and direction. Linear in T.
    """
    p = np.asarray(pos_mm, dtype=np.float64)
    T = p.size
    if T <= max_targets:
        return p, runs
    starts = (np.arange(max_targets) * T) // max_targets
    counts = np.diff(np.append(starts, T))
    pb = np.add.reduceat(p, starts) / counts
    out = {t: np.add.reduceat(np.asarray(r, dtype=np.float64), starts, axis=2) / counts
           for t, r in runs.items()}
    return pb, out
