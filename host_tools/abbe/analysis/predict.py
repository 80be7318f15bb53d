"""Prediction through the model: a ballbar test from a fitted table, against the measurement.

The paper's §4 in code: predict a circular test from a fitted model (through the
C library), compare it with the measurement (Fig. 8), and compute the roundness
if the predicted error were removed exactly (the "ideal compensation").
Compensation in the loop on the virtual machine is :mod:`abbe.sim.compensation`.

Units: positions mm, radial deviations um. "Roundness" is the ISO 230-4
bidirectional circular deviation G (one least-squares circle through the CCW
and the CW run, max - min of the residual), the figure ballbar software quotes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

from abbe.analysis.iso230_4 import BallbarResult, evaluate_ballbar, fit_circle
from abbe.errors import AbbeInputError
from abbe.formats.ballbar_csv import BallbarTrace
from abbe.formats.ballbar_file import read_ballbar_file
from abbe.formats.blob import read_blob_file
from abbe.formats.machine import Machine
from abbe.model import clib
from abbe.model.evaluate import model_error_um
from abbe.model.geometry import (
    CircleTest,
    circle_points,
    from_machine,
    radial_units,
    travel_direction,
)
from abbe.model.table import AXES, Table


@dataclass
class Prediction:
    """A measured ballbar test against the model's prediction (um).

    ``residual_um``: measured - predicted on the data samples (feed arcs
    excluded), with the set-up nuisances (centre offset, radius) removed by one
    least-squares circle. ``ideal_G_um``: its max - min, the roundness left if
    the predicted error were compensated exactly.
    """

    name: str
    test: CircleTest
    trace: BallbarTrace
    predicted_um: np.ndarray
    residual_um: np.ndarray
    before: BallbarResult

    @property
    def max_residual_um(self) -> float:
        return float(np.max(np.abs(self.residual_um)))

    @property
    def rms_residual_um(self) -> float:
        return float(np.sqrt(np.mean(self.residual_um ** 2)))

    @property
    def ideal_G_um(self) -> float:
        return float(self.residual_um.max() - self.residual_um.min())

    @property
    def roundness_before_um(self) -> float:
        return self.before.both.G_um

    @property
    def ideal_improvement_pct(self) -> float:
        return 100.0 * (1.0 - self.ideal_G_um / self.roundness_before_um)

    def to_json(self) -> dict[str, Any]:
        return {"ballbar": self.name,
                "residual_max_um": round(self.max_residual_um, 4),
                "residual_rms_um": round(self.rms_residual_um, 4),
                "roundness_before_um": round(self.roundness_before_um, 4),
                "ideal_roundness_um": round(self.ideal_G_um, 4),
                "ideal_improvement_pct": round(self.ideal_improvement_pct, 2)}


def _ballbar(machine: Machine, name: str) -> tuple[CircleTest, BallbarTrace]:
    if name not in machine.ballbar:
        known = ", ".join(sorted(machine.ballbar)) or "none"
        raise AbbeInputError(f"no ballbar test {name!r} (the machine file has: {known})",
                             file=str(machine.path), field=f"ballbar.{name}")
    bt = machine.ballbar[name]
    return from_machine(bt), read_ballbar_file(bt, str(machine.path))


def _check_model_fits_machine(machine: Machine, table: Table, model_path: str) -> None:
    """A model fitted on another machine is refused, not silently used."""
    for i, a in enumerate(AXES):
        lo, hi = table.axes[a].travel_mm
        mlo, mhi = machine.axes[a].travel_mm
        if lo < mlo - 1.0 or hi > mhi + 1.0:
            raise AbbeInputError(
                f"model travel of {a} [{lo:g}, {hi:g}] mm is outside the machine's [{mlo:g}, {mhi:g}] mm: "
                "the model is for another machine", file=model_path, field=f"axes.{a}.travel_mm")
        if abs(table.reference_mm[i] - machine.reference_mm[i]) > 1e-3:
            raise AbbeInputError(
                f"model reference point {table.reference_mm} differs from the machine's "
                f"{machine.reference_mm}: the model is for another machine or set-up",
                file=model_path, field="reference_mm")


def load_model(path: str | Path) -> tuple[bytes, Table, clib.CModel]:
    """Read a model blob; validate it in Python and in the C library."""
    blob, table = read_blob_file(path)
    return blob, table, clib.CModel(blob)


def predict(machine: Machine, model_path: str | Path, name: str) -> Prediction:
    """Predict ballbar test ``name`` with the model (C library, _f32) and compare."""
    blob, table, cmodel = load_model(model_path)
    _check_model_fits_machine(machine, table, str(model_path))
    test, trace = _ballbar(machine, name)
    takeup = tuple(float(table.axes[a].backlash_takeup_mm) for a in AXES)
    pred = predict_ballbar(cmodel, test, trace.angle_deg, trace.direction, takeup_mm=takeup)
    m = trace.data_mask()
    diff = fit_circle(trace.angle_deg[m], trace.radial_um[m] - pred[m], test.radius_mm)
    return Prediction(name=name, test=test, trace=trace, predicted_um=pred,
                      residual_um=diff.residual_um, before=evaluate_ballbar(trace, test))


def plot_prediction(p: Prediction, path: str | Path, title: str | None = None) -> None:
    """Overlay of measured and predicted traces (paper Fig. 8) and the residual."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    m = p.trace.data_mask()
    ang, dirs = p.trace.angle_deg[m], p.trace.direction[m]
    meas = fit_circle(ang, p.trace.radial_um[m], p.test.radius_mm).residual_um
    pred = fit_circle(ang, p.predicted_um[m], p.test.radius_mm).residual_um
    fig = plt.figure(figsize=(11, 4.8))
    ax = fig.add_subplot(1, 2, 1, projection="polar")
    span = max(np.abs(meas).max(), np.abs(pred).max(), 1e-3)
    base = 2.0 * span  # magnified deviation around a nominal circle
    for d, style in (("ccw", "-"), ("cw", "--")):
        k = dirs == d
        order = np.argsort(ang[k])
        th = np.radians(ang[k][order])
        ax.plot(th, base + meas[k][order], style, color="tab:blue", lw=1, label=f"measured {d.upper()}")
        ax.plot(th, base + pred[k][order], style, color="tab:red", lw=1, label=f"predicted {d.upper()}")
    ax.plot(np.linspace(0, 2 * np.pi, 361), np.full(361, base), color="0.6", lw=0.5)
    ax.set_ylim(0, base + span * 1.2)
    ax.set_yticklabels([])
    ax.set_title(f"{p.test.plane} circle R {p.test.radius_mm:g} mm (scale: {span:.1f} um per ring step)",
                 fontsize=9)
    ax.legend(loc="lower left", fontsize=7, bbox_to_anchor=(-0.15, -0.15))
    ax2 = fig.add_subplot(1, 2, 2)
    for d, c in (("ccw", "tab:green"), ("cw", "tab:purple")):
        k = dirs == d
        order = np.argsort(ang[k])
        ax2.plot(ang[k][order], p.residual_um[k][order], color=c, lw=1, label=d.upper())
    ax2.axhline(0, color="0.5", lw=0.5)
    ax2.set_xlabel("angle (deg)")
    ax2.set_ylabel("measured - predicted (um)")
    ax2.set_title(f"residual: max {p.max_residual_um:.2f} um, RMS {p.rms_residual_um:.2f} um", fontsize=9)
    ax2.legend(fontsize=8)
    ax2.grid(alpha=0.3)
    fig.suptitle(title or f"ballbar {p.name}: prediction vs measurement")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def direction_states(test: Any, angle_deg: np.ndarray, direction: np.ndarray,
                     takeup_mm: tuple[float, float, float] | None = None) -> np.ndarray:
    """Backlash direction state (N, 3) along the commanded samples, in their order.

    Without take-up (None or 0): the direction of motion (0 at a reversal point).
    With take-up: the state ramps by 2 dp / take-up along the path (as the library's
    compensator does), starting from the direction of the first motion of each axis.
    """
    from abbe.model.backlash import backlash_state

    ang = np.asarray(angle_deg, dtype=np.float64).reshape(-1)
    inst = travel_direction(test, ang, np.asarray(direction).reshape(-1))
    if takeup_mm is None:
        return inst
    pos = circle_points(test, ang)
    out = inst.copy()
    for j in range(3):
        if not takeup_mm[j] or takeup_mm[j] <= 0:
            continue
        nz = np.nonzero(inst[:, j])[0]
        s0 = float(inst[nz[0], j]) if nz.size else 1.0
        out[:, j] = backlash_state(pos[:, j], float(takeup_mm[j]), s0)
    return out


