"""Where an export's residual is evaluated: the work volume grid and the ballbar circles.

The work volume is the machine file's axis travel (``--machine``), else the
model's fitted travel. Its grid has, per axis, n = clip(ceil(travel / 5 mm) + 1,
21, 61) equally spaced points including both ends (vmc500: 61 x 61 x 61).
A circle is the machine file's ballbar test, run CCW from -45 deg to 405 deg
and back CW (feed-in and feed-out arcs of 45 deg, so the direction state of every
axis is established), sampled every 0.1 deg; the data arc [0, 360) of each run
is evaluated. Positions mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from abbe.errors import AbbeInputError
from abbe.model.geometry import circle_points, radial_units
from abbe.model.table import AXES, Table

GRID_STEP_MM = 5.0
GRID_MIN_POINTS = 21
GRID_MAX_POINTS = 61
CIRCLE_STEP_DEG = 0.1
FEED_ARC_DEG = 45.0


@dataclass(frozen=True)
class Circle:
    """A ballbar circle (machine file section ``ballbar.NAME``)."""

    name: str
    plane: str
    center_mm: tuple[float, float, float]
    radius_mm: float


@dataclass(frozen=True)
class CirclePath:
    """The commanded path of one circle: CCW then CW, with the feed arcs.

    pos_mm (N, 3); angle_deg (N,); direction (N,) +1 CCW / -1 CW; data (N,) bool:
    on the evaluated data arc [0, 360). u_r (N, 3) radial unit vectors.
    """

    circle: Circle
    pos_mm: np.ndarray
    angle_deg: np.ndarray
    direction: np.ndarray
    data: np.ndarray
    u_r: np.ndarray


@dataclass(frozen=True)
class WorkVolume:
    """The travel of each axis (mm) and where it came from."""

    travel_mm: dict[str, tuple[float, float]]
    source: str
    circles: tuple[Circle, ...] = ()

    def counts(self) -> dict[str, int]:
        """Grid points per axis (module docstring)."""
        out = {}
        for a in AXES:
            lo, hi = self.travel_mm[a]
            n = int(math.ceil((hi - lo) / GRID_STEP_MM - 1e-9)) + 1
            out[a] = int(min(GRID_MAX_POINTS, max(GRID_MIN_POINTS, n)))
        return out

    def axis_samples(self, counts: dict[str, int] | None = None) -> dict[str, np.ndarray]:
        """Equally spaced positions per axis, both ends included, mm."""
        c = counts or self.counts()
        return {a: np.linspace(self.travel_mm[a][0], self.travel_mm[a][1], c[a]) for a in AXES}

    def grid(self, counts: dict[str, int] | None = None) -> np.ndarray:
        """All grid points (N, 3), X varying slowest. mm."""
        s = self.axis_samples(counts)
        gx, gy, gz = np.meshgrid(s["X"], s["Y"], s["Z"], indexing="ij")
        return np.column_stack([gx.ravel(), gy.ravel(), gz.ravel()])

    def describe(self) -> dict:
        """JSON description of the grid (for residual.json)."""
        c = self.counts()
        return {"source": self.source,
                "axes": {a: {"min_mm": self.travel_mm[a][0], "max_mm": self.travel_mm[a][1],
                             "points": c[a]} for a in AXES},
                "points": int(np.prod(list(c.values())))}


def circle_path(c: Circle) -> CirclePath:
    """CCW from -45 to 405 deg, then CW back (module docstring)."""
    n = int(round((360.0 + 2 * FEED_ARC_DEG) / CIRCLE_STEP_DEG))
    up = np.linspace(-FEED_ARC_DEG, 360.0 + FEED_ARC_DEG, n + 1)
    ang = np.concatenate([up, up[::-1][1:]])
    direc = np.concatenate([np.ones(up.size), -np.ones(up.size - 1)])
    data = (ang >= 0.0) & (ang < 360.0)
    data[up.size - 1] = False  # the turn-around point belongs to neither run
    pos = circle_points(c, ang)
    return CirclePath(circle=c, pos_mm=pos, angle_deg=ang, direction=direc, data=data,
                      u_r=radial_units(c.plane, ang))


def work_volume(table: Table, machine=None) -> WorkVolume:
    """The work volume of ``machine`` (an ``abbe.formats.machine.Machine``) or, without
    one, the model's fitted travel. Circles come from the machine file only."""
    if machine is None:
        return WorkVolume({a: tuple(float(v) for v in table.axes[a].travel_mm)  # type: ignore[misc]
                           for a in AXES}, source="model travel (no machine file given)")
    travel = {}
    for a in AXES:
        if a not in machine.axes:
            raise AbbeInputError(f"the machine file has no [axes.{a}]: the work volume needs "
                                 "all three travels", file=str(machine.path), field=f"axes.{a}")
        travel[a] = tuple(float(v) for v in machine.axes[a].travel_mm)
    circles = tuple(Circle(name=b.name, plane=b.plane,
                           center_mm=tuple(float(v) for v in b.center_mm),  # type: ignore[arg-type]
                           radius_mm=float(b.radius_mm))
                    for _, b in sorted(machine.ballbar.items()))
    return WorkVolume(travel, source=f"machine file {machine.path.name}", circles=circles)
