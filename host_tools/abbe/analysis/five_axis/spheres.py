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
    centre (M, 3) mm, radius (M,) mm, RMS of the fit (M,) um, radius check passed (M,),
    number of points (M,) and the centre's variance factor (M,): trace of the centre block
    of (J^T J)^-1 of the geometric fit, so that the centre's 3-D variance is sigma^2 times
    it for a point noise sigma (dimensionless)."""

    angles_deg: np.ndarray
    time_s: np.ndarray
    centre_mm: np.ndarray
    radius_mm: np.ndarray
    rms_um: np.ndarray
    radius_ok: np.ndarray
    position: np.ndarray
    n_points: np.ndarray
    centre_factor: np.ndarray

    def centre_noise_um(self, keep: np.ndarray | None = None) -> float | None:
        """Expected RMS 3-D length of the fitted centres' noise (um): the point noise pooled
        from the fits' residuals (sum of squares over their degrees of freedom, N - 4 each)
        times each fit's variance factor. It holds every point-level error the radius fit
        leaves, a direction-dependent pre-travel included, so it bounds the centre noise
        from above. None when no fit has more points than unknowns."""
        k = np.ones(self.rms_um.size, bool) if keep is None else keep
        dof = float(np.sum(self.n_points[k] - 4))
        if dof <= 0:
            return None
        s2 = float(np.sum(self.n_points[k] * self.rms_um[k] ** 2)) / dof
        return float(np.sqrt(s2 * np.mean(self.centre_factor[k])))


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


def centre_factor(points_mm: np.ndarray, centre_mm: np.ndarray) -> float:
    """Trace of the centre block of (J^T J)^-1 for the geometric sphere fit at its solution
    (J: rows [-u_i, -1], u_i the unit direction from the centre to point i); inf when the
    points do not fix a centre."""
    v = np.asarray(points_mm, dtype=np.float64) - centre_mm
    u = v / np.linalg.norm(v, axis=1)[:, None]
    J = np.column_stack([-u, -np.ones(len(u))])
    try:
        return float(np.trace(np.linalg.inv(J.T @ J)[:3, :3]))
    except np.linalg.LinAlgError:
        return float("inf")


def sphere_centres(pts: ProbePoints, nominal_radius_mm: float, tol_mm: float) -> SphereCentres:
    """Fit every position of a probing file; ``nominal_radius_mm`` = sphere + stylus radius."""
    ids = pts.position
    starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
    ends = np.r_[starts[1:], ids.size]
    ang, t, c, r, rms, pos, npt, fac = [], [], [], [], [], [], [], []
    for s, e in zip(starts, ends):
        ci, ri, q = fit_sphere(pts.points_mm[s:e])
        ang.append(pts.angles_deg[s])
        t.append(float(np.mean(pts.time_s[s:e])))
        c.append(ci)
        r.append(ri)
        rms.append(q)
        pos.append(int(ids[s]))
        npt.append(e - s)
        fac.append(centre_factor(pts.points_mm[s:e], ci))
    r_arr = np.asarray(r)
    return SphereCentres(np.asarray(ang), np.asarray(t), np.asarray(c), r_arr, np.asarray(rms),
                         np.abs(r_arr - nominal_radius_mm) <= tol_mm, np.asarray(pos),
                         np.asarray(npt), np.asarray(fac))
