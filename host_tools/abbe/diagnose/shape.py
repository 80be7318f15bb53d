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
from typing import Callable

import numpy as np
from scipy import stats

from abbe.diagnose.candidates import Engine, Selected, selection_residual
from abbe.diagnose.effects import BACKLASH_TAKEUP_GRID_MM
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
