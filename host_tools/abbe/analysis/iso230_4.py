"""ISO 230-4 circular test evaluation of a ballbar trace, and its polar plot.

A least-squares circle (geometric fit, scipy) per direction and for both
directions together; centre offset (um, in plane axes a, b), radius deviation
(um), circular deviation G = max - min of the radial residuals (per direction
and bidirectional), circular hysteresis H = max |CCW - CW| residual at the same
angle. Feed-in / feed-out arcs (angles outside [0, 360)) are not evaluated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from abbe.formats.ballbar_csv import BallbarTrace
from abbe.model.geometry import DIRECTIONS, PLANE_AXES


@dataclass
class CircleFit:
    """Least-squares circle: centre offset (um, plane axes a, b), radius deviation (um),
    residuals (um) of the fitted samples, circular deviation G = max - min (um)."""

    center_um: tuple[float, float]
    radius_dev_um: float
    residual_um: np.ndarray
    G_um: float


def fit_circle(angle_deg: np.ndarray, radial_um: np.ndarray, radius_mm: float) -> CircleFit:
    """Least-squares circle of a ballbar trace.

    Model: the machine's path is the commanded circle shifted by the centre
    offset c (um, plane axes a, b: the path centre relative to the centre ball) and
    the bar reads ``|c + R u(theta)| - R + rho``, rho the radius deviation (um).
    Minimises sum (dR_i - model_i)^2 over (c, rho) with scipy least_squares, started
    from the linearised solution ``dR ~ c . u + rho`` (to which it reduces for small
    c). Exact for a pure set-up offset of any size.
    """
    th = np.radians(np.asarray(angle_deg, dtype=np.float64))
    dr = np.asarray(radial_um, dtype=np.float64)
    A = np.stack([np.cos(th), np.sin(th), np.ones_like(th)], axis=1)
    lin, *_ = np.linalg.lstsq(A, dr, rcond=None)
    R_um = radius_mm * 1000.0
    ux, uy = np.cos(th), np.sin(th)

    def res(p: np.ndarray) -> np.ndarray:
        return dr - (np.hypot(p[0] + R_um * ux, p[1] + R_um * uy) - R_um + p[2])

    sol = least_squares(res, lin, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    r = res(sol.x)
    return CircleFit(center_um=(float(sol.x[0]), float(sol.x[1])), radius_dev_um=float(sol.x[2]),
                     residual_um=r, G_um=float(r.max() - r.min()))


@dataclass
class BallbarResult:
    """ISO 230-4 evaluation of one trace (um; centre in the plane axes a, b)."""

    name: str
    plane: str
    radius_mm: float
    feed_mm_min: float
    per_direction: dict[str, CircleFit]
    both: CircleFit
    H_um: float
    n_samples: dict[str, int]
    angles: dict[str, np.ndarray] = field(default_factory=dict)
    residual_both: dict[str, np.ndarray] = field(default_factory=dict)

    def axis_names(self) -> tuple[str, str]:
        a, b = PLANE_AXES[self.plane]
        return ("XYZ"[a], "XYZ"[b])

    def to_json(self) -> dict[str, Any]:
        """JSON-ready summary (um)."""
        na, nb = self.axis_names()

        def fit(cf: CircleFit) -> dict[str, Any]:
            return {f"center_{na.lower()}_um": round(cf.center_um[0], 4),
                    f"center_{nb.lower()}_um": round(cf.center_um[1], 4),
                    "radius_dev_um": round(cf.radius_dev_um, 4), "G_um": round(cf.G_um, 4)}

        return {"name": self.name, "plane": self.plane, "radius_mm": self.radius_mm,
                "feed_mm_min": self.feed_mm_min,
                "ccw": fit(self.per_direction["ccw"]), "cw": fit(self.per_direction["cw"]),
                "bidirectional": fit(self.both), "H_um": round(self.H_um, 4),
                "samples": self.n_samples}

    def format_text(self) -> str:
        na, nb = self.axis_names()
        lines = [f"ballbar {self.name}: plane {self.plane}, R = {self.radius_mm:g} mm, "
                 f"F = {self.feed_mm_min:g} mm/min (ISO 230-4, LSC; feed arcs excluded)"]
        for key, cf in (("CCW", self.per_direction["ccw"]), ("CW", self.per_direction["cw"]),
                        ("both", self.both)):
            lines.append(f"  {key:5s} G = {cf.G_um:8.3f} um   centre {na}/{nb} = "
                         f"{cf.center_um[0]:8.3f} / {cf.center_um[1]:8.3f} um   "
                         f"radius dev = {cf.radius_dev_um:8.3f} um")
        lines.append(f"  circular hysteresis H = {self.H_um:.3f} um")
        return "\n".join(lines)


def _periodic_interp(x_new: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    order = np.argsort(x)
    return np.interp(x_new, x[order], y[order], period=360.0)


def evaluate_ballbar(trace: BallbarTrace, test: Any) -> BallbarResult:
    """ISO 230-4 evaluation of a trace of ``test`` (needs name, plane, radius_mm, feed_mm_min).

    Only data samples (0 <= angle < 360) are used. Per direction: its own LS
    circle, G. Bidirectional: one LS circle through both runs, G over both. H:
    max |residual_ccw(theta) - residual_cw(theta)| about the common circle, the
    CW residuals interpolated (periodically) at the CCW angles.
    """
    per: dict[str, CircleFit] = {}
    n: dict[str, int] = {}
    for d in DIRECTIONS:
        m = trace.data_mask(d)
        per[d] = fit_circle(trace.angle_deg[m], trace.radial_um[m], test.radius_mm)
        n[d] = int(m.sum())
    m = trace.data_mask()
    both = fit_circle(trace.angle_deg[m], trace.radial_um[m], test.radius_mm)
    dirs = trace.direction[m]
    ang = trace.angle_deg[m]
    res = {d: both.residual_um[dirs == d] for d in DIRECTIONS}
    angs = {d: ang[dirs == d] for d in DIRECTIONS}
    cw_at_ccw = _periodic_interp(angs["ccw"], angs["cw"], res["cw"])
    H = float(np.max(np.abs(res["ccw"] - cw_at_ccw)))
    return BallbarResult(name=test.name, plane=test.plane, radius_mm=float(test.radius_mm),
                         feed_mm_min=float(test.feed_mm_min), per_direction=per, both=both,
                         H_um=H, n_samples=n, angles=angs, residual_both=res)


def _nice(x: float) -> float:
    if x <= 0:
        return 1.0
    e = 10 ** math.floor(math.log10(x))
    for m in (1.0, 2.0, 5.0, 10.0):
        if x <= m * e:
            return m * e
    return 10.0 * e


def plot_polar(result: BallbarResult, path: str | Path, title: str | None = None) -> None:
    """Polar plot as ballbar software draws it: both runs' radial residuals about the
    bidirectional LS circle (centre and radius removed), magnified around a nominal
    circle (the bold circle = 0 um; scale in um on the radial axis). Writes a PNG."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    res_all = np.concatenate([result.residual_both[d] for d in DIRECTIONS])
    half = _nice(max(float(np.max(np.abs(res_all))), 1e-3) * 1.1)
    fig = plt.figure(figsize=(6.4, 6.4), dpi=100)
    ax = fig.add_subplot(projection="polar")
    ax.set_rorigin(-3.0 * half)
    ax.set_rlim(-half, half)
    th = np.radians(np.linspace(0.0, 360.0, 721))
    ax.plot(th, np.zeros_like(th), color="black", lw=1.6, label="nominal")
    colors = {"ccw": "tab:blue", "cw": "tab:red"}
    for d in DIRECTIONS:
        a = result.angles[d]
        r = result.residual_both[d]
        o = np.argsort(a)
        a2 = np.append(a[o], a[o][0] + 360.0)
        r2 = np.append(r[o], r[o][0])
        ax.plot(np.radians(a2), r2, color=colors[d], lw=1.0,
                label=f"{d.upper()}  G = {result.per_direction[d].G_um:.2f} um")
    na, nb = result.axis_names()
    ax.set_thetagrids(range(0, 360, 45),
                      [f"+{na}", "", f"+{nb}", "", f"-{na}", "", f"-{nb}", ""])
    ax.set_rticks([-half, -half / 2, 0.0, half / 2, half])
    ax.set_rlabel_position(22.5)
    ax.tick_params(axis="y", labelsize=7)
    c = result.both
    info = (f"G (both) = {c.G_um:.2f} um   H = {result.H_um:.2f} um\n"
            f"centre {na}/{nb} = {c.center_um[0]:.2f} / {c.center_um[1]:.2f} um   "
            f"radius dev = {c.radius_dev_um:.2f} um\n"
            f"scale: {half / 2:g} um per ring; LS circle removed")
    fig.text(0.98, 0.02, info, ha="right", va="bottom", fontsize=8, family="monospace")
    ax.set_title(title or f"ballbar {result.name}: {result.plane}, R {result.radius_mm:g} mm, "
                 f"F {result.feed_mm_min:g} mm/min", fontsize=10, pad=22)
    ax.legend(loc="lower left", bbox_to_anchor=(-0.14, -0.16), fontsize=8, frameon=False)
    fig.subplots_adjust(bottom=0.16)
    fig.savefig(str(path), format="png", metadata={"Software": None})
    plt.close(fig)
