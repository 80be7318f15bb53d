"""The standard tests ``abbe diagnose`` recommends to separate ambiguous explanations.

:func:`standard_checks` gives the geometry of the usual tests for a table: a
ballbar in each plane (CW + CCW) and a laser line per axis, with zero measured
values, so that the two explanations can be predicted on each and compared.
Units: mm, um, s.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from abbe.diagnose.checks import BallbarCheck, Check, LaserChannel, LaserCheck
from abbe.model.geometry import PLANE_AXES
from abbe.model.table import AXES, Table

#: Laser channel map of the standard laser lines (channel -> (term, sign)).
LASER_MAP: dict[str, dict[str, tuple[str, int]]] = {
    "X": {"linear": ("dx", 1), "straight_h": ("dy", 1), "straight_v": ("dz", 1)},
    "Y": {"linear": ("dy", 1), "straight_h": ("dx", 1), "straight_v": ("dz", 1)},
    "Z": {"linear": ("dz", 1), "straight_h": ("dx", 1), "straight_v": ("dy", 1)},
}


def ballbar_geometry(plane: str, center_mm: tuple[float, float, float], name: str | None = None,
                     radius_mm: float = 100.0, feed_mm_min: float = 1000.0, step_deg: float = 2.0,
                     arc_deg: float = 10.0, pause_s: float = 1.0,
                     t0_s: float = 0.0) -> dict[str, Any]:
    """Samples of a CCW-then-CW ballbar test: direction, angle (deg), time (s)."""
    om = math.degrees(feed_mm_min / 60.0 / radius_mm)  # deg/s
    a_ccw = np.arange(-arc_deg, 360.0 + arc_deg + 1e-9, step_deg)
    a_cw = a_ccw[::-1] + 0.5 * step_deg
    t_ccw = t0_s + (a_ccw - a_ccw[0]) / om
    t_cw = t_ccw[-1] + pause_s + (a_cw[0] - a_cw) / om
    return {"name": name or f"ballbar_{plane.lower()}", "plane": plane,
            "center_mm": center_mm, "radius_mm": radius_mm, "feed_mm_min": feed_mm_min,
            "direction": np.array(["ccw"] * a_ccw.size + ["cw"] * a_cw.size),
            "angle_deg": np.concatenate([a_ccw, a_cw]),
            "time_s": np.concatenate([t_ccw, t_cw])}


def ballbar_check_from(geom: dict[str, Any], radial_um: np.ndarray,
                       reference_mm: tuple[float, float, float]) -> BallbarCheck:
    return BallbarCheck(geom["name"], geom["plane"], geom["center_mm"], geom["radius_mm"],
                        geom["feed_mm_min"], geom["direction"], geom["angle_deg"], radial_um,
                        geom["time_s"], reference_mm, source="<synthetic>")


def standard_checks(table: Table) -> list[Check]:
    """Geometry of the usual tests for ``table`` (measured values 0): a ballbar in each
    plane (centre mid-travel, R = min(100, 0.4 x the smaller span), F 1000 mm/min, CW + CCW)
    and a laser line per axis through the reference point (linear + straightness)."""
    mid = tuple(0.5 * (table.axes[a].travel_mm[0] + table.axes[a].travel_mm[1]) for a in AXES)
    out: list[Check] = []
    for plane in ("XY", "YZ", "ZX"):
        a, b = PLANE_AXES[plane]
        span = min(np.ptp(table.axes[AXES[a]].travel_mm), np.ptp(table.axes[AXES[b]].travel_mm))
        g = ballbar_geometry(plane, radius_mm=float(min(100.0, 0.4 * span)), step_deg=4.0,
                             center_mm=mid)  # type: ignore[arg-type]
        out.append(ballbar_check_from(g, np.zeros(g["angle_deg"].size), table.reference_mm))
    for a in AXES:
        lo, hi = table.axes[a].travel_mm
        tg = np.linspace(lo, hi, 11)
        n_runs, T = 2, tg.size
        order = np.arange(n_runs * 2 * T).reshape(n_runs, 2, T)
        chans = [LaserChannel(ch, LASER_MAP[a][ch][0], LASER_MAP[a][ch][1],
                              np.zeros((n_runs, 2, T))) for ch in LASER_MAP[a]]
        out.append(LaserCheck(f"laser_{a}", a, table.reference_mm, tg, chans, order,
                              table.reference_mm, time_s=order * 10.0))
    return out


def faster_circles(checks: list[Check], factor: float = 3.0) -> list[Check]:
    """The ballbar tests among ``checks`` repeated at ``factor`` x their feed (measured
    values 0): a dynamic error (servo mismatch) grows with the feed, a geometric one
    does not, so the same circle at a second feed separates them."""
    out: list[Check] = []
    seen: set[tuple] = set()
    for c in checks:
        if not isinstance(c, BallbarCheck):
            continue
        key = (c.plane, tuple(np.round(c.center_mm, 3)), round(c.radius_mm, 3))
        if key in seen:
            continue
        seen.add(key)
        f = c.feed_mm_min * factor
        g = ballbar_geometry(c.plane, tuple(c.center_mm), name=f"{c.name} at {f:g} mm/min",
                             radius_mm=c.radius_mm, feed_mm_min=f, step_deg=4.0)
        out.append(ballbar_check_from(g, np.zeros(g["angle_deg"].size), tuple(c.reference_mm)))
    return out
