"""The programmed path of a Simulator session and the model's motor path beside it:
a dense polyline (pieces <= 0.02 mm, arcs on the true circle), the motor steps the model
gives at a point, and the exact largest-axis distance from recorded steps to that path.

Positions mm, errors um, steps at 250 steps/mm (sim_driver.STEPS_PER_MM).
"""

from __future__ import annotations

import math

import numpy as np

from abbe.model.backlash import direction_state
from abbe.model.reference import spatial_error
from sim_driver import STEPS_PER_MM

class Path3:
    """The programmed path of one simulator session, from (0, 0, 0), as a dense
    polyline (pieces <= 0.02 mm; arcs as the true circle), with marks."""

    def __init__(self) -> None:
        self.pts: list[np.ndarray] = [np.zeros((1, 3))]
        self.count = 1
        self.cur = np.zeros(3)

    def _add(self, p: np.ndarray) -> None:
        self.pts.append(p)
        self.count += len(p)
        self.cur = p[-1].copy()

    def line(self, b: np.ndarray) -> None:
        a = self.cur
        n = max(1, int(math.ceil(np.linalg.norm(b - a) / 0.02)))
        t = np.linspace(0.0, 1.0, n + 1)[1:, None]
        p = a + t * (b - a)
        p[-1] = b
        self._add(p)

    def arc(self, b: np.ndarray, center: np.ndarray, cw: bool) -> None:
        """XY arc from the current point to b about center (b = start: a full circle)."""
        a = self.cur
        r = float(np.hypot(*(a - center)[:2]))
        a0 = math.atan2(a[1] - center[1], a[0] - center[0])
        a1 = math.atan2(b[1] - center[1], b[0] - center[0])
        sweep = a1 - a0
        if cw and sweep >= -1e-12:
            sweep -= 2 * math.pi
        if not cw and sweep <= 1e-12:
            sweep += 2 * math.pi
        n = max(1, int(math.ceil(abs(sweep) * r / 0.02)))
        ang = a0 + np.linspace(0.0, sweep, n + 1)[1:]
        p = np.column_stack([center[0] + r * np.cos(ang), center[1] + r * np.sin(ang), np.full(n, a[2])])
        p[-1] = b
        self._add(p)

    def model(self, table) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Dense points p, direction state s (the compensator's take-up rule,
        state 0 at start) and the model's motor positions p - E(p, s), mm."""
        p = np.vstack(self.pts)
        s = np.zeros_like(p)
        if table is None:  # grblHAL's own: no correction
            return p, s, p.copy()
        for j, ax in enumerate(("X", "Y", "Z")):
            s[:, j] = direction_state(p[:, j], table.axes[ax].backlash_takeup_mm, 0.0)
        return p, s, p - spatial_error(table, p, s) * 1e-3


def model_steps(table, p: np.ndarray, s: np.ndarray) -> np.ndarray:
    """round-free (p - E(p, s)) x steps/mm for one point (table None: p x steps/mm)."""
    if table is None:
        return p * STEPS_PER_MM
    return (p - spatial_error(table, p[None, :], s[None, :])[0] * 1e-3) * STEPS_PER_MM


def cheb_to_segments(q: np.ndarray, a: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Per row, the Chebyshev (largest-axis) distance from point q to the
    segment a + t d, t in [0, 1]: the minimum over t of max_j |r_j - t d_j|
    (r = q - a), a convex piecewise-linear function of t, so it is attained at
    t = 0, 1, a zero of some r_j - t d_j or where two of them are equal or
    opposite; every candidate is evaluated."""
    r = q - a
    cands = [np.zeros(len(q)), np.ones(len(q))]
    n = q.shape[1]
    with np.errstate(divide="ignore", invalid="ignore"):
        for j in range(n):
            cands.append(r[:, j] / d[:, j])
            for k in range(j + 1, n):
                cands.append((r[:, j] - r[:, k]) / (d[:, j] - d[:, k]))
                cands.append((r[:, j] + r[:, k]) / (d[:, j] + d[:, k]))
    t = np.clip(np.nan_to_num(np.column_stack(cands), nan=0.0, posinf=0.0, neginf=0.0), 0.0, 1.0)
    res = np.abs(r[:, None, :] - t[:, :, None] * d[:, None, :]).max(2)
    return res.min(1)


def path_deviation(points_steps: np.ndarray, motor: np.ndarray) -> np.ndarray:
    """Per point (steps), the Chebyshev distance in steps (largest axis, exact:
    cheb_to_segments) from the model's motor path (the dense polyline through
    p - E(p), mm), over the pieces around the point's nearest vertex. (A
    Euclidean projection measured on its largest axis, used before, overstates
    that distance by up to 21 % for a path at an angle to the axes.)"""
    from scipy.spatial import cKDTree

    q = points_steps.astype(float) / STEPS_PER_MM
    if len(q) == 0:
        return np.zeros(0)
    _, k = cKDTree(motor).query(q)
    out = np.full(len(q), np.inf)
    for j in (k - 1, k):
        ok = (j >= 0) & (j + 1 < len(motor))
        jj = np.clip(j, 0, max(len(motor) - 2, 0))
        a, d = motor[jj], motor[np.minimum(jj + 1, len(motor) - 1)] - motor[jj]
        out = np.where(ok, np.minimum(out, cheb_to_segments(q, a, d)), out)
    return out * STEPS_PER_MM
