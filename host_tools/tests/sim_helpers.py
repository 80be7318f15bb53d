"""Helpers for the simulator / ballbar tests: small virtual machines built in code."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from abbe.model.geometry import CircleTest
from abbe.model.table import AXES, TERMS
from abbe.sim.truth import Effects, MachineTruth, build_axis

TRAVEL = {"X": (0.0, 500.0), "Y": (-400.0, 0.0), "Z": (-300.0, 0.0)}
REF = (163.626, -212.772, -290.704)
REPO = Path(__file__).resolve().parents[2]
EXAMPLE = REPO / "examples" / "vmc500"


def make_truth(shapes: dict[str, dict[str, dict[str, Any]]] | None = None,
               wave_period_mm: dict[str, float] | None = None, **effects: Any) -> MachineTruth:
    """A paper-geometry machine with the given term shapes and effects (rest zero)."""
    shapes = shapes or {}
    eff = Effects(**effects)
    axes = {}
    for j, a in enumerate(AXES):
        axes[a] = build_axis(a, TRAVEL[a], REF[j], shapes.get(a, {}),
                             (wave_period_mm or {}).get(a), cyclic_um=eff.cyclic_um[j],
                             cyclic_period_mm=eff.cyclic_period_mm[j],
                             cyclic_phase_deg=eff.cyclic_phase_deg[j])
    return MachineTruth(name="t", seed=1, reference_mm=REF, tool_offset_mm=(0.0, 0.0, 0.0),
                        axes=axes, effects=eff)


def typical_shapes() -> dict[str, dict[str, dict[str, Any]]]:
    """Shapes of VMC-like magnitudes on all 18 terms."""
    return {
        "X": {"dx": {"slope_um_per_m": 20.0, "wave_um": [6.0, 2.0], "wave_phase_deg": [30.0, 90.0]},
              "dy": {"bow_um": 5.0}, "dz": {"bow_um": -4.0, "cantilever_um": 2.0},
              "ex": {"slope_urad_per_m": 10.0, "bow_urad": 4.0},
              "ey": {"slope_urad_per_m": 20.0, "bow_urad": 12.0},
              "ez": {"bow_urad": 10.0, "wave_urad": [4.0]}},
        "Y": {"dx": {"bow_um": 6.0}, "dy": {"wave_um": [8.0, 3.0], "slope_um_per_m": -8.0},
              "dz": {"cantilever_um": -3.0}, "ex": {"bow_urad": 10.0},
              "ey": {"bow_urad": -5.0}, "ez": {"slope_urad_per_m": 10.0, "bow_urad": 4.0}},
        "Z": {"dx": {"cantilever_um": 4.0, "cantilever_end": "min"}, "dy": {"bow_um": 2.5},
              "dz": {"slope_um_per_m": 10.0, "wave_um": [2.0]},
              "ex": {"cantilever_urad": 12.0, "cantilever_end": "min"},
              "ey": {"bow_urad": 8.0}, "ez": {"slope_urad_per_m": 5.0}},
    }


def paper_circle(**kw: Any) -> CircleTest:
    """The paper's 100 mm XY circle (settings overridable)."""
    d = dict(name="c1", plane="XY", center_mm=(343.507, -285.090, -286.430), radius_mm=100.0,
             feed_mm_min=200.0, sample_deg=1.0, feed_arc_deg=45.0)
    d.update(kw)
    return CircleTest(**d)


def random_positions(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    lo = np.array([TRAVEL[a][0] for a in AXES])
    hi = np.array([TRAVEL[a][1] for a in AXES])
    return lo + (hi - lo) * rng.random((n, 3))


__all__ = ["TRAVEL", "REF", "REPO", "EXAMPLE", "make_truth", "typical_shapes", "paper_circle",
           "random_positions", "TERMS"]
