"""The stacked measurement problem: every check's rows, nuisance columns, noise.

:class:`Problem` stacks the checks (measured vector, block-diagonal nuisance,
noise groups); :func:`estimate_noise` estimates each group's noise from repeated
runs or the scatter about a smooth fit. Values um / urad.
"""

from __future__ import annotations

import hashlib
import math
from collections import OrderedDict

import numpy as np
from scipy.signal import lfilter

from abbe.diagnose.checks import Check
from abbe.diagnose.effects import PredParams
from abbe.diagnose.evaluator import Evaluator
from abbe.diagnose.results import GapStats
from abbe.model.table import Table

#: Smallest noise level assumed (um or urad): float32 prediction resolution and
#: instrument resolution; keeps noiseless synthetic data from making everything significant.
NOISE_FLOOR = 0.01

#: Held-out splits in time (checks.py's fold names): a repeated-run line's early / late
#: runs, a circle's CCW trace then its CW trace.
TIME_SPLITS = ("runs", "direction")


#: qr_basis results by the bytes of their input (the same nuisance, fold and selected
#: set recur for every candidate of a selection step): (shape, tol, digest) -> basis
_QR_CACHE: OrderedDict[tuple[tuple[int, ...], float, bytes], np.ndarray] = OrderedDict()
_QR_CACHE_SIZE = 16


def qr_basis(A: np.ndarray, tol: float = 1e-10) -> np.ndarray:
    """Orthonormal basis of the column space of A (columns scaled first).

    The result is cached by A's bytes (an SVD of thousands of rows costs far more than a
    digest of them) and returned read-only: the same input gives the same array."""
    A = np.ascontiguousarray(A, dtype=np.float64)
    key = (A.shape, float(tol), hashlib.sha1(A.data, usedforsecurity=False).digest())
    Q = _QR_CACHE.get(key)
    if Q is not None:
        _QR_CACHE.move_to_end(key)
        return Q
    Q = _qr_basis(A, tol)
    Q.flags.writeable = False
    _QR_CACHE[key] = Q
    if len(_QR_CACHE) > _QR_CACHE_SIZE:
        _QR_CACHE.popitem(last=False)
    return Q


def _qr_basis(A: np.ndarray, tol: float) -> np.ndarray:
    if A.shape[1] == 0:
        return np.zeros((A.shape[0], 0))
    nrm = np.linalg.norm(A, axis=0)
    keep = nrm > 0
    A = A[:, keep] / nrm[keep]
    if A.shape[1] == 0:
        return np.zeros((A.shape[0], 0))
    u, s, _ = np.linalg.svd(A, full_matrices=False)
    return u[:, s > tol * max(s[0], 1e-300)]


def project_out(Q: np.ndarray, A: np.ndarray) -> np.ndarray:
    if Q.shape[1] == 0:
        return A.copy()
    return A - Q @ (Q.T @ A)


def lstsq_rss(Z: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, float]:
    """Least squares of r on Z: (coef, decrease of the residual sum of squares)."""
    if Z.shape[1] == 0:
        return np.zeros(0), 0.0
    coef, *_ = np.linalg.lstsq(Z, r, rcond=None)
    fit = Z @ coef
    return coef, float(fit @ fit)


def is_identifiable(A: np.ndarray, tol: float = 1e-4, ref_norm: np.ndarray | None = None) -> bool:
    """Full column rank with a sane condition (columns normalised).

    ``ref_norm``: the columns' scale before the nuisance (and the named effects) were
    projected out. Without it each column is normalised by its own norm, so a column the
    projection reduced to rounding noise (a sine sampled at its own period's nodes, a
    harmonic the set-up takes whole) looks as good as any; with it, a column must keep
    ``tol`` of its scale, and the set must be well conditioned at that scale."""
    if A.shape[1] == 0:
        return True
    if A.shape[0] < A.shape[1] or not np.all(np.isfinite(A)):
        return False
    nrm = np.linalg.norm(A, axis=0) if ref_norm is None else \
        np.broadcast_to(np.asarray(ref_norm, dtype=float), (A.shape[1],))
    if np.any(~(nrm > 0)):
        return False
    s = np.linalg.svd(A / nrm, compute_uv=False)
    if ref_norm is not None and not s[-1] > tol:
        return False
    return bool(s[-1] > tol * s[0])


