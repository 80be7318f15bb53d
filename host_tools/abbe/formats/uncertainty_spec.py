"""The uncertainty budget and the tolerances a machine file may declare
(``[uncertainty.laser]``, ``[uncertainty.ballbar]``, ``[tolerances.A]``,
``[tolerances.ballbar]``; docs/uncertainty.md, docs/formats.md).

Every budget figure is a half-width ``a`` of a rectangular distribution (standard
uncertainty a / sqrt(3)) except ``calibration_U_um``, a calibration certificate's
expanded uncertainty (k = 2). A budget starts from the defaults of its instrument
class (:data:`CLASSES`); keys in the machine file replace single defaults.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

from abbe.errors import AbbeInputError, check_number
from abbe.errors.numbers import show_value
from abbe.formats.structured import unknown_key

#: Instrument classes and their default budgets (docs/uncertainty.md names the sources).
#: Units: ppm, um, deg C, ppm/K, hPa, %RH, mrad, mm.
CLASSES: dict[str, dict[str, float]] = {
    # a stabilised HeNe interferometer with an air / material compensation unit
    # (figures of the Renishaw XL-80 + XC-80 datasheet)
    "laser_interferometer": {
        "accuracy_ppm": 0.05, "linearity_um": 0.0, "resolution_um": 0.001,
        "material_temp_u_c": 0.1, "expansion_ppm_per_k": 11.7, "expansion_u_ppm_per_k": 1.0,
        "temp_deviation_c": 2.0, "air_temp_u_c": 0.2, "air_pressure_u_hpa": 1.0,
        "air_humidity_u_pct": 6.0, "misalignment_mrad": 0.1, "dead_path_mm": 100.0},
    # a laser triangulation displacement sensor (Micro-Epsilon ILD2300-50: linearity
    # +-0.03 % of its 50 mm range = +-15 um, resolution 0.75 um at 20 kHz)
    "laser_triangulation": {
        "accuracy_ppm": 0.0, "linearity_um": 15.0, "resolution_um": 0.75,
        "material_temp_u_c": 0.5, "expansion_ppm_per_k": 11.7, "expansion_u_ppm_per_k": 1.0,
        "temp_deviation_c": 2.0, "air_temp_u_c": 0.0, "air_pressure_u_hpa": 0.0,
        "air_humidity_u_pct": 0.0, "misalignment_mrad": 1.0, "dead_path_mm": 0.0},
    # a telescopic ballbar with its calibrator (Renishaw QC20-W datasheet figures)
    "ballbar": {
        "scale_pct": 0.1, "resolution_um": 0.1, "calibration_U_um": 1.0,
        "expansion_ppm_per_k": 11.5, "expansion_u_ppm_per_k": 1.0, "bar_temp_u_c": 0.5,
        "drift_c": 0.1},
}
LASER_CLASSES = ("laser_interferometer", "laser_triangulation")
#: Upper bounds of every budget figure (a figure beyond them is a typo, not a budget).
_RANGES: dict[str, tuple[float, float, str]] = {
    "accuracy_ppm": (0.0, 1000.0, "ppm"), "linearity_um": (0.0, 1000.0, "um"),
    "resolution_um": (0.0, 100.0, "um"), "material_temp_u_c": (0.0, 20.0, "deg C"),
    "expansion_ppm_per_k": (-100.0, 100.0, "ppm/K"), "expansion_u_ppm_per_k": (0.0, 50.0, "ppm/K"),
    "temp_deviation_c": (0.0, 50.0, "deg C"), "air_temp_u_c": (0.0, 20.0, "deg C"),
    "air_pressure_u_hpa": (0.0, 100.0, "hPa"), "air_humidity_u_pct": (0.0, 100.0, "%RH"),
    "misalignment_mrad": (0.0, 50.0, "mrad"), "dead_path_mm": (0.0, 10000.0, "mm"),
    "scale_pct": (0.0, 10.0, "%"), "calibration_U_um": (0.0, 100.0, "um"),
    "bar_temp_u_c": (0.0, 20.0, "deg C"), "drift_c": (0.0, 20.0, "deg C")}
#: Quantities a tolerance may be stated for.
ISO230_2_LIMITS = ("E_um", "A_um", "B_um", "R_um", "M_um")
BALLBAR_LIMITS = ("G_um", "H_um")


@dataclass
class Budget:
    """One instrument's budget: its class and every figure (declared or default)."""

    instrument: str
    figures: dict[str, float]
    declared: tuple[str, ...] = ()   # the keys the machine file stated (the rest: class defaults)
    source: str = "class defaults"

    def __getitem__(self, key: str) -> float:
        return self.figures[key]

    def to_json(self) -> dict[str, Any]:
        return {"instrument": self.instrument, "source": self.source,
                "declared": list(self.declared), "figures": dict(self.figures)}


