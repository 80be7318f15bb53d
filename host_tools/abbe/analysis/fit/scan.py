"""Period and order search for one axis: the design, CV scans, periodogram, one-SE rule.

Every model is a column subset of the library's exact basis (Chebyshev trend +
Fourier harmonics of a searched period): :func:`scan` scores (degree, harmonics,
period) combinations by leave-one-target-out cross-validation; the one-standard
-error rule picks the most parsimonious. Positions mm, values um / urad.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from abbe.analysis.fit.options import FitOptions
from abbe.model.table import AxisTable, FourierBlock, basis_matrix


@dataclass
class AxisDesign:
    """Quantities that depend only on the target positions (not on the readings).

    travel_mm: (first, last) target, the table travel; origin_mm: phase origin of
    block 0 (= travel start); spacing_mm: median target spacing; freqs: coarse
    frequency grid (1/mm); step: its spacing.
    """

    travel_mm: tuple[float, float]
    origin_mm: float
    spacing_mm: float
    freqs: np.ndarray
    step: float
    max_degree: int
    max_harmonics: int
    max_wave_degree: int
    samples_per_wavelength: float
    col_tol: float

    def hmax(self, f: np.ndarray | float) -> np.ndarray:
        """Most harmonics resolvable at frequency f (1/mm), capped at max_harmonics."""
        f = np.asarray(f, dtype=float)
        h = np.floor(1.0 / (f * self.samples_per_wavelength * self.spacing_mm) + 1e-9)
        return np.clip(h, 0, self.max_harmonics).astype(int)

    def axis_table(self, degree: int | None, period_mm: float | None, harmonics: int) -> AxisTable:
        """An AxisTable (no coefficients) with this structure."""
        blk = None
        if period_mm is not None and harmonics > 0:
            blk = FourierBlock(float(period_mm), float(self.origin_mm), int(harmonics))
        return AxisTable(travel_mm=self.travel_mm, trend_degree=degree, blocks=(blk, None))


def make_design(targets_mm: np.ndarray, opts: FitOptions) -> AxisDesign:
    """Design quantities for targets (T,) ascending, mm."""
    p = np.asarray(targets_mm, dtype=float)
    T = p.size
    span = float(p[-1] - p[0])
    spacing = float(np.median(np.diff(p)))
    fmax = 1.0 / (opts.samples_per_wavelength * spacing)
    fmin = 1.0 / (1.5 * span)
    step = 1.0 / (8.0 * span)
    freqs = np.arange(fmin, fmax + 1e-12, step) if fmax > fmin else np.zeros(0)
    return AxisDesign(travel_mm=(float(p[0]), float(p[-1])), origin_mm=float(p[0]),
                      spacing_mm=spacing, freqs=freqs, step=step,
                      max_degree=int(max(0, min(opts.max_degree, T - 3))),
                      max_harmonics=int(min(opts.max_harmonics, 8)),
                      max_wave_degree=int(opts.max_wave_degree),
                      samples_per_wavelength=opts.samples_per_wavelength, col_tol=opts.col_tol)


@dataclass
class Scan:
    """LOO cross-validation of every (degree d, harmonics h) at each frequency.

    cv, se, sse: (F, D+1, H+1, m): mean squared leave-one-target-out residual,
    its standard error, in-sample SSE; +inf where the model is inadmissible.
    """

    freqs: np.ndarray
    cv: np.ndarray
    se: np.ndarray
    sse: np.ndarray


def design_stack(design: AxisDesign, pos: np.ndarray, freqs: np.ndarray, D: int, H: int
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Trend columns (T, D+1) and Fourier columns (F, T, 2H) of the library basis.

    Both come from :func:`abbe.model.table.basis_matrix`: the trend from the axis'
    structure; the Fourier columns of all F periods in one call, through an
    auxiliary block of period 1 evaluated at x = (p - origin) / P, which is the
    same phase 2 pi (p - origin) / P. Positions must lie inside the travel.
    """
    pos = np.asarray(pos, dtype=float)
    trend = basis_matrix(design.axis_table(D, None, 0), pos)
    F, T = freqs.size, pos.size
    if H == 0 or F == 0:
        return trend, np.zeros((F, T, 0))
    x = np.outer(freqs, pos - design.origin_mm).reshape(-1)
    lo, hi = float(x.min()), float(x.max())
    aux = AxisTable(travel_mm=(lo, hi if hi > lo else lo + 1.0), trend_degree=None,
                    blocks=(FourierBlock(1.0, 0.0, H), None))
    return trend, basis_matrix(aux, x).reshape(F, T, 2 * H)