class Problem:
    """All checks stacked: measured vector, nuisance (block diagonal), labels."""

    def __init__(self, checks: list[Check]) -> None:
        self.checks = checks
        self.offsets = np.cumsum([0] + [c.n for c in checks])
        self.N = int(self.offsets[-1])
        self.y = np.concatenate([c.y for c in checks])
        m = sum(c.nuisance.shape[1] for c in checks)
        self.nuis = np.zeros((self.N, m))
        col = 0
        groups, units, names = [], [], []
        for i, c in enumerate(checks):
            s = slice(self.offsets[i], self.offsets[i + 1])
            k = c.nuisance.shape[1]
            self.nuis[s, col:col + k] = c.nuisance
            col += k
            groups.append(c.group + len(names))
            names += c.group_names
            units += c.group_units
        self.group = np.concatenate(groups)
        self.group_names = names
        self.group_units = units
        self.um_rows = np.array([units[g] == "um" for g in self.group])
        self.check_of = np.concatenate([np.full(c.n, i) for i, c in enumerate(checks)])

    def split(self, level: int) -> tuple[np.ndarray, str] | None:
        """Fold labels (N,) of split ``level`` (0 = preferred) of every check."""
        labs, names = [], []
        for c in self.checks:
            keys = list(c.folds)
            if not keys:
                return None
            k = keys[min(level, len(keys) - 1)]
            labs.append(c.folds[k])
            names.append(k)
        uniq = sorted(set(names))
        return np.concatenate(labs), "; ".join(uniq)

    def split_in_time(self) -> tuple[np.ndarray, str] | None:
        """Fold labels (N,) of the split in time of every check that has one, or None when
        none has: a repeated-run line's early / late runs, a circle's CCW / CW trace (run
        one after the other); a check without one keeps its preferred split. The arbiter
        of a drift: a change in time must extrapolate from one fold in time to the other
        (docs/effects.md §3, "a drift needs a held-out split in time")."""
        labs, names, timed = [], [], False
        for c in self.checks:
            keys = list(c.folds)
            if not keys:
                return None
            k = next((x for x in keys if x.startswith(TIME_SPLITS)), keys[0])
            timed |= k.startswith(TIME_SPLITS)
            labs.append(c.folds[k])
            names.append(k)
        if not timed:
            return None
        return np.concatenate(labs), "; ".join(sorted(set(names)))

    def predict(self, ev: Evaluator, table: Table, pp: PredParams) -> np.ndarray:
        with ev.pinned(table):
            return np.concatenate([c.predict(ev, table, pp) for c in self.checks])

    def slice(self, i: int) -> slice:
        return slice(int(self.offsets[i]), int(self.offsets[i + 1]))


def contribution_rms(prob: Problem, contrib: np.ndarray) -> float:
    """Size of an effect's contribution (N,) to the predictions: its RMS (um) on the
    um-valued channel (noise group: a circle's radial deviation, a laser line's linear
    or straightness reading) where it shows most. An effect acts on the quantities that
    see it (a drift of Z on the Z line's linear reading, not on its straightness nor on
    an XY circle): an RMS over every sample would dilute it by the others and call a
    drift of several um "too small to matter" because a long ballbar trace sits beside
    its laser line."""
    best = 0.0
    for g, unit in enumerate(prob.group_units):
        if unit != "um":
            continue
        v = contrib[prob.group == g]
        if v.size:
            best = max(best, float(np.sqrt(np.mean(v * v))))
    return best


def observable_rms(prob: Problem, contrib: np.ndarray) -> float:
    """Size of an effect's contribution (N,) that the checks can see: its RMS (um) as in
    :func:`contribution_rms`, after each check's nuisance (ballbar centre and radius, laser
    zeros and set-up slopes, per-run zeros) is fitted to it and removed. The part a
    nuisance takes is indistinguishable from a set-up of the check: a straightness of Z
    moves every XY circle at one height by a constant, which its centre absorbs, so it
    cannot make the effect "large enough to matter" (docs/effects.md §3, the size of an
    effect)."""
    return contribution_rms(prob, remove_nuisance(prob, contrib))


