"""ISO 230-2 evaluation of bidirectional positioning data (notes.md §3).

Per target i and direction (up = ``+`` approach, down = ``-``) over n runs: mean
deviation x_i, standard deviation s_i (n - 1 in the denominator). Then

* reversal B_i = x_i(up) - x_i(down); B = max |B_i|
* repeatability R_i = max(2 s_up + 2 s_down + |B_i|, 4 s_up, 4 s_down); R = max R_i
* systematic deviation E = max(x_up, x_down) - min(x_up, x_down) over all targets
* mean bidirectional deviation M = range of (x_up + x_down) / 2
* accuracy A = max(x + 2 s) - min(x - 2 s) over both directions

Unidirectional E, R, A per direction are reported as well. All values in um.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from abbe.errors import AbbeInputError
from abbe.formats.deviations import PositioningData


@dataclass
class Iso230Result:
    """ISO 230-2 bidirectional results, um (per-target arrays have shape (T,))."""

    targets_mm: np.ndarray
    n_runs: int
    mean_up_um: np.ndarray
    mean_down_um: np.ndarray
    s_up_um: np.ndarray
    s_down_um: np.ndarray
    reversal_um: np.ndarray
    repeatability_um: np.ndarray
    B_um: float
    R_um: float
    E_um: float
    A_um: float
    M_um: float
    unidirectional: dict[str, dict[str, float]]
    #: what was done about 20 deg C (abbe.formats.thermal20.Normalisation) or None
    normalisation: Any = None

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dict: B_um, R_um, E_um, A_um, M_um at top level + per-target detail."""
        return {
            "standard": "ISO 230-2 (bidirectional)",
            "n_runs": self.n_runs,
            "n_targets": int(self.targets_mm.size),
            "B_um": self.B_um, "R_um": self.R_um, "E_um": self.E_um,
            "A_um": self.A_um, "M_um": self.M_um,
            "unidirectional": self.unidirectional,
            "normalisation_20c": (self.normalisation.to_json() if self.normalisation is not None
                                  else None),
            "targets": [
                {"target_mm": float(self.targets_mm[i]),
                 "mean_up_um": float(self.mean_up_um[i]),
                 "mean_down_um": float(self.mean_down_um[i]),
                 "s_up_um": float(self.s_up_um[i]),
                 "s_down_um": float(self.s_down_um[i]),
                 "reversal_um": float(self.reversal_um[i]),
                 "repeatability_um": float(self.repeatability_um[i]),
                 "mean_bidirectional_um": float(0.5 * (self.mean_up_um[i] + self.mean_down_um[i]))}
                for i in range(self.targets_mm.size)],
        }

    def format_text(self) -> str:
        """Human-readable table, um."""
        out = [f"ISO 230-2 bidirectional, {self.n_runs} runs, {self.targets_mm.size} targets (um)",
               f"{'target_mm':>11} {'x_up':>9} {'x_down':>9} {'s_up':>7} {'s_down':>7} "
               f"{'B_i':>8} {'R_i':>8}"]
        for i in range(self.targets_mm.size):
            out.append(f"{self.targets_mm[i]:11.3f} {self.mean_up_um[i]:9.3f} "
                       f"{self.mean_down_um[i]:9.3f} {self.s_up_um[i]:7.3f} "
                       f"{self.s_down_um[i]:7.3f} {self.reversal_um[i]:8.3f} "
                       f"{self.repeatability_um[i]:8.3f}")
        out.append("")
        out.append(f"B (reversal)            {self.B_um:9.1f} um")
        out.append(f"R (repeatability)       {self.R_um:9.1f} um")
        out.append(f"E (systematic dev.)     {self.E_um:9.1f} um")
        out.append(f"A (accuracy)            {self.A_um:9.1f} um")
        out.append(f"M (mean bidir. dev.)    {self.M_um:9.1f} um")
        for d, v in self.unidirectional.items():
            out.append(f"{d:<4} E {v['E_um']:.1f}  R {v['R_um']:.1f}  A {v['A_um']:.1f} um")
        out.append(self.normalisation.text() if self.normalisation is not None else
                   "20 deg C: the file carries no material temperature (results as measured)")
        return "\n".join(out)


def evaluate(data: PositioningData) -> Iso230Result:
    """ISO 230-2 bidirectional evaluation (see module docstring). um."""
    up = np.asarray(data.up_um, dtype=np.float64)
    dn = np.asarray(data.down_um, dtype=np.float64)
    if up.ndim != 2 or up.shape != dn.shape or up.shape[1] != np.size(data.targets_mm):
        raise AbbeInputError(f"up/down arrays must both be (n_runs, n_targets), got {up.shape} "
                             f"and {dn.shape}", file=data.source)
    n = up.shape[0]
    if n < 2:
        raise AbbeInputError(f"ISO 230-2 needs at least 2 runs (5 by the standard), got {n}",
                             file=data.source, field="run")
    xu, xd = up.mean(axis=0), dn.mean(axis=0)
    su, sd = up.std(axis=0, ddof=1), dn.std(axis=0, ddof=1)
    bi = xu - xd
    ri = np.maximum.reduce([2 * su + 2 * sd + np.abs(bi), 4 * su, 4 * sd])
    both = np.concatenate([xu, xd])
    mid = 0.5 * (xu + xd)
    A = max(np.max(xu + 2 * su), np.max(xd + 2 * sd)) - min(np.min(xu - 2 * su),
                                                          np.min(xd - 2 * sd))
    uni = {}
    for name, x, s in (("up", xu, su), ("down", xd, sd)):
        uni[name] = {"E_um": float(x.max() - x.min()), "R_um": float(np.max(4 * s)),
                     "A_um": float(np.max(x + 2 * s) - np.min(x - 2 * s))}
    return Iso230Result(
        targets_mm=np.asarray(data.targets_mm, dtype=np.float64), n_runs=n,
        mean_up_um=xu, mean_down_um=xd, s_up_um=su, s_down_um=sd, reversal_um=bi,
        repeatability_um=ri, B_um=float(np.max(np.abs(bi))), R_um=float(np.max(ri)),
        E_um=float(both.max() - both.min()), A_um=float(A), M_um=float(mid.max() - mid.min()),
        unidirectional=uni, normalisation=data.normalisation)