def scan(design: AxisDesign, pos: np.ndarray, Y: np.ndarray, freqs: np.ndarray,
         degrees: tuple[int, ...] | None = None, hg: int | None = None,
         want_sse: bool = False, want_cv: bool = True) -> Scan:
    """Exact LOO CV of all nested models at each frequency, batched.

    pos (T,) mm, Y (T, m) values. For each degree d one batched QR of the
    columns [T_0..T_d, sin1, cos1, ..., sin_hg, cos_hg] gives every h at once
    (prefixes of a QR are the QR of the prefix): fitted values and leverages of
    the model with h harmonics are cumulative sums over the first d + 1 + 2h
    columns of Q; the LOO residual is e_i / (1 - h_ii). All frequencies share
    one batch (harmonics a frequency cannot resolve are computed and marked
    inadmissible). ``sse`` is filled only if ``want_sse``; ``cv`` and ``se`` only if ``want_cv`` (SSE alone is cheap:
    ||y||^2 minus the cumulative squares of Q^T y).
    """
    pos = np.asarray(pos, dtype=float)
    Y = np.asarray(Y, dtype=float).reshape(pos.size, -1)
    T, m = Y.shape
    D = design.max_degree
    H = design.max_harmonics if hg is None else hg
    degrees = tuple(range(D + 1)) if degrees is None else degrees
    freqs = np.atleast_1d(np.asarray(freqs, dtype=float))
    F = freqs.size
    cv = np.full((F, D + 1, H + 1, m), np.inf)
    se = np.full_like(cv, np.inf)
    sse = np.full_like(cv, np.inf)
    if F == 0:
        return Scan(freqs, cv, se, sse)
    heff = np.minimum(np.maximum(design.hmax(freqs), 0), H)
    _scan_batch(design, pos, Y, freqs, degrees, int(heff.max()), heff, want_sse, want_cv,
                cv, se, sse)
    return Scan(freqs, cv, se, sse)


