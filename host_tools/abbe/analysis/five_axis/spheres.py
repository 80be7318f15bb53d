"""Least-squares sphere fits of probe trigger points (what a controller's probing cycle does).

Each position's points give a centre and a radius: an algebraic fit to start,
then Gauss-Newton on the geometric distances ``|x - c| - r``. The fitted radius
is checked against the certificate radius plus the calibrated stylus radius, as
Heidenhain's cycle 451 does (a probing that misses the radius is rejected).

The point noise behind the centres' scatter is pooled from the fits' residuals,
less their part common to every position probed with the same directions: a
controller's cycle approaches along machine-fixed directions, so a
direction-dependent pre-travel leaves the same residual pattern (and the same
centre bias) at every position; it inflates the residuals but never scatters the
centres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from abbe.formats.five_axis import ProbePoints

#: Two positions were probed along the same directions when no direction component differs
#: by more than this (a cycle's directions are machine-fixed; the centres' micrometres
#: move them by ~1e-4).
SAME_DIRECTION = 0.01


@dataclass(frozen=True)
class SphereCentres:
    """Per probing position: angles (M, 2) deg, time s (mean of its points), fitted
    centre (M, 3) mm, radius (M,) mm, RMS of the fit (M,) um, radius check passed (M,),
    number of points (M,), the centre's variance factor (M,): trace of the centre block
    of (J^T J)^-1 of the geometric fit, so that the centre's 3-D variance is sigma^2 times
    it for a point noise sigma (dimensionless), that block itself (M, 3, 3), and the
    fits' signed distance residuals (um), one array per position."""

    angles_deg: np.ndarray
    time_s: np.ndarray
    centre_mm: np.ndarray
    radius_mm: np.ndarray
    rms_um: np.ndarray
    radius_ok: np.ndarray
    position: np.ndarray
    n_points: np.ndarray
    centre_factor: np.ndarray
    centre_block: np.ndarray
    residuals_um: tuple[np.ndarray, ...]
    #: unit directions (N, 3) from each fitted centre to its points
    directions: tuple[np.ndarray, ...]

    def point_noise_um(self, keep: np.ndarray | None = None) -> float | None:
        """Standard deviation of the trigger points' random error along the normal (um).

        Positions probed along the same directions form a group; the group's mean residual
        pattern (a direction-dependent pre-travel, the same at each of them) is taken out
        and the rest pooled: (m - 1)(N - 4) degrees of freedom for m positions of N points
        (the fits' hat matrices are the same within a group). A position alone in its
        group keeps its raw residuals (N - 4). None without redundant points."""
        k = np.ones(self.rms_um.size, bool) if keep is None else keep
        groups: list[tuple[np.ndarray, list[int]]] = []
        for i in np.flatnonzero(k):
            u = self.directions[i]
            for rep, idx in groups:
                if rep.shape == u.shape and np.max(np.abs(rep - u)) < SAME_DIRECTION:
                    idx.append(int(i))
                    break
            else:
                groups.append((u, [int(i)]))
        ss = dof = 0.0
        for _rep, idx in groups:
            r = np.array([self.residuals_um[i] for i in idx])
            m, n = r.shape
            if m > 1:
                ss += float(np.sum((r - r.mean(axis=0)) ** 2))
                dof += (m - 1) * (n - 4)
            else:
                ss += float(np.sum(r ** 2))
                dof += n - 4
        return float(np.sqrt(ss / dof)) if dof > 0 else None

    def centre_noise_um(self, keep: np.ndarray | None = None) -> float | None:
        """Expected RMS 3-D length of the fitted centres' noise (um): the point noise
        (:meth:`point_noise_um`) times each fit's variance factor. None when no fit has
        more points than unknowns."""
        k = np.ones(self.rms_um.size, bool) if keep is None else keep
        s = self.point_noise_um(k)
        if s is None:
            return None
        return float(s * np.sqrt(np.mean(self.centre_factor[k])))

    def centre_cov_um2(self, keep: np.ndarray | None = None) -> np.ndarray | None:
        """(M, 3, 3) covariance of each kept centre (um^2, machine axes): the point noise
        squared times the fit's centre block; None as :meth:`point_noise_um`."""
        k = np.ones(self.rms_um.size, bool) if keep is None else keep
        s = self.point_noise_um(k)
        return None if s is None else s * s * self.centre_block[k]


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


def centre_block(points_mm: np.ndarray, centre_mm: np.ndarray) -> np.ndarray:
    """The centre block (3, 3) of (J^T J)^-1 for the geometric sphere fit at its solution
    (J: rows [-u_i, -1], u_i the unit direction from the centre to point i); inf when the
    points do not fix a centre."""
    v = np.asarray(points_mm, dtype=np.float64) - centre_mm
    u = v / np.linalg.norm(v, axis=1)[:, None]
    J = np.column_stack([-u, -np.ones(len(u))])
    try:
        return np.linalg.inv(J.T @ J)[:3, :3]
    except np.linalg.LinAlgError:
        return np.full((3, 3), np.inf)


def centre_factor(points_mm: np.ndarray, centre_mm: np.ndarray) -> float:
    """Trace of :func:`centre_block` (dimensionless)."""
    return float(np.trace(centre_block(points_mm, centre_mm)))


def _directions(points_mm: np.ndarray, centre_mm: np.ndarray) -> np.ndarray:
    """(N, 3) unit directions from the centre to the points."""
    v = np.asarray(points_mm, dtype=np.float64) - centre_mm
    return v / np.linalg.norm(v, axis=1)[:, None]


def sphere_centres(pts: ProbePoints, nominal_radius_mm: float, tol_mm: float) -> SphereCentres:
    """Fit every position of a probing file; ``nominal_radius_mm`` = sphere + stylus radius."""
    ids = pts.position
    starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
    ends = np.r_[starts[1:], ids.size]
    ang, t, c, r, rms, pos, npt, fac = [], [], [], [], [], [], [], []
    blk, resid, keys = [], [], []
    for s, e in zip(starts, ends):
        p = pts.points_mm[s:e]
        ci, ri, q = fit_sphere(p)
        blk.append(centre_block(p, ci))
        resid.append((np.linalg.norm(p - ci, axis=1) - ri) * 1e3)
        keys.append(_directions(p, ci))
        ang.append(pts.angles_deg[s])
        t.append(float(np.mean(pts.time_s[s:e])))
        c.append(ci)
        r.append(ri)
        rms.append(q)
        pos.append(int(ids[s]))
        npt.append(e - s)
        fac.append(float(np.trace(blk[-1])))
    r_arr = np.asarray(r)
    return SphereCentres(np.asarray(ang), np.asarray(t), np.asarray(c), r_arr, np.asarray(rms),
                         np.abs(r_arr - nominal_radius_mm) <= tol_mm, np.asarray(pos),
                         np.asarray(npt), np.asarray(fac), np.asarray(blk), tuple(resid),
                         tuple(keys))
