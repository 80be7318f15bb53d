"""Positioning readings at 20 deg C (ISO 230-2 states its results at 20 deg C).

A laser measures the displacement of the carriage in length units; a machine (and
the work it makes) at a material temperature T != 20 deg C is longer by the nominal
differential expansion alpha (T - 20) per unit length. The reading normalised to
20 deg C is the raw one scaled by (1 - alpha (T - 20)), about the laser's datum x0
(the first target measured), so the deviation changes by

    correction = alpha (T - 20) (x - x0) * 1e-3   [um; alpha ppm/K, T deg C, x mm]

and deviation_20 = deviation - correction. Which files carry what, and when the
instrument did it already: docs/formats.md, "20 deg C".
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

#: ISO 1 reference temperature, deg C.
REFERENCE_C = 20.0
APPLIED = "applied by abbe"
BY_INSTRUMENT = "already applied by the instrument"
NOT_APPLIED = "not applied"


@dataclass
class Normalisation:
    """What was done about 20 deg C for one positioning file.

    status: :data:`APPLIED`, :data:`BY_INSTRUMENT` or :data:`NOT_APPLIED`; reason:
    why, in words. material_temp_c: mean material temperature (deg C);
    expansion_ppm_per_k: the file's coefficient; span_mm: the measured span;
    nominal_differential_expansion_um: alpha (T - 20) x span (um), None when a
    quantity is missing.
    """

    status: str
    reason: str
    material_temp_c: float | None = None
    expansion_ppm_per_k: float | None = None
    span_mm: float = 0.0
    nominal_differential_expansion_um: float | None = None

    def to_json(self) -> dict[str, Any]:
        return {"status": self.status, "reason": self.reason,
                "reference_c": REFERENCE_C, "material_temp_c": self.material_temp_c,
                "expansion_ppm_per_k": self.expansion_ppm_per_k, "span_mm": self.span_mm,
                "nominal_differential_expansion_um": self.nominal_differential_expansion_um}

    def text(self) -> str:
        nde = self.nominal_differential_expansion_um
        head = (f"20 deg C: {self.status}" + (f"; nominal differential expansion "
                f"{nde:+.3f} um over {self.span_mm:g} mm" if nde is not None else ""))
        return f"{head} ({self.reason})"


def nominal_expansion_um(alpha_ppm_per_k: float, temp_c: float, span_mm: float) -> float:
    """alpha (T - 20) x span, um."""
    return float(alpha_ppm_per_k * (temp_c - REFERENCE_C) * span_mm * 1e-3)


def correction_um(pos_mm: np.ndarray, x0_mm: float, temp_c: np.ndarray | float,
                  alpha_ppm_per_k: float) -> np.ndarray:
    """The change of each deviation when normalised to 20 deg C (um, subtract it)."""
    return alpha_ppm_per_k * (np.asarray(temp_c) - REFERENCE_C) * (pos_mm - x0_mm) * 1e-3
