"""ISO 230-3 evaluation of a thermal record: drift per channel, tilts, the envelope.

Per displacement channel (um, from its start): the drift over time, its range (max - min,
ISO 230-3's "thermal drift" of the spindle test) and the value at the end; per sensor pair
of one direction (a :class:`abbe.formats.thermal_machine.TiltPair`) the tilt (urad, from
the pair's difference over its spacing); the envelope: the largest drift range of any
channel and when each channel reached its extremes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from abbe.formats.thermal_machine import TiltPair
from abbe.formats.thermal_record import ThermalRecord


@dataclass(frozen=True)
class Drift:
    """One signal's drift in ``unit`` (um, urad, K): ``range`` (max - min), ``final`` (at
    the record's end), the extremes and their hours, all from the signal's start."""

    name: str
    unit: str
    range: float
    final: float
    max: float
    max_h: float
    min: float
    min_h: float


def tilt_signal(rec: ThermalRecord, pair: TiltPair) -> np.ndarray:
    """The pair's tilt over the record, urad, from its start: b = (x_up - x_low) / L,
    a = -(y_up - y_low) / L (a rotation about +X moves a point at +z to -y)."""
    i = rec.channel_names.index(pair.lower)
    j = rec.channel_names.index(pair.upper)
    d = (rec.disp_um[:, j] - rec.disp_um[0, j]) - (rec.disp_um[:, i] - rec.disp_um[0, i])
    sign = 1.0 if pair.output == "b" else -1.0
    return sign * d / pair.spacing_mm * 1e3


def drift_of(name: str, unit: str, hours: np.ndarray, v: np.ndarray) -> Drift:
    imax, imin = int(np.argmax(v)), int(np.argmin(v))
    return Drift(name, unit, float(v[imax] - v[imin]), float(v[-1]), float(v[imax]),
                 float(hours[imax]), float(v[imin]), float(hours[imin]))


def evaluate_record(rec: ThermalRecord, pairs: list[TiltPair]) -> dict:
    """The ISO 230-3 figures of a record (plain data, JSON-ready)."""
    h = rec.hours
    drifts = [drift_of(n, "um", h, rec.disp_um[:, k] - rec.disp_um[0, k])
              for k, n in enumerate(rec.channel_names)]
    tilts = [drift_of(f"tilt {p.output} ({p.upper}-{p.lower})", "urad", h, tilt_signal(rec, p))
             for p in pairs]
    temps = [drift_of(n, "K", h, rec.temps_c[:, k] - rec.temps_c[0, k])
             for k, n in enumerate(rec.temp_names)]
    env = max(drifts, key=lambda d: d.range)
    return {"duration_h": float(h[-1] - h[0]), "samples": int(h.size),
            "channels": [d.__dict__ for d in drifts], "tilts": [d.__dict__ for d in tilts],
            "temperatures": [d.__dict__ for d in temps],
            "envelope": {"channel": env.name, "range_um": env.range}}
