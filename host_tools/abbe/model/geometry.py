"""Geometry of circular tests: planes, commanded points, unit vectors, travel checks.

Conventions (notes.md §4, docs/formats.md "Ballbar and simulation"): planes
follow G17/G18/G19 and the right-hand rule; the angle theta runs XY: from +X
toward +Y, ZX: from +Z toward +X, YZ: from +Y toward +Z; CCW = increasing theta.
The commanded point at theta is ``centre + R (cos theta e_a + sin theta e_b)``
with (a, b) = (X, Y), (Z, X), (Y, Z). Positions mm, angles deg.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from abbe.errors import AbbeInputError

PLANES: tuple[str, ...] = ("XY", "YZ", "ZX")

#: plane -> indices (a, b) of the axes spanning it: theta from +a toward +b.
PLANE_AXES: dict[str, tuple[int, int]] = {"XY": (0, 1), "ZX": (2, 0), "YZ": (1, 2)}

DIRECTIONS: tuple[str, str] = ("ccw", "cw")


@dataclass(frozen=True)
class CircleTest:
    """One circular test: geometry plus the simulation settings.

    plane: "XY", "YZ" or "ZX"; center_mm (3,) machine coordinates; radius_mm;
    feed_mm_min. Simulation only: sample_deg (angular step of the recorded
    samples), feed_arc_deg (feed-in and feed-out arcs), pause_s (between the CCW
    and the CW run), setup_offset_um (3,) (centre ball off the commanded centre),
    file (relative CSV path).
    """

    name: str
    plane: str
    center_mm: tuple[float, float, float]
    radius_mm: float
    feed_mm_min: float
    sample_deg: float = 0.5
    feed_arc_deg: float = 45.0
    pause_s: float = 2.0
    setup_offset_um: tuple[float, float, float] = (0.0, 0.0, 0.0)
    file: str = ""

    @property
    def axes(self) -> tuple[int, int]:
        return PLANE_AXES[self.plane]

    @property
    def omega_deg_s(self) -> float:
        """Angular speed at the programmed feed, deg/s."""
        return math.degrees(self.feed_mm_min / 60.0 / self.radius_mm)


def from_machine(bt: Any) -> CircleTest:
    """CircleTest from an ``abbe.formats.machine.BallbarTest`` (or anything with the same fields)."""
    return CircleTest(name=bt.name, plane=bt.plane, center_mm=tuple(bt.center_mm),
                      radius_mm=float(bt.radius_mm), feed_mm_min=float(bt.feed_mm_min),
                      file=str(bt.file))


def radial_units(plane: str, angle_deg: np.ndarray) -> np.ndarray:
    """Unit vectors u_r (N, 3) from the centre to the commanded point."""
    th = np.radians(np.asarray(angle_deg, dtype=np.float64).reshape(-1))
    a, b = PLANE_AXES[plane]
    u = np.zeros((th.size, 3))
    u[:, a] = np.cos(th)
    u[:, b] = np.sin(th)
    return u


def tangent_units(plane: str, angle_deg: np.ndarray) -> np.ndarray:
    """Unit vectors (N, 3) along increasing theta (the CCW direction of travel)."""
    th = np.radians(np.asarray(angle_deg, dtype=np.float64).reshape(-1))
    a, b = PLANE_AXES[plane]
    u = np.zeros((th.size, 3))
    u[:, a] = -np.sin(th)
    u[:, b] = np.cos(th)
    return u


def circle_points(test: Any, angle_deg: np.ndarray) -> np.ndarray:
    """Commanded machine positions (N, 3) mm at the angles (deg)."""
    c = np.asarray(test.center_mm, dtype=np.float64)
    return c + float(test.radius_mm) * radial_units(test.plane, angle_deg)


def travel_direction(test: Any, angle_deg: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Per-axis direction of motion (N, 3) in {-1, 0, +1} along the commanded circle."""
    d = np.where(np.asarray(direction) == "cw", -1.0, 1.0)
    v = tangent_units(test.plane, angle_deg) * d[:, None]
    v[np.abs(v) < 1e-12] = 0.0
    return np.sign(v)


def check_test_in_travel(test: Any, travel_mm: dict[str, tuple[float, float]],
                         file: str | None = None, line: int | None = None) -> None:
    """The circle (and its centre) must lie inside the machine travel (mm)."""
    a, b = PLANE_AXES[test.plane]
    for k, ax in enumerate("XYZ"):
        if ax not in travel_mm:
            continue
        lo, hi = travel_mm[ax]
        c = float(test.center_mm[k])
        r = float(test.radius_mm) if k in (a, b) else 0.0
        if c - r < lo - 1e-6 or c + r > hi + 1e-6:
            fld = "radius_mm" if lo <= c <= hi else "center_mm"
            raise AbbeInputError(
                f"circle {ax.lower()} = {c:g} +/- {r:g} mm leaves the travel [{lo:g}, {hi:g}] mm "
                f"of axis {ax}", file=file, line=line, field=f"ballbar.{test.name}.{fld}")
