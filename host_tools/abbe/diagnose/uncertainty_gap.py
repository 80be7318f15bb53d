"""u of ``abbe diagnose``'s gap figures (moved from :mod:`abbe.diagnose.uncertainty`):
the RMS and the max |residual| of the um-valued samples, each check's set-up nuisance
removed, under the readings' noise of a re-measurement and the instruments' inputs: the
random ones (noise, a target's linearity, a reading's resolution) through the exact
variance of the RMS' quadratic form and the competition of the samples for the max, the
common ones (scale, drift, calibration) through the exact figures over their distribution.

Units: um.
"""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from abbe.diagnose.problem import remove_nuisance
from abbe.diagnose.uncertainty_inputs import K, Inputs


def _nuisance_removal_T(prob: Any, v: np.ndarray) -> np.ndarray:
    """P_n^T v = P_n v (each check's unweighted least-squares removal is symmetric)."""
    return np.nan_to_num(remove_nuisance(prob, v))


def _random_parts(prob: Any, inp: Inputs, um: np.ndarray) -> dict[str, tuple[np.ndarray, list[np.ndarray]]]:
    """Per instrument input acting as a random error of the samples (a target's linearity,
    a reading's resolution): its variance per sample (N,) and its blocks (rows that share
    one error), for the quadratic form of an RMS and the competition of a max."""
    out: dict[str, tuple[np.ndarray, list[np.ndarray]]] = {}
    for g in inp.grouped:
        v = np.where(g.labels >= 0, g.half_um ** 2 / 3.0, 0.0) * um
        blocks = [np.flatnonzero((g.labels == lab) & um) for lab in np.unique(g.labels[g.labels >= 0])]
        out[f"{g.check}: {g.name}"] = (v, blocks)
    for r in inp.per_reading:
        v = (r.half_um ** 2 / 3.0) * um
        out[f"{r.check}: {r.name}"] = (v, [])
    return out


def _max_abs_variance(r: np.ndarray, um: np.ndarray,
                      rand: dict[str, tuple[np.ndarray, list[np.ndarray]]]) -> float:
    """Variance of max_i |r_i + e_i| over the um samples: e_i normal (the noise and the
    resolution, variance summed) plus, where a block of samples shares one rectangular
    error (a target's linearity), that error: within a block the max is the error plus the
    largest of its normals; blocks, and the two signs, independent. CDF on a grid."""
    from scipy.special import log_ndtr
    v_norm = np.zeros(r.size)
    block_of = np.full(r.size, -1)
    half: list[float] = []
    for name, (v, blocks) in rand.items():
        if blocks:
            for b in blocks:
                block_of[b] = len(half)
                half.append(math.sqrt(3.0 * float(v[b[0]])))
        else:
            v_norm = v_norm + v
    idx = np.flatnonzero(um)
    sd = np.maximum(np.sqrt(v_norm[idx]), 1e-9)
    a = np.array([half[b] if b >= 0 else 0.0 for b in block_of[idx]])
    x_all = np.concatenate([r[idx], -r[idx]])
    sd_all, a_all = np.concatenate([sd, sd]), np.concatenate([a, a])
    blk = np.concatenate([block_of[idx], block_of[idx] + len(half)])
    blk = np.where(np.concatenate([block_of[idx], block_of[idx]]) < 0, -1, blk)
    lo = float(np.max(x_all - 9 * sd_all - a_all))
    hi = float(np.max(x_all + 9 * sd_all + a_all))
    keep = x_all + 9 * sd_all + a_all >= lo
    amax = float(np.max(a_all[keep])) if np.any(keep) else 0.0
    y = np.linspace(lo - amax, hi + amax, 2001)
    hstep = y[1] - y[0]
    logF = np.zeros_like(y)
    single = keep & (blk < 0)
    xs, ss = x_all[single], sd_all[single]
    for j in range(0, xs.size, 256):
        logF += np.sum(log_ndtr((y[:, None] - xs[None, j:j + 256]) / ss[None, j:j + 256]), axis=1)
    for b in np.unique(blk[keep & (blk >= 0)]):
        m = keep & (blk == b)
        FM = np.exp(np.sum(log_ndtr((y[:, None] - x_all[m][None, :]) / sd_all[m][None, :]), axis=1))
        ab = float(a_all[m][0])
        w = int(round(ab / hstep))
        if w >= 1:  # the mean of F_M over [y - a, y + a]: the rectangular error added
            C = np.concatenate([[0.0], np.cumsum(FM)])
            i = np.arange(y.size)
            i0, i1 = np.clip(i - w, 0, y.size), np.clip(i + w + 1, 0, y.size)
            FB = (C[i1] - C[i0] + np.maximum(0, (i + w + 1) - y.size)) / (2 * w + 1)
        else:
            FB = FM
        logF += np.log(np.maximum(FB, 1e-300))
    F = np.exp(logF)
    top = y[-1]
    mean = top - np.trapezoid(F, y)
    second = top * top - np.trapezoid(2 * y * F, y)
    return max(float(second - mean * mean), 0.0)