def predict_ballbar(model: Any, test: Any, angle_deg: np.ndarray | None = None,
                    direction: np.ndarray | None = None, temp_c: np.ndarray | None = None,
                    backlash: bool = True,
                    takeup_mm: tuple[float, float, float] | None = None) -> np.ndarray:
    """Predicted ballbar radial deviation (um) per sample: ``u_r . E_model`` at the
    commanded points.

    ``angle_deg``/``direction``: the samples in the order run (e.g. a measured
    trace's, feed arcs included); default one CCW revolution at 1 deg. Backlash
    direction state: :func:`direction_states` with the take-up ``takeup_mm`` (default:
    the Table's ``backlash_takeup_mm``; instantaneous for other models), off if
    ``backlash`` is False. ``temp_c`` (N, 3) axis temperatures or None (no thermal).
    Dynamic effects (servo lag) are not predicted.
    """
    from abbe.model.table import AXES, Table

    if angle_deg is None:
        angle_deg = np.arange(0.0, 360.0, 1.0)
    ang = np.asarray(angle_deg, dtype=np.float64).reshape(-1)
    dirs = (np.full(ang.size, "ccw") if direction is None
            else np.asarray(direction).reshape(-1))
    pos = circle_points(test, ang)
    ds = None
    if backlash:
        if takeup_mm is None and isinstance(model, Table):
            takeup_mm = tuple(float(model.axes[a].backlash_takeup_mm) for a in AXES)
        ds = direction_states(test, ang, dirs, takeup_mm)
    err = model_error_um(model, pos, ds, temp_c)
    return np.einsum("ni,ni->n", radial_units(test.plane, ang), err)


