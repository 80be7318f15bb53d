"""The backlash direction state: the take-up rule of the library's compensator.

While an axis moves, its direction state s changes by 2 dp / take-up and is
clipped to [-1, 1]; at standstill it keeps its value. The table's backlash term
is ``-b/2 * s`` on the axis' own error (docs/table-format.md). Positions mm.
"""

from __future__ import annotations

import numpy as np


def backlash_state(pos_mm: np.ndarray, takeup_mm: float, s0: float) -> np.ndarray:
    """Direction state s in [-1, 1] along a path of positions (N,), mm.

    s changes by 2 dp / takeup while the axis moves (+ for increasing p) and is
    clipped to [-1, 1]: after a reversal it crosses from -1 to +1 over the
    take-up distance (the library compensator's model). ``s0`` is the state at
    pos_mm[0]. Exact for a piecewise-linear path through the given points.
    """
    p = np.asarray(pos_mm, dtype=np.float64).reshape(-1)
    out = np.empty(p.size)
    if p.size == 0:
        return out
    out[0] = s = float(np.clip(s0, -1.0, 1.0))
    if p.size == 1:
        return out
    dp = np.diff(p)
    sgn = np.sign(dp)
    # Segments of constant motion sign (standstill steps keep the state).
    i = 0
    n = dp.size
    k = 2.0 / float(takeup_mm)
    while i < n:
        j = i
        while j + 1 < n and sgn[j + 1] == sgn[i]:
            j += 1
        seg = p[i + 1: j + 2] - p[i]
        out[i + 1: j + 2] = np.clip(s + k * seg, -1.0, 1.0)
        s = out[j + 1]
        i = j + 1
    return out


def direction_state(pos_mm: np.ndarray, takeup_mm: float, s0: float | None = None) -> np.ndarray:
    """Backlash direction state s in [-1, 1] along a polyline path of positions (N,) mm.

    s changes by 2 dp / takeup while the axis moves and is clipped to [-1, 1] (the
    library compensator's model); standstill keeps it. ``s0`` defaults to the sign of
    the first motion. ``takeup_mm`` <= 0: s is the sign of the motion (0 at rest).
    """
    p = np.asarray(pos_mm, dtype=np.float64).reshape(-1)
    n = p.size
    out = np.zeros(n)
    if n < 2:
        return out
    dp = np.diff(p)
    if s0 is None:
        nz = np.flatnonzero(np.abs(dp) > 1e-12)
        s0 = float(np.sign(dp[nz[0]])) if nz.size else 0.0
    if takeup_mm <= 0:
        sg = np.sign(dp)
        out[1:] = sg
        out[0] = s0
        return out
    return backlash_state(p, takeup_mm, s0)
