"""Choosing a 1D table grid within a target's point limit, and its interpolation.

A target tabulates a function of one axis position (the model's error on a
line, um) at equally spaced knots and interpolates linearly between them,
holding the end values outside (every table target here does that). The
spacing is chosen to minimise the interpolation residual: among "round"
spacings (1, 2, 2.5, 5 x 10^k mm) and the finest spacing the limit allows, the
lowest maximum |f - interpolant| over the travel wins; a coarser grid is
preferred only when it is within max(0.001 um, 1 %) of the lowest. When the
chosen grid still leaves more than 0.05 um and twice the allowed points would
shrink that by a quarter or more, the point limit is named as the cause.
Positions mm, values um.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

LIMIT_CAUSE_UM = 0.05
TIE_UM = 0.001
TIE_REL = 0.01


@dataclass
class Grid:
    """An equally spaced grid ``knots`` (mm) chosen for a table of at most ``limit`` points.

    interp_residual_um: max |f - linear interpolant| over the travel (all columns);
    finest_residual_um: the same at the finest spacing the limit allows;
    double_residual_um: the same with twice the allowed points (what the limit costs);
    limit_is_cause: see the module docstring.
    """

    knots: np.ndarray
    spacing_mm: float
    limit: int
    interp_residual_um: float
    finest_residual_um: float
    double_residual_um: float
    limit_is_cause: bool

    @property
    def points(self) -> int:
        return int(self.knots.size)

    def describe(self) -> dict:
        return {"points": self.points, "limit": self.limit,
                "start_mm": float(self.knots[0]), "end_mm": float(self.knots[-1]),
                "spacing_mm": self.spacing_mm,
                "interpolation_residual_um": round(self.interp_residual_um, 4),
                "finest_allowed_residual_um": round(self.finest_residual_um, 4),
                "twice_the_points_residual_um": round(self.double_residual_um, 4),
                "limit_is_cause": self.limit_is_cause}


def nice_spacings(lo: float, hi: float) -> list[float]:
    """Round spacings 1, 2, 2.5, 5 x 10^k mm between 1 um and the travel."""
    span = hi - lo
    out = []
    for k in range(-3, int(math.log10(span)) + 2):
        for m in (1.0, 2.0, 2.5, 5.0):
            h = m * 10.0 ** k
            if 1e-3 <= h <= span:
                out.append(h)
    return sorted(set(out))


def knots_for(lo: float, hi: float, h: float) -> np.ndarray:
    """lo, lo + h, ... up to the first knot >= hi."""
    n = int(math.ceil((hi - lo) / h - 1e-9)) + 1
    return lo + h * np.arange(max(n, 2))


def interp_error(f: Callable[[np.ndarray], np.ndarray], q: np.ndarray, fq: np.ndarray,
                 knots: np.ndarray) -> float:
    """max |f - linear interpolant through f(knots)| at the samples q (all columns)."""
    fk = np.asarray(f(knots), dtype=np.float64).reshape(knots.size, -1)
    fq = fq.reshape(q.size, -1)
    err = 0.0
    for c in range(fq.shape[1]):
        err = max(err, float(np.max(np.abs(np.interp(q, knots, fk[:, c]) - fq[:, c]))))
    return err


def choose_grid(lo: float, hi: float, f: Callable[[np.ndarray], np.ndarray], limit: int,
                spacings: list[float] | None = None, min_spacing_mm: float = 0.0,
                quantum_mm: float = 0.0) -> Grid:
    """The grid for a table over [lo, hi] mm of at most ``limit`` points (module docstring).

    ``spacings``: candidate spacings (default: round ones plus the finest allowed);
    ``min_spacing_mm``: the target's smallest admissible spacing; ``quantum_mm``: the
    spacing must be a multiple of it (a format's decimals or units; 0 = any).
    """
    if limit < 2:
        raise ValueError("a table needs at least 2 points")
    finest = (hi - lo) / (limit - 1)
    if quantum_mm > 0:
        finest = math.ceil(finest / quantum_mm - 1e-9) * quantum_mm
        if spacings is not None:
            spacings = [math.ceil(h / quantum_mm - 1e-9) * quantum_mm for h in spacings]
    if spacings is None:
        spacings = nice_spacings(lo, hi) + [finest]
    cands = [h for h in spacings if h >= max(min_spacing_mm, finest * (1 - 1e-12))]
    if not cands:
        cands = [max(finest, min_spacing_mm)]
    m = max(2001, 10 * limit)
    q = np.linspace(lo, hi, m)
    fq = np.asarray(f(q), dtype=np.float64)
    scored = []
    for h in sorted(set(cands)):
        k = knots_for(lo, hi, h)
        if k.size > limit:
            continue
        scored.append((interp_error(f, q, fq, k), h, k))
    if not scored:
        h = max(finest, min_spacing_mm)
        k = knots_for(lo, hi, h)[:limit]
        scored.append((interp_error(f, q, fq, k), h, k))
    best = min(s[0] for s in scored)
    tol = max(TIE_UM, TIE_REL * best)
    ok = [s for s in scored if s[0] <= best + tol]
    err, h, k = max(ok, key=lambda s: s[1])  # the coarsest within the tie
    hf = min(s[1] for s in scored)
    fin = next(s[0] for s in scored if s[1] == hf)
    dbl = interp_error(f, q, fq, knots_for(lo, hi, hf / 2.0))
    cause = bool(err > LIMIT_CAUSE_UM and dbl < 0.75 * err)
    return Grid(knots=k, spacing_mm=float(h), limit=limit, interp_residual_um=err,
                finest_residual_um=fin, double_residual_um=dbl, limit_is_cause=cause)


def interp_held(x: np.ndarray, knots: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Linear interpolation, end values held outside the knots (np.interp)."""
    return np.interp(np.asarray(x, dtype=np.float64), knots, values)