def predict_trace(model: Any, trace: BallbarTrace, test: Any, **kw: Any) -> np.ndarray:
    """:func:`predict_ballbar` at the samples of ``trace``."""
    return predict_ballbar(model, test, trace.angle_deg, trace.direction, **kw)


#: Gauss-Legendre nodes over a rectangular input's interval (exact for a figure that is a
#: polynomial of degree up to 2 x 12 - 1 in that input)
GL_NODES = 12


def residual_uncertainty(p: Prediction, budget: Any, draws: int = 0,
                         seed: int = 20232) -> dict[str, Any]:
    """U (k = 2) of the prediction residual's max |r| and RMS (um) from the ballbar's own
    budget (``abbe.analysis.uncertainty.ballbar_budget``, docs/uncertainty.md "ISO 230-4").

    The residual is the measured circle minus the model's prediction, a least-squares
    circle removed (:func:`predict`). The prediction is held fixed (the table the controller
    applies is known exactly once written), so r is uncertain by the measurement: see
    :func:`trace_residual_uncertainty`. With ``draws`` a Monte Carlo of the same inputs
    (GUM S1) is returned beside it."""
    m = p.trace.data_mask()
    ang = p.trace.angle_deg[m]
    pred = p.predicted_um

    def residual_of(rr: np.ndarray) -> np.ndarray:
        return fit_circle(ang, rr[m] - pred[m], p.test.radius_mm).residual_um

    return trace_residual_uncertainty(p.trace, float(p.test.radius_mm), residual_of, budget,
                                      draws=draws, seed=seed)