def effect_size_um(prob: Problem, kind: str, contrib: np.ndarray) -> float:
    """The size (um RMS) the relevance rule (``min_effect_um``) judges an effect by.

    A new term of the model (straightness, scale, drift, ...) is judged by what the
    checks see of it (:func:`observable_rms`): the part each check's set-up takes is an
    extrapolation of the pattern fitted to the rest, and a small real pattern (model
    error, correlated noise) extrapolated that way is not "large".

    A tool offset is a declared length, not a pattern: its change moves the tool tip by
    the model's own angular error motions times the change (a lever law fixed by the
    laser lines that measured those motions, not by the circles), and that displacement
    is what a part machined at another height gets. The circles at several heights see
    it mostly as a shift of each circle, which their centres take (their set-up), so the
    set-up-removed RMS says "small" for a change of tens of mm. Its size is therefore
    taken at the tool tip, i.e. the contribution at the checks' positions with nothing
    removed (:func:`contribution_rms`); whether the change is real is the evidence
    ratio's business (declared prior, model-angle uncertainty), not the size rule's
    (docs/effects.md §3, the size of an effect).

    A thermal drift measured by repeated runs is sized on those runs with nothing
    removed (the drift between the runs, which their zeros take, moves the tool too)."""
    if kind == "tool_offset":
        return contribution_rms(prob, contrib)
    seen = observable_rms(prob, contrib)
    if kind == "thermal":
        # A drift is a change of the machine in time, not a pattern: what a repeated-run
        # check's per-run zeros take of it (the drift between the runs) is a displacement
        # of the tool all the same, and its time course is what the held-out split of
        # those checks (fit on the early runs, judge the late ones) has validated. On the
        # rows of such checks the drift is sized with nothing removed; a drift seen only
        # within circle traces (whose split is by sectors, not by time) keeps the seen
        # size: its extrapolation in time is not checked (docs/effects.md §3, size).
        timed = np.zeros(prob.N, dtype=bool)
        for i, c in enumerate(prob.checks):
            if any(k.startswith("runs") for k in c.folds):
                timed[prob.slice(i)] = True
        if np.any(timed):
            seen = max(seen, contribution_rms(prob, np.where(timed, contrib, 0.0)))
    return seen