def _scan_batch(design: AxisDesign, pos: np.ndarray, Y: np.ndarray, freqs: np.ndarray,
                degrees: tuple[int, ...], H: int, heff: np.ndarray, want_sse: bool,
                want_cv: bool, cv: np.ndarray, se: np.ndarray, sse: np.ndarray) -> None:
    """The work of scan(): H harmonics computed at every frequency, models with
    more than heff[f] (the resolvable count) marked inadmissible. Columns after
    a prefix do not change the QR of the prefix, so the padding is harmless."""
    T, m = Y.shape
    F = freqs.size
    trend, four = design_stack(design, pos, freqs, design.max_degree, H)
    harm = np.arange(H + 1)
    for d in degrees:
        nh = min(H, (T - 2 - (d + 1)) // 2)  # most harmonics with >= 2 residual dof
        if d > design.max_wave_degree:
            nh = min(nh, 0)  # pure polynomial only: the same at every frequency
        if nh < 0:
            continue
        F_all = F
        if nh == 0:
            F = 1  # a pure polynomial: computed once, broadcast to every frequency below
        Ad = np.concatenate([np.broadcast_to(trend[None, :, :d + 1], (F, T, d + 1)),
                             four[:F, :, :2 * nh]], axis=2)
        Q, R = np.linalg.qr(Ad)
        norms = np.linalg.norm(Ad, axis=1)  # (F, k)
        ratio = np.abs(np.diagonal(R, axis1=1, axis2=2)) / np.maximum(norms, 1e-300)
        ok = np.logical_and.accumulate(ratio >= design.col_tol, axis=1)  # (F, k)
        c = np.swapaxes(Q, 1, 2) @ Y  # (F, k, m)
        if not want_cv:
            ends = d + 2 * harm[:nh + 1]  # last column of each prefix
            sseh = np.maximum(np.sum(Y ** 2, axis=0) - np.cumsum(c ** 2, axis=1)[:, ends], 0.0)
            adm = ok[:, ends] & (harm[None, :nh + 1] <= heff[:, None] if nh else True)
            if nh == 0:
                F = F_all
                adm = np.broadcast_to(adm, (F, 1))
                sseh = np.broadcast_to(sseh, (F, 1, m))
            sse[:, d, :nh + 1] = np.where(~adm[..., None], np.inf, sseh)
            continue
        # Group the columns: trend (group 0), then one sin/cos pair per harmonic.
        g_fit = np.empty((F, nh + 1, T, m))
        g_fit[:, 0] = Q[:, :, :d + 1] @ c[:, :d + 1]
        g_hat = np.empty((F, nh + 1, T))
        g_hat[:, 0] = np.sum(Q[:, :, :d + 1] ** 2, axis=2)
        if nh:
            Qp = Q[:, :, d + 1:].reshape(F, T, nh, 2).transpose(0, 2, 1, 3)  # (F, nh, T, 2)
            cp = c[:, d + 1:].reshape(F, nh, 2, m)
            g_fit[:, 1:] = Qp @ cp
            g_hat[:, 1:] = np.sum(Qp ** 2, axis=3)
        resid = Y[None, None] - np.cumsum(g_fit, axis=1)  # (F, nh+1, T, m)
        lev = 1.0 - np.cumsum(g_hat, axis=1)  # (F, nh+1, T)
        press2 = resid / np.maximum(lev, 1e-6)[..., None]
        press2 *= press2
        cvh = press2.mean(axis=2)  # (F, nh+1, m)
        press2 *= press2
        seh = np.sqrt(np.maximum(press2.mean(axis=2) - cvh ** 2, 0.0) / (T - 1))
        adm = ok[:, d + 2 * harm[:nh + 1]]  # (F, nh+1): every column up to the prefix
        adm &= lev.min(axis=2) > 1e-6
        if nh:
            adm &= harm[None, :nh + 1] <= heff[:, None]
        if nh == 0:
            F = F_all
            adm = np.broadcast_to(adm, (F, 1))
            cvh, seh = np.broadcast_to(cvh, (F, 1, m)), np.broadcast_to(seh, (F, 1, m))
            resid = np.broadcast_to(resid, (F,) + resid.shape[1:])
        bad = ~adm[..., None]
        cv[:, d, :nh + 1] = np.where(bad, np.inf, cvh)
        se[:, d, :nh + 1] = np.where(bad, np.inf, seh)
        if want_sse:
            sse[:, d, :nh + 1] = np.where(bad, np.inf, (resid ** 2).sum(axis=2))


def _n_params(shape: tuple[int, ...]) -> np.ndarray:
    """d + 1 + 2h on a (D+1, H+1) grid."""
    d = np.arange(shape[0])[:, None]
    h = np.arange(shape[1])[None, :]
    return (d + 1 + 2 * h).astype(float)


def one_se_select(cv: np.ndarray, se: np.ndarray, one_se: bool = True
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One-standard-error rule, vectorised over leading axes.

    cv, se: (..., D+1, H+1). Among the models whose CV <= min CV + SE(min), the
    one with the fewest parameters d + 1 + 2h (ties: the lower CV). Returns the
    chosen d, h, its CV and its SE, each of shape (...).
    """
    lead = cv.shape[:-2]
    D1, H1 = cv.shape[-2:]
    flat = cv.reshape(lead + (D1 * H1,))
    sef = se.reshape(lead + (D1 * H1,))
    i = np.argmin(flat, axis=-1)[..., None]
    thr = np.take_along_axis(flat, i, -1) + (np.take_along_axis(sef, i, -1) if one_se else 0.0)
    ok = np.isfinite(flat) & (flat <= thr)
    k = _n_params((D1, H1)).reshape(-1)
    kk = np.where(ok, k, np.inf)
    cand = ok & (kk == kk.min(axis=-1, keepdims=True))
    j = np.argmin(np.where(cand, flat, np.inf), axis=-1)
    return (j // H1, j % H1, np.take_along_axis(flat, j[..., None], -1)[..., 0],
            np.take_along_axis(sef, j[..., None], -1)[..., 0])


def one_se_choice(cv: np.ndarray, se: np.ndarray, one_se: bool = True) -> tuple[int, int]:
    """(d, h) by the one-standard-error rule for one term: cv, se of shape (D+1, H+1)."""
    d, h, _, _ = one_se_select(cv, se, one_se)
    return int(d), int(h)


def joint_score(s: Scan, norm: np.ndarray, one_se: bool = True
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Joint score of each frequency of a scan, its SE and the parameter count.

    At each f every term takes its one-SE choice over all admissible (d, h) (what
    would be stored); J(f) = sum_t CV_t / norm_t, each term counted in units of
    ``norm`` (its best CV over the candidate scan); SE_J = sqrt(sum (SE_t /
    norm_t)^2); K(f) = total parameters of the choices.
    """
    d, h, cvsel, sesel = one_se_select(s.cv.transpose(0, 3, 1, 2), s.se.transpose(0, 3, 1, 2),
                                       one_se)
    n = np.maximum(norm, 1e-300)[None, :]
    J = (cvsel / n).sum(axis=1)
    SE = np.sqrt(((sesel / n) ** 2).sum(axis=1))
    K = (d + 1 + 2 * h).sum(axis=1).astype(float)
    K = np.where(np.isfinite(J), K, np.inf)
    return J, SE, K


def pick_parsimonious(J: np.ndarray, SE: np.ndarray, K: np.ndarray, one_se: bool = True) -> int:
    """Index by the one-SE rule across frequencies: among J <= min J + SE(min),
    the fewest total parameters, then the lowest J."""
    i0 = int(np.argmin(J))
    thr = J[i0] + (SE[i0] if one_se else 0.0)
    ok = np.isfinite(J) & (J <= thr)
    kk = np.where(ok, K, np.inf)
    cand = ok & (kk == kk.min())
    return int(np.argmin(np.where(cand, J, np.inf)))


def _zoom(design: AxisDesign, f0: float, half: float, n: int = 5) -> np.ndarray:
    lo = max(design.freqs[0], f0 - half)
    hi = min(design.freqs[-1], f0 + half)
    return np.linspace(lo, hi, n)


def periodogram(design: AxisDesign, pos: np.ndarray, Y: np.ndarray, degree: int = 3
                ) -> np.ndarray:
    """Joint least-squares periodogram on the frequency grid: for each f, the sum
    over terms of the fraction of the residual (after a Chebyshev trend of
    ``degree``) explained by one sin/cos pair of frequency f. Shape (F,)."""
    pos = np.asarray(pos, dtype=float)
    Y = np.asarray(Y, dtype=float).reshape(pos.size, -1)
    d = min(degree, design.max_degree)
    trend, four = design_stack(design, pos, design.freqs, d, 1)
    Qt, _ = np.linalg.qr(trend)
    proj = np.eye(pos.size) - Qt @ Qt.T
    Rres = proj @ Y  # (T, m) residuals of the trend
    S = proj @ four  # (F, T, 2): sin/cos with the trend projected out
    a11 = np.sum(S[:, :, 0] ** 2, axis=1)
    a22 = np.sum(S[:, :, 1] ** 2, axis=1)
    a12 = np.sum(S[:, :, 0] * S[:, :, 1], axis=1)
    b1 = S[:, :, 0] @ Rres  # (F, m)
    b2 = S[:, :, 1] @ Rres
    det = a11 * a22 - a12 ** 2
    good = det > 1e-9 * np.maximum(a11 * a22, 1e-300)
    det = np.where(good, det, np.inf)
    expl = (a22[:, None] * b1 ** 2 - 2 * a12[:, None] * b1 * b2 + a11[:, None] * b2 ** 2) \
        / det[:, None]
    tot = np.maximum(np.sum(Rres ** 2, axis=0), 1e-300)
    return np.sum(expl / tot[None, :], axis=1)


def candidate_freqs(design: AxisDesign, pos: np.ndarray, Y: np.ndarray, n_peaks: int = 3,
                    peak_frac: float = 0.2, sub_frac: float = 0.1) -> np.ndarray:
    """Candidate fundamental frequencies from the joint periodogram.

    Heights are measured above the periodogram's median (its noise floor). The
    ``n_peaks`` highest local maxima reaching ``peak_frac`` of the highest
    (parabolically interpolated), plus their 1/2 and 1/3 (the fundamental of a
    wave whose 2nd or 3rd harmonic dominates) where the periodogram there still
    reaches ``sub_frac`` of the highest peak. Candidates closer than one grid
    step are merged (the stronger kept).
    """
    P = periodogram(design, pos, Y)
    F = P.size
    if F < 3:
        return design.freqs.copy()
    floor = float(np.median(P))
    peak = np.flatnonzero((P[1:-1] >= P[:-2]) & (P[1:-1] >= P[2:])) + 1
    if P[0] > P[1]:
        peak = np.append(peak, 0)
    if P[-1] > P[-2]:
        peak = np.append(peak, F - 1)
    if peak.size == 0:
        return design.freqs[[int(np.argmax(P))]]
    top = peak[np.argsort(-P[peak], kind="stable")][:n_peaks]
    height = P[top[0]] - floor
    cands: list[tuple[float, float]] = []  # (frequency, height)
    for i in top:
        if P[i] - floor < peak_frac * height and i != top[0]:
            continue
        f = design.freqs[i]
        if 0 < i < F - 1:  # parabolic interpolation of the peak
            den = P[i - 1] - 2 * P[i] + P[i + 1]
            if den < 0:
                f += 0.5 * design.step * (P[i - 1] - P[i + 1]) / den
        cands.append((f, P[i] - floor))
        for k in (2, 3):
            fk = f / k
            if fk >= design.freqs[0] - 1e-15:
                hk = float(np.interp(fk, design.freqs, P)) - floor
                if hk >= sub_frac * height:
                    cands.append((fk, hk))
    cands.sort(key=lambda c: -c[1])
    kept: list[float] = []
    for f, _ in cands:
        if all(abs(f - g) > design.step for g in kept):
            kept.append(f)
    return np.array(sorted(kept))


def search_period(design: AxisDesign, pos: np.ndarray, Y: np.ndarray,
                  one_se: bool = True) -> tuple[float | None, float]:
    """Frequency (1/mm) of block 0 by the joint score (:func:`joint_score`).

    Every candidate from the joint periodogram (:func:`candidate_freqs`) is
    refined on its own: the lowest J on a local grid (5 points over +/- half a
    grid step) fixes each term's orders, then :func:`refine_period` fits the
    frequency by least squares for those orders. The candidates are compared at
    their refined frequencies by the one-SE rule across frequencies
    (:func:`pick_parsimonious`): the fewest total parameters within one SE of
    the best J, so a multiple of the true period (which needs more harmonics) is
    not chosen for a noise-level gain. Returns (f, J), or (None, inf) if nothing
    is resolvable.
    """
    if design.freqs.size == 0 or design.max_harmonics == 0:
        return None, float("inf")
    cands = candidate_freqs(design, pos, Y)
    n = 5
    s = scan(design, pos, Y, np.concatenate([_zoom(design, c, design.step / 2, n)
                                             for c in cands]))
    norm = np.min(s.cv, axis=(0, 1, 2))
    J, _, _ = joint_score(s, norm, one_se)
    refined = []
    for q in range(cands.size):
        b = q * n + int(np.argmin(J[q * n:(q + 1) * n]))
        if not np.isfinite(J[b]):
            continue
        d, h, _, _ = one_se_select(s.cv[b].transpose(2, 0, 1), s.se[b].transpose(2, 0, 1), one_se)
        orders = list(zip(d.tolist(), h.tolist()))
        f = float(s.freqs[b])
        if any(hh for _, hh in orders):
            f = refine_period(design, pos, Y, f, orders)
        refined.append(f)
    if not refined:
        return None, float("inf")
    s = scan(design, pos, Y, np.array(refined))
    J, SE, K = joint_score(s, norm, one_se)
    if not np.any(np.isfinite(J)):
        return None, float("inf")
    i = pick_parsimonious(J, SE, K, one_se)
    return float(s.freqs[i]), float(J[i])


def search_period_ls(design: AxisDesign, pos: np.ndarray, Y: np.ndarray, d: int, h: int,
                     score) -> tuple[float | None, float]:
    """Frequency minimising ``score(scan)`` for models of degree d with h harmonics
    on the full grid, then two zooms. (None, inf) if never admissible."""
    if design.freqs.size == 0 or design.hmax(design.freqs[0]) < h:
        return None, float("inf")
    f, best = None, float("inf")
    grid = design.freqs
    for level in range(3):
        s = scan(design, pos, Y, grid, (d,), h, want_sse=True, want_cv=False)
        J = score(s)
        i = int(np.argmin(J))
        if J[i] < best:
            f, best = float(s.freqs[i]), float(J[i])
        if f is None:
            break
        grid = _zoom(design, f, design.step / 2 / 4 ** level)
    return f, best


def search_period_each(design: AxisDesign, pos: np.ndarray, Y: np.ndarray, d: int, h: int
                       ) -> list[float | None]:
    """Per column of Y, the frequency minimising the in-sample SSE of the (d, h)
    model (least-squares fit of the period): coarse grid and two zooms, all
    columns batched."""
    Y = np.asarray(Y, dtype=float).reshape(np.size(pos), -1)
    m = Y.shape[1]
    if design.freqs.size == 0 or design.hmax(design.freqs[0]) < h:
        return [None] * m
    s = scan(design, pos, Y, design.freqs, (d,), h, want_sse=True, want_cv=False)
    e = s.sse[:, d, h, :]  # (F, m)
    i = np.argmin(e, axis=0)
    best = e[i, np.arange(m)]
    f = np.where(np.isfinite(best), s.freqs[i], np.nan)
    for level in range(2):
        live = np.flatnonzero(np.isfinite(f))
        if live.size == 0:
            break
        grids = [_zoom(design, f[j], design.step / 2 / 4 ** level) for j in live]
        s = scan(design, pos, Y[:, live], np.concatenate(grids), (d,), h, want_sse=True,
                 want_cv=False)
        n = grids[0].size
        for q, j in enumerate(live):
            ej = s.sse[q * n:(q + 1) * n, d, h, q]
            k = int(np.argmin(ej))
            if ej[k] <= best[j]:
                best[j], f[j] = ej[k], s.freqs[q * n + k]
                if level == 1 and 0 < k < n - 1:  # parabola through the lowest three
                    fg = s.freqs[q * n:(q + 1) * n]
                    f[j] += _parabola_shift(ej[k - 1:k + 2], fg[1] - fg[0])
    return [None if not np.isfinite(v) else float(v) for v in f]


def refine_period(design: AxisDesign, pos: np.ndarray, Y: np.ndarray, f: float,
                  orders: list[tuple[int, int]]) -> float:
    """Least-squares refinement of the frequency for fixed orders: minimise
    sum_t SSE_t(f) / SSE_t(f0) over f0 +/- 1/4 grid step (9 points, then a
    parabola through the lowest three). Only terms with harmonics count."""
    wave = [j for j, (_, h) in enumerate(orders) if h > 0]
    degs = tuple(sorted({orders[j][0] for j in wave}))
    grid = _zoom(design, f, design.step / 4, 9)
    s = scan(design, pos, Y[:, wave], grid, degs, max(orders[j][1] for j in wave), want_sse=True,
             want_cv=False)
    e = np.stack([s.sse[:, orders[j][0], orders[j][1], q] for q, j in enumerate(wave)], axis=1)
    i0 = int(np.argmin(np.abs(grid - f)))
    if not np.all(np.isfinite(e)):
        return f
    score = (e / np.maximum(e[i0], 1e-300)).sum(axis=1)
    i = int(np.argmin(score))
    if 0 < i < grid.size - 1:
        return float(grid[i] + _parabola_shift(score[i - 1:i + 2], grid[1] - grid[0]))
    return float(grid[i])


def _parabola_shift(e: np.ndarray, step: float) -> float:
    """Offset from the middle of three equally spaced points (``step`` apart) to the
    vertex of the parabola through them, for a minimum at the middle one; 0 when there is
    no such vertex. A neighbour whose model is inadmissible at its frequency has SSE +inf:
    inf - inf in the formula was NaN and turned the refined frequency into "none", so
    the grid's own frequency is kept then."""
    if not np.all(np.isfinite(e)):
        return 0.0
    den = float(e[0] - 2.0 * e[1] + e[2])
    if not den > 0.0:
        return 0.0
    return 0.5 * step * float(e[0] - e[2]) / den
