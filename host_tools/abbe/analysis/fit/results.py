"""What ``abbe fit`` produces, as data: one fitted term (:class:`TermResult`), one axis
(:class:`AxisResult`), the machine (:class:`FitResult`). A module of its own so that the
pipeline, the report and the uncertainty read the same types without importing each
other. Units: targets mm, linear terms um, angular terms urad.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from abbe.analysis.fit.prep import RunStats
from abbe.analysis.fit.select import AxisFit
from abbe.analysis.iso230_2 import Iso230Result
from abbe.formats.laser_csv import LaserData
from abbe.formats.machine import LaserLine, Machine
from abbe.analysis.fit.options import FitOptions
from abbe.model.table import LINEAR_TERMS, OWN_TERM, AxisTable, Table


TERM_NAMES = {"dx": "d_x", "dy": "d_y", "dz": "d_z", "ex": "eps_x", "ey": "eps_y",
              "ez": "eps_z"}
JSON_FORMAT = "abbe-fit"


def unit_of(term: str) -> str:
    """um for linear terms, urad for angular terms."""
    return "um" if term in LINEAR_TERMS else "urad"


def role_of(axis: str, term: str) -> str:
    """positioning / straightness / angular (roll, pitch or yaw by axis)."""
    if term == OWN_TERM[axis]:
        return "positioning"
    if term in LINEAR_TERMS:
        return "straightness"
    about = term[1]
    return "roll" if about == axis.lower() else "angular"


@dataclass
class TermResult:
    """One fitted term. Arrays over the T targets; runs (n_runs, 2, T).

    All values are after detrending and relative to the reference point (the
    stored model is 0 there). ``ref_shift`` is the total value subtracted.
    """

    axis: str
    term: str
    channel: str
    sign: int
    runs: np.ndarray
    stats: RunStats
    detrend: dict[str, float] | None
    ref_shift: float
    order: tuple[int, int]
    coef: np.ndarray
    predictions: dict[str, dict[str, np.ndarray]]
    metrics: dict[str, dict[str, dict[str, float]]]
    paper_f3_period_mm: float | None
    post_shift: float = 0.0  # the part of ref_shift applied after the fit (exact zero at ref)
    quant_error: float = float("nan")

    @property
    def unit(self) -> str:
        return unit_of(self.term)


@dataclass
class AxisResult:
    """Fit of one measured axis."""

    axis: str
    line: LaserLine
    data: LaserData
    targets_mm: np.ndarray
    fit: AxisFit
    terms: dict[str, TermResult]
    backlash: dict[str, Any]
    iso: Iso230Result | None
    table: AxisTable
    n_measured: int = 0  # targets in the file (targets_mm holds the bins of a dense line)
    thermal: dict[str, Any] = field(default_factory=dict)
    ref_mm: float = 0.0  # the reference point's coordinate on this axis (every term 0 there)


@dataclass
class FitResult:
    """Everything ``abbe fit`` writes."""

    machine: Machine
    options: FitOptions
    table: Table
    blob: bytes
    axes: dict[str, AxisResult]
    model_json: dict[str, Any] = field(default_factory=dict)
    #: every fitted term's covariance and the compensated residual
    #: (:class:`abbe.analysis.fit.uncertainty.FitUncertainty`)
    uncertainty: Any = None
