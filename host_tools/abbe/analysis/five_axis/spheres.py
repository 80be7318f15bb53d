"""Least-squares sphere fits of probe trigger points (what a controller's probing cycle does).

Each position's points give a centre and a radius: an algebraic fit to start,
then Gauss-Newton on the geometric distances ``|x - c| - r``. The fitted radius
is checked against the certificate radius plus the calibrated stylus radius, as
Heidenhain's cycle 451 does (a probing that misses the radius is rejected).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from abbe.formats.five_axis import ProbePoints


@dataclass(frozen=True)
class SphereCentres:
    """Per probing position: angles (M, 2) deg, time s (mean of its points), fitted
    centre (M, 3) mm, radius (M,) mm, RMS of the fit (M,) um, radius check passed (M,)."""

    angles_deg: np.ndarray
    time_s: np.ndarray
    centre_mm: np.ndarray
    radius_mm: np.ndarray
    rms_um: np.ndarray
    radius_ok: np.ndarray
    position: np.ndarray


def fit_sphere(points_mm: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Centre (3,) mm, radius mm and RMS distance residual (um) of points (N >= 4, 3)."""
    x = np.asarray(points_mm, dtype=np.float64)
    m = x.mean(axis=0)
    d = x - m  # centred for conditioning
    A = np.column_stack([2 * d, np.ones(len(d))])
    sol, *_ = np.linalg.lstsq(A, (d * d).sum(axis=1), rcond=None)
    c = sol[:3]
    r = float(np.sqrt(max(sol[3] + c @ c, 1e-12)))
    for _ in range(10):
        v = d - c
        dist = np.linalg.norm(v, axis=1)
        res = dist - r
        J = np.column_stack([-v / dist[:, None], -np.ones(len(d))])
        step, *_ = np.linalg.lstsq(J, -res, rcond=None)
        c = c + step[:3]
        r += float(step[3])
        if np.max(np.abs(step)) < 1e-12:
            break
    res = np.linalg.norm(d - c, axis=1) - r
    return c + m, r, float(np.sqrt(np.mean(res ** 2)) * 1e3)


def sphere_centres(pts: ProbePoints, nominal_radius_mm: float, tol_mm: float) -> SphereCentres:
    """Fit every position of a probing file; ``nominal_radius_mm`` = sphere + stylus radius."""
    ids = pts.position
    starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
    ends = np.r_[starts[1:], ids.size]
    ang, t, c, r, rms, pos = [], [], [], [], [], []
    for s, e in zip(starts, ends):
        ci, ri, q = fit_sphere(pts.points_mm[s:e])
        ang.append(pts.angles_deg[s])
        t.append(float(np.mean(pts.time_s[s:e])))
        c.append(ci)
        r.append(ri)
        rms.append(q)
        pos.append(int(ids[s]))
    r_arr = np.asarray(r)
    return SphereCentres(np.asarray(ang), np.asarray(t), np.asarray(c), r_arr, np.asarray(rms),
                         np.abs(r_arr - nominal_radius_mm) <= tol_mm, np.asarray(pos))
