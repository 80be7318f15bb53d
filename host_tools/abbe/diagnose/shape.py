"""Shape parameters of the named effects: continuous refinement and profile intervals.

A candidate's nonlinear shape parameter (backlash take-up, cyclic period) is first
searched on a grid (:mod:`abbe.diagnose.candidates`); once the effect is named, this
module refines it continuously (golden section on the whitened residual sum of
squares of the whole selected set, the other effects and the nuisance refitted)
and gives its 95 % profile-likelihood interval: the values whose RSS exceeds the
minimum by less than chi2_1(0.95) x s2 (s2 = max(1, residual variance), noise
units). An interval that reaches the end of the searched range is open there
("take-up <= 0.008 mm": the checks do not resolve a sharper step).

Units: take-up mm, period mm.
"""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np
from scipy import stats

from abbe.diagnose.backlash_pair import is_pair
from abbe.diagnose.candidates import Engine, Selected, selection_residual
from abbe.diagnose.effects import BACKLASH_TAKEUP_GRID_MM
from abbe.model.table import AXES
from abbe.diagnose.problem import qr_basis

#: Range searched for a take-up (mm) and a cyclic period (relative to the grid value).
TAKEUP_RANGE_MM = (0.002, 10.0)
CHI2_95 = float(stats.chi2.ppf(0.95, 1))


