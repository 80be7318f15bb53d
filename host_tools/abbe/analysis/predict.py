"""Ballbar prediction through the C library, and compensation in the loop.

The paper's §4 in code: predict a circular test from a fitted model, compare
it with the measurement (Fig. 8), compute the roundness if the predicted error
were removed exactly (the "ideal compensation"), and run the circle again on
the virtual machine with the C compensator correcting each interpolation cycle.

Units: positions mm, radial deviations um. "Roundness" is the ISO 230-4
bidirectional circular deviation G (one least-squares circle through the CCW
and the CW run, max - min of the residual), the figure ballbar software quotes.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from abbe.model import clib
from abbe.analysis.iso230_4 import (BallbarResult, BallbarTrace, CircleTest, evaluate_ballbar, fit_circle,
                          from_machine, predict_ballbar, read_ballbar_csv)
from abbe.errors import AbbeInputError
from abbe.formats.machine import Machine
from abbe.formats.blob import AXES, Table, read_blob

# Compensator settings for the virtual machine's 1 kHz interpolation cycle: the
# same safety layer a drive would run (limits, rate limit, fades, watchdog).
DEMO_COMP_CONFIG: dict[str, Any] = {
    "warn_nm": 30_000, "limit_nm": 100_000,   # 30 um warning, 100 um fault
    "rate_nm_per_cycle": 500,                 # 0.5 um per ms
    "fade_cycles": 500, "stale_cycles": 5, "axis_sign": 1,
}


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
    return from_machine(bt), read_ballbar_csv(bt.file)


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
    path = Path(path)
    try:
        blob = path.read_bytes()
    except OSError as exc:
        raise AbbeInputError(f"cannot read model: {exc}", file=str(path)) from None
    table = read_blob(blob, source=str(path))
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


def compensated_circle(truth_path: str | Path, test: CircleTest, blob: bytes, start_time_s: float,
                       noise_um: float, seed: int,
                       config: dict[str, Any] | None = None) -> tuple[BallbarTrace, dict[str, int]]:
    """Run ``test`` on the virtual machine of ``truth_path`` with the C compensator
    (model ``blob``) in the loop at 1 kHz, and measure it with the ballbar.

    Returns the measured trace and the compensator's counters.
    """
    from abbe.sim.instruments import ccompensator_step, run_circle_with_compensation
    from abbe.sim.virtual_machine import VirtualMachine
    from abbe.sim.truth import load_truth

    vm = VirtualMachine(load_truth(truth_path))
    comp = clib.CCompensator(config or DEMO_COMP_CONFIG)
    comp.load_model(blob)
    comp.enable()
    trace = run_circle_with_compensation(vm, test, ccompensator_step(comp), start_time_s=start_time_s,
                                         noise_um=noise_um, rng=np.random.default_rng(seed))
    return trace, comp.stats()


def campaign_test(truth_path: str | Path, name: str) -> tuple[CircleTest, float, float, float]:
    """The simulated test ``name`` as the campaign ran it (with its simulation
    settings), its end time (s), the gap between tests (s) and the ballbar noise (um)."""
    d = json.loads(Path(truth_path).read_text(encoding="utf-8"))
    entry = d["campaign"][f"ballbar.{name}"]
    fields = {k: v for k, v in entry.items() if k not in ("start_s", "end_s")}
    for k in ("center_mm", "setup_offset_um"):
        if k in fields:
            fields[k] = tuple(fields[k])
    test = CircleTest(name=name, **fields)
    return test, float(entry["end_s"]), float(d.get("gap_s", 0.0)), float(d["noise"]["ballbar_um"])
