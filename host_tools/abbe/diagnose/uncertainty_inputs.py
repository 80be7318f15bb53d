"""The instrument inputs of ``abbe diagnose``'s uncertainty (moved from
:mod:`abbe.diagnose.uncertainty`): the budget of each check's instrument
(``[uncertainty.*]`` of the machine file, else the class defaults; docs/uncertainty.md)
as inputs to propagate: one common to many readings (a laser's scale, a ballbar's drift
ramp and calibration: :class:`Systematic`), one per target (linearity: :class:`Grouped`)
and one per reading (resolution: :class:`PerReading`). ``K`` (= 2) is the coverage factor
of every figure the diagnosis states.

Units: um per unit of each input's t; ppm for a laser's scale inputs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from abbe.diagnose.checks import OWN_TERM, BallbarCheck, LaserCheck


K = 2.0
SQRT3 = math.sqrt(3.0)


@dataclass
class Systematic:
    """One input common to many readings: dy = t * pattern, t from U(low, high)."""

    name: str
    check: str
    pattern: np.ndarray     # (N,) um per unit of t
    low: float = -1.0
    high: float = 1.0
    normal_sd: float | None = None  # set: t is normal with this standard deviation
    #: a laser line's scale-like input (a ramp along this axis' own channel): propagated
    #: with the axis' scale free in the fit unless a scale of the axis is named
    ramp_axis: str | None = None

    @property
    def sd(self) -> float:
        if self.normal_sd is not None:
            return self.normal_sd
        return (self.high - self.low) / math.sqrt(12.0)

    def draw(self, rng: np.random.Generator) -> float:
        if self.normal_sd is not None:
            return float(rng.normal(0.0, self.normal_sd))
        return float(rng.uniform(self.low, self.high))


@dataclass
class Grouped:
    """An error per label (a target's linearity), independent between labels, the same for
    every reading of the label: U(-half, half) um; label -1 = not affected."""

    name: str
    check: str
    labels: np.ndarray      # (N,) int
    half_um: float


@dataclass
class PerReading:
    """An error per reading (resolution): U(-half_i, half_i) um, independent."""

    name: str
    check: str
    half_um: np.ndarray     # (N,)


@dataclass
class Inputs:
    systematic: list[Systematic]
    grouped: list[Grouped]
    per_reading: list[PerReading]
    budgets: dict[str, Any]


def instrument_inputs(prob: Any, laser_budget: Any, ballbar_budget: Any) -> Inputs:
    """The instrument inputs of every check of ``prob`` (one input per line of the budget)."""
    from abbe.analysis.uncertainty import scale_inputs
    N = prob.N
    sysl: list[Systematic] = []
    grp: list[Grouped] = []
    per: list[PerReading] = []
    budgets: dict[str, Any] = {}
    for i, c in enumerate(prob.checks):
        s = prob.slice(i)
        if isinstance(c, BallbarCheck) and ballbar_budget is not None:
            f = ballbar_budget.figures
            budgets[c.name] = ballbar_budget.to_json()
            t = np.asarray(c.all_time, dtype=np.float64)[c.mask]
            span = float(np.ptp(c.all_time)) or 1.0
            ramp = (t - float(np.min(c.all_time))) / span
            p = np.zeros(N)
            p[s] = c.y * f["scale_pct"] / 100.0
            sysl.append(Systematic("ballbar scale", c.name, p))
            p = np.zeros(N)
            p[s] = abs(f["expansion_ppm_per_k"]) * f["drift_c"] * c.radius_mm * 1e-3 * ramp
            sysl.append(Systematic("ballbar thermal drift", c.name, p))
            p = np.zeros(N)
            p[s] = 1.0
            sysl.append(Systematic("ballbar length (calibration)", c.name, p,
                                   normal_sd=f["calibration_U_um"] / 2.0))
            h = np.zeros(N)
            h[s] = f["resolution_um"] / 2.0
            per.append(PerReading("ballbar resolution", c.name, h))
        elif isinstance(c, LaserCheck) and laser_budget is not None:
            f = laser_budget.figures
            budgets[c.name] = laser_budget.to_json()
            own = next((k for k, ch in enumerate(c.channels) if ch.term == OWN_TERM[c.axis]), None)
            if own is None:
                continue
            rows = np.zeros(N, dtype=bool)
            rows[s] = c.group == own
            dist_um = (np.asarray(c.x, dtype=np.float64) - float(c.reference_mm[c.j])) * 1e3
            for si in scale_inputs(laser_budget, None):
                p = np.zeros(N)
                p[s] = np.where(c.group == own, dist_um * 1e-6, 0.0)
                sysl.append(Systematic(si.name, c.name, p, si.low_ppm, si.high_ppm,
                                       ramp_axis=c.axis))
            if f["linearity_um"] > 0:
                lab = np.full(N, -1)
                lab[s] = np.where(c.group == own, c.cell % c.T, -1)  # one error per target, both directions
                grp.append(Grouped("linearity (per target)", c.name, lab, f["linearity_um"]))
            if f["resolution_um"] > 0:
                h = np.zeros(N)
                h[rows] = f["resolution_um"] / 2.0
                per.append(PerReading("resolution", c.name, h))
    return Inputs(sysl, grp, per, budgets)


def budgets_of_machine(machine: Any) -> tuple[Any, Any]:
    """(laser budget, ballbar budget) of a machine file: its ``[uncertainty.*]``, else the
    class defaults (laser_interferometer, ballbar)."""
    from abbe.analysis.uncertainty import ballbar_budget
    from abbe.formats.uncertainty_spec import default_budget
    extra = getattr(machine, "extra", None) or {}
    spec = extra.get("uncertainty")
    laser = spec.laser if spec is not None and spec.laser is not None else None
    if laser is None:
        laser = default_budget("laser_interferometer")
        laser.source = "class defaults (docs/uncertainty.md)"
    if hasattr(machine, "extra"):
        return laser, ballbar_budget(machine)[0]
    ballbar = default_budget("ballbar")
    ballbar.source = "class defaults (docs/uncertainty.md)"
    return laser, ballbar


def budget_of_positioning_file(path: Any) -> Any:
    """The class default of an ISO 230-2 file: laser_triangulation for an ecmc .dat (the
    ESS file names an ILD sensor), else laser_interferometer (as ``abbe iso230-2``)."""
    from pathlib import Path

    from abbe.formats import ess_dat
    from abbe.formats.uncertainty_spec import default_budget
    cls = "laser_triangulation" if ess_dat.looks_like_dat(Path(path)) else "laser_interferometer"
    b = default_budget(cls)
    b.source = f"class defaults {cls} (docs/uncertainty.md)"
    return b