def _rss_fn(eng: Engine, sel: list[Selected], i: int, W: np.ndarray
            ) -> Callable[[float], tuple[float, np.ndarray, np.ndarray | None]]:
    """v -> (whitened RSS of the selected set with effect i at shape value v, its
    columns, its fixed offset)."""
    prob = eng.prob
    s = sel[i]
    others = sel[:i] + sel[i + 1:]
    r_base = selection_residual(eng, others)
    X_o = [prob.nuis] + [o.cand.cols for o in others]
    spec = s.cand.spec

    def f(v: float) -> tuple[float, np.ndarray, np.ndarray | None]:
        if spec.kind == "cyclic":
            cols, off = eng.cyclic_cols(spec.axis, v, eng.table,  # type: ignore[arg-type]
                                        len(s.cand.param_idx) // 2), None
        else:
            c, off = eng.sensitivity_offset(spec, v, eng.table, eng.pp, eng.y0)
            cols = c[:, s.cand.param_idx]
        r = r_base if off is None else r_base - off
        X = np.hstack(X_o + [cols]) * W[:, None]
        Q = qr_basis(X)
        rw = r * W
        e = rw - Q @ (Q.T @ rw)
        return float(e @ e), cols, off
    return f


def _golden(g: Callable[[float], float], lo: float, hi: float, it: int = 18) -> float:
    gr = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = hi - gr * (hi - lo), lo + gr * (hi - lo)
    ga, gb = g(a), g(b)
    for _ in range(it):
        if ga < gb:
            hi, b, gb = b, a, ga
            a = hi - gr * (hi - lo)
            ga = g(a)
        else:
            lo, a, ga = a, b, gb
            b = lo + gr * (hi - lo)
            gb = g(b)
    return a if ga < gb else b


def _edge(g: Callable[[float], float], x0: float, step: float, bound: float, level: float
          ) -> tuple[float, bool]:
    """Walk from x0 by ``step`` toward ``bound`` until g exceeds ``level``; bisect the
    crossing. Returns (x, closed): closed = False if the bound was reached first."""
    x = x0
    while True:
        nx = x + step
        if (step > 0 and nx >= bound) or (step < 0 and nx <= bound):
            if g(bound) <= level:
                return bound, False
            nx = bound
        if g(nx) > level:
            a, b = x, nx
            for _ in range(12):
                m = 0.5 * (a + b)
                if g(m) > level:
                    b = m
                else:
                    a = m
            return 0.5 * (a + b), True
        x = nx


def refine_scans(eng: Engine, sel: list[Selected], W: np.ndarray) -> None:
    """Refine the shape parameter of every named effect that has one (take-up of a
    backlash searched on a grid, cyclic period) and attach its 95 % interval
    (``stats['scan_ci']`` = (lo, hi, lo_closed, hi_closed)). Updates the candidate's
    columns, offset and scan value in place."""
    prob = eng.prob
    for i, s in enumerate(sel):
        spec = s.cand.spec
        s.stats.pop("scan_ci_pair", None)
        if spec.kind == "backlash" and is_pair(s.cand.scan_value) and _refine_pair(eng, sel, i, W):
            continue
        v0 = s.cand.scan_value
        if v0 is None or not math.isfinite(v0):
            continue
        if spec.kind == "backlash":
            if s.cand.n_scan <= 1:
                continue          # take-up not searched (no ballbar moves the axis)
            to_x, from_x = math.log, math.exp
            lo_b, hi_b = (to_x(TAKEUP_RANGE_MM[0]), to_x(TAKEUP_RANGE_MM[1]))
            grid = [to_x(g) for g in BACKLASH_TAKEUP_GRID_MM]
            x0 = to_x(v0)
            nb = [g for g in grid if abs(g - x0) > 1e-9]
            left = max([g for g in nb if g < x0], default=lo_b)
            right = min([g for g in nb if g > x0], default=hi_b)
            step = 0.15
        elif spec.kind == "cyclic":
            span = float(np.ptp(eng._cyc_pos[spec.axis][eng._probe[spec.axis] != 0]))  # type: ignore[index]
            df = 1.0 / (4.0 * span)
            to_x, from_x = (lambda p: 1.0 / p), (lambda f: 1.0 / f)
            x0 = to_x(v0)
            left, right = x0 - df, x0 + df
            lo_b, hi_b = x0 - 4 * df, x0 + 4 * df
            step = df / 8.0
        else:
            continue
        f = _rss_fn(eng, sel, i, W)
        cache: dict[float, float] = {}

        def g(x: float) -> float:
            if x not in cache:
                cache[x] = f(from_x(x))[0]
            return cache[x]
        xb = _golden(g, left, right)
        if g(x0) < g(xb):
            xb = x0
        rss, cols, off = f(from_x(xb))
        k = sum(o.cand.cols.shape[1] for o in sel) + prob.nuis.shape[1]
        s2 = max(1.0, rss / max(prob.N - k - 1, 1))
        level = rss + CHI2_95 * s2
        a, a_closed = _edge(g, xb, -step, lo_b, level)
        b, b_closed = _edge(g, xb, step, hi_b, level)
        va, vb = from_x(a), from_x(b)
        if va > vb:
            va, vb = vb, va
            a_closed, b_closed = b_closed, a_closed
        s.cand.scan_value = float(from_x(xb))
        s.cand.cols = cols
        s.cand.offset = off
        s.stats["scan_ci"] = (float(va), float(vb), bool(a_closed), bool(b_closed))


def _refine_pair(eng: Engine, sel: list[Selected], i: int, W: np.ndarray) -> bool:
    """A backlash named with a per-direction take-up pair (abbe.diagnose.backlash_pair):
    refine the pair (log take-ups, each in turn, twice, within the grid's neighbours) and
    the single take-up between the pair's, and keep the pair only if the BIC keeps its
    second shape parameter (RSS decrease > log N x s2, as the selection's choice among a
    candidate's alternatives). Kept: the candidate's pair, columns and offset, the 95 %
    interval of each take-up with the other at its value (``stats['scan_ci_pair']``); True.
    Not kept: the single take-up becomes the candidate's grid value for the 1-D refinement
    (the caller); False. Units: take-ups mm, RSS in noise units."""
    s = sel[i]
    f = _rss_fn(eng, sel, i, W)
    lo_b, hi_b = math.log(TAKEUP_RANGE_MM[0]), math.log(TAKEUP_RANGE_MM[1])
    grid = [math.log(g) for g in BACKLASH_TAKEUP_GRID_MM]
    cache: dict[tuple[float, float], float] = {}

    def g2(x: tuple[float, float]) -> float:
        if x not in cache:
            cache[x] = f((math.exp(x[0]), math.exp(x[1])))[0]
        return cache[x]

    def bracket(x0: float) -> tuple[float, float]:
        nb = [g for g in grid if abs(g - x0) > 1e-9]
        return (max([g for g in nb if g < x0], default=lo_b),
                min([g for g in nb if g > x0], default=hi_b))

    x = [math.log(v) for v in s.cand.scan_value]
    for _ in range(2):
        for c in (0, 1):
            def gc(v: float, c: int = c) -> float:
                return g2((v, x[1]) if c == 0 else (x[0], v))
            xb = _golden(gc, *bracket(x[c]))
            if gc(xb) < gc(x[c]):
                x[c] = xb
    xp = (x[0], x[1])
    rss_p = g2(xp)
    # the single take-up, between the pair's grid neighbours
    g1: dict[float, float] = {}

    def gs(v: float) -> float:
        if v not in g1:
            g1[v] = f(math.exp(v))[0]
        return g1[v]
    xs = _golden(gs, bracket(min(x))[0], bracket(max(x))[1])
    prob = eng.prob
    k = sum(o.cand.cols.shape[1] for o in sel) + prob.nuis.shape[1]
    s2 = max(1.0, rss_p / max(prob.N - k - 2, 1))
    if gs(xs) - rss_p <= math.log(prob.N) * s2:
        s.cand.scan_value = float(math.exp(xs))
        return False
    rss, cols, off = f((math.exp(xp[0]), math.exp(xp[1])))
    level = rss + CHI2_95 * s2
    ci = {}
    for c, name in ((0, "takeup_plus_mm"), (1, "takeup_minus_mm")):
        def gc(v: float, c: int = c) -> float:
            return g2((v, xp[1]) if c == 0 else (xp[0], v))
        a, a_closed = _edge(gc, xp[c], -0.15, lo_b, level)
        b, b_closed = _edge(gc, xp[c], 0.15, hi_b, level)
        ci[name] = (math.exp(a), math.exp(b), bool(a_closed), bool(b_closed))
    s.cand.scan_value = (float(math.exp(xp[0])), float(math.exp(xp[1])))
    s.cand.cols, s.cand.offset = cols, off
    s.stats.pop("scan_ci", None)
    s.stats["scan_ci_pair"] = ci
    return True


def drift_headline_weights(eng: Engine, spec: Any, idx: list[int]) -> np.ndarray:
    """Weights g (len(idx),) of a drift's headline g @ theta: its rate at the reference
    point, the offset, plus the bow's (1 - u_ref^2) when the bow is fitted (the scale is
    zero there). Units: the drift's (um per h, run or K)."""
    g = np.zeros(len(idx))
    g[idx.index(0)] = 1.0
    if 2 in idx:
        lo, hi = eng.table.axes[spec.axis].travel_mm
        r = float(eng.table.reference_mm[AXES.index(spec.axis)])
        u = (2.0 * r - lo - hi) / (hi - lo)
        g[idx.index(2)] = 1.0 - u * u
    return g


def drift_tau_average(eng: Engine, sel: list[Selected], values: list[np.ndarray], W: np.ndarray,
                      s2: float) -> dict[str, dict]:
    """The time drift's headline (its rate at the check's start, um/h) under every warm-up
    time constant of the grid the selection searched (candidates.Engine._tau_grid), and the
    95 % interval of their mixture: the time constant's uncertainty carried into the rate
    (docs/effects.md §3, "the warm-up time constant is chosen on the checks that span it").

    The grid values are equally likely models before the data; after them each weighs
    exp(-dRSS / (2 s2)) (dRSS its whitened RSS above the best one on the checks that span
    the grid, Engine.tau_rows, as the selection chose; the parameter counts are equal, so
    this is the BIC's weight; s2 = max(1, the final fit's residual variance)). For each
    value every named drift (one warm-up, one time constant) and the other named effects
    are refitted, linearised at the final values. Returns, per drift key: ``ci95`` of the
    mixture of the normal laws N(v_k, sd_k^2) with those weights, and per time constant
    (``tau`` in the drift variable's unit, None = linear) the value, its sd and its weight.
    Empty when no drift in time is named or the grid has one value."""
    drifts = [i for i, s in enumerate(sel) if s.cand.spec.kind == "thermal"
              and not eng.drift_on_table and 0 in s.cand.param_idx]
    if not drifts:
        return {}
    grid = eng._tau_grid()
    if len(grid) < 2:
        return {}
    prob = eng.prob
    from abbe.diagnose.candidates import apply_selection
    others = [i for i in range(len(sel)) if i not in drifts]
    t_o, p_o = apply_selection(eng, [sel[i] for i in others], [values[i] for i in others])
    y_o = prob.predict(eng.ev, t_o, p_o)
    r = (prob.y - y_o) * W
    X_o = [prob.nuis] + [eng.sensitivity(sel[i].cand.spec, sel[i].cand.scan_value, t_o, p_o, y_o,
                                         sel[i].cand.param_idx)[:, sel[i].cand.param_idx]
                         for i in others]
    rows = None
    k_o = sum(x.shape[1] for x in X_o)
    fits = []
    for tau in grid:
        X_d = [eng.sensitivity(sel[i].cand.spec, tau, t_o, p_o, y_o,
                               sel[i].cand.param_idx)[:, sel[i].cand.param_idx] for i in drifts]
        if rows is None:   # the checks the drift acts on that span the grid, as chosen
            rows = eng.tau_rows(np.hstack(X_d))
            if not rows.any():
                rows = np.ones(prob.N, dtype=bool)
        X = np.hstack(X_o + X_d) * W[:, None]
        beta, *_ = np.linalg.lstsq(X, r, rcond=None)
        cov = s2 * np.linalg.pinv(X.T @ X)
        b_r, *_ = np.linalg.lstsq(X[rows], r[rows], rcond=None)
        e = r[rows] - X[rows] @ b_r
        k, heads = k_o, {}
        for i, x in zip(drifts, X_d):
            g = drift_headline_weights(eng, sel[i].cand.spec, sel[i].cand.param_idx)
            sl = slice(k, k + x.shape[1])
            heads[sel[i].cand.spec.key] = (float(g @ beta[sl]),
                                           math.sqrt(max(float(g @ cov[sl, sl] @ g), 0.0)))
            k += x.shape[1]
        fits.append((None if not math.isfinite(tau) else float(tau), float(e @ e), heads))
    best = min(f[1] for f in fits)
    w = np.array([math.exp(-(f[1] - best) / (2.0 * max(s2, 1.0))) for f in fits])
    w /= w.sum()
    out: dict[str, dict] = {}
    for i in drifts:
        key = sel[i].cand.spec.key
        v = np.array([f[2][key][0] for f in fits])
        sd = np.array([f[2][key][1] for f in fits])
        out[key] = {"ci95": _mixture_interval(v, sd, w),
                    "alternatives": [{"tau": f[0], "value": float(a), "sd": float(b),
                                      "weight": float(c)}
                                     for f, a, b, c in zip(fits, v, sd, w)]}
    return out


def _mixture_interval(v: np.ndarray, sd: np.ndarray, w: np.ndarray,
                      level: float = 0.95) -> tuple[float, float]:
    """Central ``level`` interval of the mixture sum_k w_k N(v_k, sd_k^2) (bisection on its
    distribution function)."""
    sd = np.maximum(sd, 1e-12 * max(float(np.max(np.abs(v))), 1.0))

    def cdf(x: float) -> float:
        return float(np.sum(w * stats.norm.cdf((x - v) / sd)))

    def q(p: float) -> float:
        lo, hi = float(np.min(v - 10 * sd)), float(np.max(v + 10 * sd))
        for _ in range(80):
            m = 0.5 * (lo + hi)
            if cdf(m) < p:
                lo = m
            else:
                hi = m
        return 0.5 * (lo + hi)
    a = 0.5 * (1.0 - level)
    return q(a), q(1.0 - a)