def trace_residual_uncertainty(trace: BallbarTrace, radius_mm: float,
                               residual_of: Callable[[np.ndarray], np.ndarray], budget: Any,
                               draws: int = 0, seed: int = 20232,
                               note: str = "measurement of the circle only; the prediction "
                                           "(the table as written) is held fixed"
                               ) -> dict[str, Any]:
    """U (k = 2) of max |r| and RMS (um) of a residual ``residual_of(readings)`` of a
    ballbar trace (the readings, um, every sample of ``trace``: the model's prediction and
    the set-up removal are inside ``residual_of``, held fixed), from the ballbar budget.

    Inputs: the bar's reading scale and the drift ramp over the test (each rectangular,
    acting alone: the standard deviation of the figure over its interval by Gauss-Legendre
    quadrature of the same evaluation, :data:`GL_NODES` nodes), the resolution per reading
    (first order: max, the one reading that makes it; RMS, averaged over the n readings,
    1 / sqrt(n)). The bar's length (calibration,
    temperature) moves every reading alike and the set-up removal absorbs it. With
    ``draws`` a Monte Carlo of the same inputs (GUM S1) is returned beside it; beyond 10 %
    its U is the one stated (``U_stated_um``)."""
    from abbe.analysis.uncertainty import K, _ramp
    f = budget.figures
    r = np.asarray(trace.radial_um, dtype=np.float64)
    ramp = _ramp(trace)

    def figures(rr: np.ndarray) -> np.ndarray:
        res = residual_of(rr)
        return np.array([np.max(np.abs(res)), np.sqrt(np.mean(res ** 2))])

    base = figures(r)
    L_mm = float(radius_mm)
    scale_h = f["scale_pct"] / 100.0
    drift_um = abs(f["expansion_ppm_per_k"]) * f["drift_c"] * L_mm * 1e-3
    # scale and drift: each one input acting alone, its standard deviation over the whole
    # rectangular interval (Gauss-Legendre), not a derivative at its centre: a residual
    # left by a least-squares fit sits near a minimum in some directions (the RMS of a
    # small residual against a drift ramp it is nearly orthogonal to), where the
    # derivative is near 0 and the spread is not (measured on the demo's diagnosed model:
    # the first order 22 % low against the Monte Carlo)
    nodes, weights = np.polynomial.legendre.leggauss(GL_NODES)
    weights = weights / 2.0

    def spread(perturbed: Callable[[float], np.ndarray]) -> np.ndarray:
        v = np.array([figures(perturbed(float(t))) for t in nodes])
        mean = weights @ v
        return np.sqrt(np.clip(weights @ (v - mean) ** 2, 0.0, None))

    s_scale = spread(lambda t: r * (1 + t * scale_h))
    s_drift = spread(lambda t: r + t * drift_um * ramp)
    u_res = f["resolution_um"] / math.sqrt(12.0)
    n = int(np.size(residual_of(r)))
    c_res = np.array([1.0, 1.0 / math.sqrt(max(n, 1))])
    out: dict[str, Any] = {"k": K, "budget": getattr(budget, "source", ""), "note": note}
    for i, key in enumerate(("max_abs", "rms")):
        parts = {"scale": float(s_scale[i]), "thermal drift": float(s_drift[i]),
                 "resolution": c_res[i] * u_res}
        u = math.sqrt(sum(v ** 2 for v in parts.values()))
        out[key] = {"value_um": float(base[i]), "u_um": u, "U_um": K * u,
                    "budget_u_um": parts}
    if draws:
        rng = np.random.default_rng(seed)
        F = np.empty((draws, 2))
        for k in range(draws):
            rr = (r * (1 + rng.uniform(-1, 1) * f["scale_pct"] / 100.0)
                  + rng.uniform(-drift_um, drift_um) * ramp
                  + rng.uniform(-0.5, 0.5, size=r.shape) * f["resolution_um"])
            F[k] = figures(rr)
        for i, key in enumerate(("max_abs", "rms")):
            d = out[key]
            d["U_mc_um"] = K * float(F[:, i].std(ddof=1))
            # GUM S1 validation, as the thermal results: beyond 10 % the first order is not
            # adequate (the max: readings compete for it, its spread is smaller than one
            # reading's) and the Monte Carlo's U is the one stated
            ok = d["U_um"] > 0 and abs(d["U_mc_um"] / d["U_um"] - 1.0) <= 0.10
            d["U_stated_um"] = d["U_um"] if ok else d["U_mc_um"]
            d["U_from"] = ("first order (the Monte Carlo agrees within 10 %)" if ok else
                           "Monte Carlo (the first order is more than 10 % off)")
        out["monte_carlo"] = {"draws": draws, "seed": seed}
    else:
        for key in ("max_abs", "rms"):
            out[key]["U_stated_um"] = out[key]["U_um"]
            out[key]["U_from"] = "first order (no Monte Carlo run)"
    return out