def _systematic_gap_lines(r: np.ndarray, um: np.ndarray, inp: Inputs,
                          forward: Callable[[np.ndarray], np.ndarray]) -> dict[str, np.ndarray]:
    """Each input common to many samples acting alone on the residual r + t M p: the
    standard deviation of (RMS, max |r|) over t's distribution (12-point Gauss-Legendre for
    a rectangular t, Gauss-Hermite for a normal one) of the exact figures, not a
    derivative at t's centre: a residual left by a least-squares fit sits near a minimum
    in some directions (a scale error nearly orthogonal to it), where the derivative is
    near 0 and the spread is not."""
    def figures(x: np.ndarray) -> np.ndarray:
        v = x[um]
        return np.array([math.sqrt(float(np.mean(v * v))), float(np.max(np.abs(v)))])

    gl_x, gl_w = np.polynomial.legendre.leggauss(12)
    gh_x, gh_w = np.polynomial.hermite_e.hermegauss(12)
    gh_w = gh_w / gh_w.sum()
    out: dict[str, np.ndarray] = {}
    for x in inp.systematic:
        mp = np.nan_to_num(forward(x.pattern))
        if not np.any(mp[um]):
            continue
        if x.normal_sd is not None:
            ts, ws = gh_x * x.normal_sd, gh_w
        else:
            ts = 0.5 * (x.low + x.high) + 0.5 * (x.high - x.low) * gl_x
            ws = gl_w / 2.0
        F = np.array([figures(r + t * mp) for t in ts])
        mean = ws @ F
        sd = np.sqrt(np.clip(ws @ (F - mean) ** 2, 0.0, None))
        name = f"{x.check}: {x.name}"
        out[name] = np.sqrt(out.get(name, np.zeros(2)) ** 2 + sd ** 2)
    return out


def _gap_lines(prob: Any, r_clean: np.ndarray, back: Callable[[np.ndarray], np.ndarray],
               var_noise: np.ndarray, inp: Inputs,
               forward: Callable[[np.ndarray], np.ndarray] | None = None) -> dict[str, Any]:
    """u of RMS and max |r| (um rows) of a residual r(y + dy) = r + M dy, M^T given by
    ``back``; noise of a re-measurement with variance ``var_noise`` per reading.

    The errors that are random from sample to sample (the noise, a target's linearity, a
    reading's resolution) enter an RMS through the exact variance of a quadratic form in
    them (first order 4 r^T S r plus 2 tr(S^2), S their covariance, the projections M
    dropped) and a max through the competition of the samples (the largest of independent
    normals, the exact distribution ISO 230-2's E uses); the inputs common to many samples
    (scale, drift, calibration) to first order."""
    um = prob.um_rows & np.isfinite(r_clean)
    r = np.where(um, r_clean, 0.0)
    n = int(um.sum())
    k = int(np.argmax(np.abs(r)))
    rand = {"fit / readings' noise (Type A)": (var_noise * um, [])}
    rand.update(_random_parts(prob, inp, um))
    # Var(e^2) = (2 + excess kurtosis) sigma^4: 2 for the normal noise, 0.8 for a
    # rectangular error (a target's linearity, a reading's resolution)
    kurt = {name: (2.0 if i == 0 else 0.8) for i, name in enumerate(rand)}
    # new errors raise the sum of squares on average by their variance (E ss' = ss +
    # tr S): the square root is linearised at that mean, where the draws are
    ss_mean = float(r @ r) + sum(float(np.sum(v)) for v, _ in rand.values())
    rms_mean = math.sqrt(ss_mean / n)
    rms = math.sqrt(float(r @ r) / n)
    out: dict[str, Any] = {}
    # RMS
    a = r / (n * rms_mean)
    s = back(a)
    lines = {}
    for name, (v, blocks) in rand.items():
        if blocks:  # one error per block: first order through the block's sum, tr(S^2) by blocks
            v1 = sum(float(np.sum(s[b])) ** 2 * float(v[b[0]]) for b in blocks if b.size)
            tr2 = sum((b.size * float(v[b[0]])) ** 2 for b in blocks if b.size)
        else:
            v1 = float(np.sum(s * s * v))
            tr2 = float(np.sum(v * v))
        lines[name] = math.sqrt(v1 + kurt[name] * tr2 / (2.0 * n * rms_mean) ** 2)
    sys_lines = _systematic_gap_lines(r, um, inp, forward) if forward is not None else {}
    lines.update({k: float(v[0]) for k, v in sys_lines.items()})
    u = math.sqrt(sum(x * x for x in lines.values()))
    out["rms_um"] = {"value": rms, "u": u, "U": K * u, "budget_u": lines}
    # max |r|: the random errors together, by the competition of the samples (a target's
    # linearity shared by its samples), shared between their lines in proportion to their
    # variance at the sample that makes the max
    var = _max_abs_variance(r, um, rand)
    v_all = sum(v for v, _ in rand.values())
    tot = float(v_all[k]) or 1.0
    lines = {name: math.sqrt(var * float(v[k]) / tot) for name, (v, _) in rand.items()}
    lines.update({k: float(v[1]) for k, v in sys_lines.items()})
    u = math.sqrt(sum(x * x for x in lines.values()))
    out["max_um"] = {"value": abs(r[k]), "u": u, "U": K * u, "budget_u": lines}
    return out