def default_budget(instrument: str) -> Budget:
    """The class defaults of ``instrument`` (one of :data:`CLASSES`)."""
    if instrument not in CLASSES:
        raise AbbeInputError(unknown_key(instrument, CLASSES, "instrument class"),
                             field="--instrument")
    return Budget(instrument, dict(CLASSES[instrument]))


@dataclass
class UncertaintySpec:
    """The validated ``[uncertainty.*]`` and ``[tolerances.*]`` sections of a machine file."""

    laser: Budget | None = None
    ballbar: Budget | None = None
    #: axis (X, Y, Z, or a rotary name) or "ballbar" -> quantity -> limit, um
    tolerances: dict[str, dict[str, float]] = field(default_factory=dict)


Err = Callable[[str, str], AbbeInputError]


def _budget(sec: Any, f: str, allowed: tuple[str, ...], default_class: str, err: Err,
            line_of: Callable[[str], int | None], path: str) -> Budget:
    if not isinstance(sec, dict):
        raise err(f, f"expected a table [{f}], got {show_value(sec)}")
    inst = sec.get("instrument", default_class)
    if not isinstance(inst, str) or inst not in allowed:
        raise err(f"{f}.instrument", f"expected one of {', '.join(allowed)}, got "
                                     f"{show_value(inst)}")
    figures = dict(CLASSES[inst])
    declared = []
    for key, v in sec.items():
        if key == "instrument":
            continue
        if key not in figures:
            raise err(f"{f}.{key}", unknown_key(key, ("instrument", *figures)))
        lo, hi, unit = _RANGES[key]
        figures[key] = check_number(v, file=path, line=line_of(f"{f}.{key}"), field=f"{f}.{key}",
                                    lo=lo, hi=hi, unit=unit)
        declared.append(key)
    return Budget(inst, figures, tuple(declared),
                  "machine file" + ("" if declared else " (class defaults)"))


def parse_uncertainty(data: dict[str, Any], err: Err, line_of: Callable[[str], int | None],
                      path: str, axis_names: tuple[str, ...]) -> UncertaintySpec:
    """The ``[uncertainty]`` and ``[tolerances]`` sections of a parsed machine file."""
    spec = UncertaintySpec()
    unc = data.get("uncertainty")
    if unc is not None:
        if not isinstance(unc, dict):
            raise err("uncertainty", f"expected a table [uncertainty], got {show_value(unc)}")
        for key in unc:
            if key not in ("laser", "ballbar"):
                raise err(f"uncertainty.{key}", unknown_key(key, ("laser", "ballbar")))
        if "laser" in unc:
            spec.laser = _budget(unc["laser"], "uncertainty.laser", LASER_CLASSES,
                                 "laser_interferometer", err, line_of, path)
        if "ballbar" in unc:
            spec.ballbar = _budget(unc["ballbar"], "uncertainty.ballbar", ("ballbar",), "ballbar",
                                   err, line_of, path)
    tol = data.get("tolerances")
    if tol is not None:
        if not isinstance(tol, dict):
            raise err("tolerances", f"expected a table [tolerances], got {show_value(tol)}")
        for name, sec in tol.items():
            f = f"tolerances.{name}"
            if name != "ballbar" and name not in axis_names:
                raise err(f, unknown_key(name, (*axis_names, "ballbar"), "tolerance section"))
            keys = BALLBAR_LIMITS if name == "ballbar" else ISO230_2_LIMITS
            if not isinstance(sec, dict):
                raise err(f, f"expected a table [{f}], got {show_value(sec)}")
            limits: dict[str, float] = {}
            for key, v in sec.items():
                if key not in keys:
                    raise err(f"{f}.{key}", unknown_key(key, keys))
                limits[key] = check_number(v, file=path, line=line_of(f"{f}.{key}"),
                                           field=f"{f}.{key}", lo=0.0, hi=1e6, unit="um",
                                           lo_open=True)
            spec.tolerances[name] = limits
    return spec