def remove_nuisance(prob: Problem, r: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
    """Residual with each check's nuisance fitted (unweighted per noise group) and removed.
    ``rows``: only these rows take part (others returned as NaN)."""
    out = np.full(prob.N, np.nan)
    for i, c in enumerate(prob.checks):
        s = prob.slice(i)
        idx = np.arange(s.start, s.stop)
        if rows is not None:
            idx = idx[rows[s]]
        if idx.size == 0:
            continue
        A = prob.nuis[idx][:, np.any(prob.nuis[idx] != 0, axis=0)]
        rr = r[idx]
        if A.shape[1]:
            coef, *_ = np.linalg.lstsq(A, rr, rcond=None)
            rr = rr - A @ coef
        out[idx] = rr
    return out


def gap_stats(prob: Problem, r_clean: np.ndarray, rows: np.ndarray | None = None) -> GapStats | None:
    sel = prob.um_rows & np.isfinite(r_clean)
    if rows is not None:
        sel &= rows
    if not np.any(sel):
        return None
    v = r_clean[sel]
    return GapStats(float(np.sqrt(np.mean(v * v))), float(np.max(np.abs(v))), int(v.size))


def estimate_noise(prob: Problem, r: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict[str, dict[str, float]]]:
    """Noise standard deviation and autocorrelation inflation per noise group.

    Groups with repeated readings (laser runs): pooled within-cell scatter of the
    residual (same channel, target and direction in every run) about the cell means and
    an offset, slope and curvature per pass (run and direction; a drift between runs
    moves whole passes and is not noise), with n - rank degrees of freedom; readings
    more than REJECT_Z robust sigmas off are left out (reported as ``robust`` with
    ``rejected_readings``): a few wild readings cannot inflate the estimate. Ballbar groups: the
    scatter of each direction's residual about a saturated smooth fit (Fourier series
    in the angle, up to min(40, n/8) harmonics), read as AR(1) noise through that fit:
    sigma and the lag-1 correlation rho solve its expected scatter and lag-1 sum (the
    fit takes the correlated noise's slow part; _ar1_moments), unless the CW - CCW
    difference rejects that rho for a smaller one (_pair_loglik: a fine pattern both
    traces share); the variance is inflated by (1 + rho) / (1 - rho). Returns (sigma (G,),
    inflation (G,), report dict). ``r`` is the current residual (N,).
    """
    G = len(prob.group_names)
    robust = np.zeros(G, dtype=int)
    pair: dict[int, float | None] = {}
    sig = np.full(G, NOISE_FLOOR)
    infl = np.ones(G)
    dof = np.zeros(G)
    for i, c in enumerate(prob.checks):
        s = prob.slice(i)
        rr = r[s]
        for g in np.unique(c.group):
            gg = int(g) + int(prob.group[s][0] - c.group[0])
            sel = c.group == g
            cells = c.cell[sel]
            x = rr[sel]
            if np.all(cells >= 0):
                _, inv, cnt = np.unique(cells, return_inverse=True, return_counts=True)
                means = np.bincount(inv, weights=x) / cnt
                dev = x - means[inv]
                d = x.size - cnt.size
                passes = _pass_labels(c, sel)
                n_rej = 0
                if passes is not None:
                    dev_p, d_p, n_rej_p = _about_cells_and_passes(inv, passes, c.x[sel], x)
                    if d_p >= max(8, d // 4):
                        dev, d, n_rej = dev_p, d_p, n_rej_p
                else:
                    rob = _robust_cell_sigma(dev, cnt[inv])
                    if rob is not None and cnt.min() >= 3:
                        z = np.abs(dev) / np.sqrt((cnt[inv] - 1.0) / cnt[inv])
                        rej = z > REJECT_Z * rob
                        if rej.any():
                            dev, d, n_rej = dev[~rej], d - int(rej.sum()), int(rej.sum())
                if d >= 2:
                    sd = math.sqrt(float(dev @ dev) / d)
                    if n_rej:
                        robust[gg] = n_rej
                    sig[gg] = max(NOISE_FLOOR, sd)
                    dof[gg] = d
                    continue
            # Saturated smooth fit per direction (ballbar) / per run and direction.
            ss, d_tot, rho_num, rho_den = 0.0, 0, 0.0, 0.0
            resid_parts: list[np.ndarray] = []
            moments: list[np.ndarray] = []
            moments0: list[np.ndarray] = []
            total0 = 0.0
            labels = c.direction[sel].astype(str)
            xs = c.x[sel]
            for lab in np.unique(labels):
                m = labels == lab
                xv, rv = xs[m], x[m]
                n = xv.size
                K = int(min(40, max(1, n // 8)))
                if c.kind == "ballbar":
                    th = np.radians(xv)
                    cols = [np.ones(n)]
                    for k in range(1, K + 1):
                        cols += [np.cos(k * th), np.sin(k * th)]
                else:
                    u = (2 * xv - xv.min() - xv.max()) / max(np.ptp(xv), 1e-9)
                    cols = list(np.polynomial.chebyshev.chebvander(u, min(K, n - 2)).T)
                A = np.stack(cols, axis=1)
                coef, *_ = np.linalg.lstsq(A, rv, rcond=None)
                e = rv - A @ coef
                resid_parts.append(e)
                ss += float(e @ e)
                d_tot += max(n - A.shape[1], 0)
                rho_num += float(e[1:] @ e[:-1])
                rho_den += float(e @ e)
                moments.append(_ar1_moments(A))
                # the same about the fit's first three columns (a circle's centre and radius)
                A0 = A[:, :3]
                e0 = rv - A0 @ np.linalg.lstsq(A0, rv, rcond=None)[0]
                total0 += float(e0 @ e0)
                moments0.append(_ar1_moments(A0)[0])
            if d_tot >= 2:
                ee = np.concatenate(resid_parts)
                rob = 1.4826 * float(np.median(np.abs(ee))) * math.sqrt(x.size / d_tot)
                rej = np.abs(ee) > REJECT_Z * rob * math.sqrt(d_tot / x.size)
                if rej.any():
                    robust[gg] = int(rej.sum())
                # AR(1) noise through the saturated fit (a projection): its expected scatter
                # and lag-1 sum are sigma^2 tr(M R) and sigma^2 tr(S M R M) (_ar1_moments);
                # rho solves their ratio, sigma^2 = scatter / tr(M R). White noise: rho 0,
                # tr(M R) = n - rank, the plain estimate.
                mom = np.sum(moments, axis=0)
                rho = _ar1_rho(rho_num / rho_den if rho_den > 0 else 0.0, mom)
                ll = _pair_loglik(xs, labels, x) if c.kind == "ballbar" and rho > 0 else None
                if ll is not None:
                    # a pattern both traces share, finer than the saturated fit (a short
                    # cyclic error), reads as correlated noise in each trace; it cancels in
                    # the CW - CCW difference. When that difference rejects the traces'
                    # rho at the selection's level (log LR >= log 19) for a smaller one,
                    # the difference's rho holds.
                    k = int(np.argmax(ll))
                    if _AR1_GRID[k] < rho and ll[k] - float(np.interp(rho, _AR1_GRID, ll)) \
                            >= PAIR_LOG_LR:
                        rho = float(_AR1_GRID[k])
                kept = max(d_tot - int(rej.sum()), 1) / d_tot
                # the noise cannot leave more than all the scatter there is: sigma(rho)^2 x
                # the expected scatter about the centre and radius alone must not exceed the
                # scatter observed about them (a noise whose fast part is damped, e.g. by the
                # instrument's filter, is no AR(1): its slow part would be over-extrapolated)
                ss_kept = ss - float(ee[rej] @ ee[rej])
                need = ss_kept / np.maximum(mom[0] * kept, 1.0) * np.sum(moments0, axis=0)
                if rho > 0 and float(np.interp(rho, _AR1_GRID, need)) > total0:
                    ok = _AR1_GRID[need <= total0]
                    rho = float(ok.max()) if ok.size else 0.0
                trace_mr = float(np.interp(rho, _AR1_GRID, mom[0]))
                sd = math.sqrt(ss_kept / max(trace_mr * kept, 1.0))
                sig[gg] = max(NOISE_FLOOR, sd)
                dof[gg] = d_tot
                infl[gg] = (1 + rho) / (1 - rho)
            if c.kind == "ballbar":
                pair[gg] = _pair_sigma(xs, labels, x)
    rep = {prob.group_names[g]: {"sigma": round(float(sig[g]), 5), "unit": prob.group_units[g],
                                 "inflation": round(float(infl[g]), 4), "dof": int(dof[g])}
           for g in range(G)}
    for g, v in pair.items():
        if v is not None:
            rep[prob.group_names[g]]["pair_sigma"] = round(float(v), 5)
    for g in np.flatnonzero(robust):
        rep[prob.group_names[g]]["robust"] = True
        rep[prob.group_names[g]]["rejected_readings"] = int(robust[g])
    return sig, infl, rep


#: Lag-1 correlations at which the saturated fit's effect on AR(1) noise is tabulated
#: (the estimate is clipped to [0, 0.9] as before: 0.9 bounds the inflation at 19)
_AR1_GRID = np.linspace(0.0, 0.9, 19)
#: _ar1_moments results by the fit's design (the same angles recur at every step)
_AR1_CACHE: OrderedDict[bytes, np.ndarray] = OrderedDict()


def _ar1_moments(A: np.ndarray) -> np.ndarray:
    """Expected scatter and lag-1 sum of unit AR(1) noise (in reading order) about the
    least-squares fit of the columns ``A`` (n, p), at each rho of _AR1_GRID: rows
    tr(M R) and tr(S M R M), M = I - Q Q' the fit's residual projection, R_ij =
    rho^|i-j|, S the symmetric lag-1 matrix (1/2 beside the diagonal). (2, grid).
    R Q by a forward and a backward first-order recursion (O(n p), no n x n matrix)."""
    key = (hashlib.sha1(np.ascontiguousarray(A).tobytes(), usedforsecurity=False).digest()
           + str(A.shape).encode())
    hit = _AR1_CACHE.get(key)
    if hit is not None:
        return hit
    n = A.shape[0]
    Q = qr_basis(A)
    SQ = 0.5 * (np.vstack([Q[1:], np.zeros((1, Q.shape[1]))])
                + np.vstack([np.zeros((1, Q.shape[1])), Q[:-1]]))
    QSQ = Q.T @ SQ
    out = np.zeros((2, _AR1_GRID.size))
    for k, rho in enumerate(_AR1_GRID):
        RQ = (lfilter([1.0], [1.0, -rho], Q, axis=0)
              + lfilter([1.0], [1.0, -rho], Q[::-1], axis=0)[::-1] - Q)
        QRQ = Q.T @ RQ
        out[0, k] = n - float(np.trace(QRQ))
        # tr(S M R M) with M R M = R - Q Q'R - R Q Q' + Q (Q'R Q) Q'
        out[1, k] = ((n - 1) * rho - 2.0 * float(np.sum(SQ * RQ)) + float(np.sum(QSQ * QRQ)))
    _AR1_CACHE[key] = out
    while len(_AR1_CACHE) > 64:
        _AR1_CACHE.popitem(last=False)
    return out


#: log likelihood ratio at which the CW - CCW difference overrules the traces' noise
#: correlation: the selection's level, log((1 - alpha) / alpha) at alpha = 0.05
PAIR_LOG_LR = math.log(19.0)


def _pair_loglik(ang: np.ndarray, labels: np.ndarray, r: np.ndarray) -> np.ndarray | None:
    """Log likelihood, at each rho of _AR1_GRID, of the CW/CCW pair's difference above the
    saturated fit's harmonics (Whittle's, from its periodogram over the circle).

    d = r_ccw - B r_cw (B: the CW trace taken at the CCW angles, periodic linear
    interpolation, as _pair_sigma); each trace's noise AR(1) in its reading order,
    independent of the other's, so d's spectrum is sigma^2 S(w) (1 + |H(w)|^2), S the
    AR(1) spectrum, |H|^2 = (1 - f)^2 + f^2 + 2 f (1 - f) cos w the interpolation's at the
    readings' fractions f (mean); sigma^2 profiled out. The harmonics up to the saturated
    fit's K (what it takes) are left out. None when a direction has fewer than 16 readings
    or fewer than 4 harmonics remain."""
    a, b = labels == "ccw", labels == "cw"
    if a.sum() < 16 or b.sum() < 16:
        return None
    o_a = np.argsort(ang[a])
    aa = ang[a][o_a]
    o = np.argsort(ang[b])
    ab = ang[b][o]
    n = aa.size
    K = int(min(40, max(1, n // 8)))
    ks = np.arange(K + 1, (n - 1) // 2 + 1)
    if ks.size < 4:
        return None
    d = r[a][o_a] - np.interp(aa, ab, r[b][o], period=360.0)
    j = np.searchsorted(ab, aa)
    lo = np.where(j > 0, ab[np.maximum(j - 1, 0)], ab[-1] - 360.0)
    hi = np.where(j < ab.size, ab[np.minimum(j, ab.size - 1)], ab[0] + 360.0)
    f = np.clip((aa - lo) / np.maximum(hi - lo, 1e-12), 0.0, 1.0)
    w = 2.0 * np.pi * ks / n
    h2 = float(np.mean((1 - f) ** 2 + f ** 2)) + float(np.mean(2 * f * (1 - f))) * np.cos(w)
    per = np.abs(np.fft.rfft(d)[ks]) ** 2 / n
    g = _AR1_GRID[:, None]
    spec = (1 - g ** 2) / (1 - 2 * g * np.cos(w)[None, :] + g ** 2) * (1 + h2)[None, :]
    m = ks.size
    return -np.sum(np.log(spec), axis=1) - m * np.log(np.mean(per[None, :] / spec, axis=1))


def _ar1_rho(ratio: float, mom: np.ndarray) -> float:
    """Lag-1 correlation of AR(1) noise whose expected lag-1 sum over scatter, about the
    saturated fit, is the observed ``ratio`` (``mom`` from _ar1_moments, summed over the
    traces); clipped to the grid's [0, 0.9]."""
    f = mom[1] / np.maximum(mom[0], 1e-12)
    if ratio <= f[0]:
        return 0.0
    if ratio >= f[-1]:
        return float(_AR1_GRID[-1])
    return float(np.interp(ratio, f, _AR1_GRID))


#: Readings this many robust sigmas off (Huber fit / median absolute deviation) are
#: left out of the noise estimate: for normal noise none is (P < 1e-6 per reading), a
#: few wild readings cannot inflate it.
REJECT_Z = 5.0


def _pass_labels(c: Check, sel: np.ndarray) -> np.ndarray | None:
    """Pass (run, direction) label of each selected reading of a repeated laser check, or
    None when there are too few runs / targets for a line per pass."""
    runs = np.asarray(c.run)[sel]
    dirs = np.asarray(c.direction)[sel].astype(str)
    if np.unique(runs).size < 3:
        return None
    lab = np.unique(np.char.add(runs.astype(str), dirs), return_inverse=True)[1]
    per = np.bincount(lab)
    if per.min() < 5:
        return None
    return lab


def _about_cells_and_passes(cell_inv: np.ndarray, passes: np.ndarray, pos: np.ndarray,
                            x: np.ndarray) -> tuple[np.ndarray, int, float]:
    """Deviations of the readings about the cell means plus an offset, a slope and a
    curvature per pass (a drift between runs moves whole passes, it is not noise), with
    the readings more than REJECT_Z robust sigmas off left out (robust sigma: the median
    |residual| of a Huber fit, calibrated for this design by simulating unit normal
    noise); returns (deviations of the readings kept, n_kept - rank, readings left out)."""
    n = x.size
    C = np.zeros((n, int(cell_inv.max()) + 1))
    C[np.arange(n), cell_inv] = 1.0
    P = np.zeros((n, int(passes.max()) + 1))
    P[np.arange(n), passes] = 1.0
    u = (pos - pos.mean()) / max(float(np.ptp(pos)), 1e-9)
    A = np.hstack([C, P, P * u[:, None], P * (u * u)[:, None]])
    key = hashlib.sha1(A.tobytes()).hexdigest()
    if key not in _ROBUST_FACTOR:
        rng = np.random.default_rng(2301)
        _ROBUST_FACTOR[key] = float(np.median([np.median(np.abs(_huber(A, rng.normal(size=n))))
                                                for _ in range(15)]))
    er = _huber(A, x)
    rob = float(np.median(np.abs(er))) / _ROBUST_FACTOR[key]
    keep = np.abs(er) <= REJECT_Z * rob
    coef, _, rank, _ = np.linalg.lstsq(A[keep], x[keep], rcond=None)
    e = x[keep] - A[keep] @ coef
    return e, int(keep.sum() - rank), int((~keep).sum())


_ROBUST_FACTOR: dict[str, float] = {}


def _huber(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Residuals of a Huber IRLS fit of x on A (one wild reading is not smeared over the
    other readings of its pass, as in least squares)."""
    coef, *_ = np.linalg.lstsq(A, x, rcond=None)
    er = x - A @ coef
    for _ in range(10):
        k = 1.345 * max(1.4826 * float(np.median(np.abs(er))), 1e-12)
        sw = np.sqrt(np.minimum(1.0, k / np.maximum(np.abs(er), 1e-300)))
        coef, *_ = np.linalg.lstsq(A * sw[:, None], x * sw, rcond=None)
        er = x - A @ coef
    return er


def _robust_cell_sigma(dev: np.ndarray, n_cell: np.ndarray) -> float | None:
    """Noise sigma from deviations about cell means, robustly: 1.4826 x the median of
    |dev| / sqrt((n - 1) / n) (the deviation of one of n readings from their mean has
    variance sigma^2 (n - 1) / n); cells of one reading carry no information."""
    m = n_cell >= 2
    if m.sum() < 4:
        return None
    z = np.abs(dev[m]) / np.sqrt((n_cell[m] - 1.0) / n_cell[m])
    return 1.4826 * float(np.median(z))


def _pair_sigma(ang: np.ndarray, labels: np.ndarray, r: np.ndarray) -> float | None:
    """Cross-check of a ballbar's noise from its CW/CCW pair: the CW residual taken at the
    CCW angles (periodic interpolation), the difference of the pair about a smooth fit,
    divided by sqrt(2). Direction-dependent effects not yet modelled inflate it."""
    a, b = labels == "ccw", labels == "cw"
    if a.sum() < 16 or b.sum() < 16:
        return None
    o = np.argsort(ang[b])
    cw = np.interp(ang[a], ang[b][o], r[b][o], period=360.0)
    d = r[a] - cw
    th = np.radians(ang[a])
    K = int(min(40, max(1, d.size // 8)))
    cols = [np.ones(d.size)] + [f(k * th) for k in range(1, K + 1) for f in (np.cos, np.sin)]
    A = np.stack(cols, axis=1)
    e = d - A @ np.linalg.lstsq(A, d, rcond=None)[0]
    dof = d.size - A.shape[1]
    if dof < 2:
        return None
    return math.sqrt(float(e @ e) / dof / 2.0)
