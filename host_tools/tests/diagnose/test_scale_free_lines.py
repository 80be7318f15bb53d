"""A laser line's scale-like instrument inputs (instrument scale, air, temperature not
normalised, cosine) are ramps along its axis: had the readings carried one, the diagnosis
would have named (or held free) the axis' scale rather than moved another effect. So a named
effect other than a scale of that axis takes these lines with the axis' scale free in the
fit (abbe.diagnose.scale_free); a scale named on the axis keeps them (a scale measured at an
unknown temperature is uncertain by alpha dT).

The team suite's ``cyclic_y+straightness_yx`` (seed 665122612; laser files without
temperatures, the default 2 K "temperature not normalised"): before, the cyclic amplitude
1.475 um had U 1.04 um, its line from laser_Y's temperature 0.52 um (the fit's 0.009), the
interval [0.435, 2.515]; with Y's scale free the line is 0.089 um (the ballbar's XY circle
holds most of a scale_y, so 17 % of the ramp stays for the effects)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from cases.independent import suite as ind

TEMP = "temperature not normalised"
SEED = 665122612


def _run(name: str, tmp: Path):
    case = next(c for c in ind.suite(SEED) if c.name == name)
    b = ind.build(case, str(tmp))
    return {e.key: e for e in ind.run(b).effects}


def _line(e, check: str) -> float:
    return e.uncertainty["budget_u"][f"{check}: {TEMP}"]


def test_a_cyclic_amplitude_is_not_made_of_the_temperature_line(tmp_path: Path) -> None:
    eff = _run("cyclic_y+straightness_yx", tmp_path)
    assert set(eff) == {"cyclic_y", "straightness_yx"}
    cyc = eff["cyclic_y"]
    u = cyc.uncertainty
    # the input is in the budget, but through the scale it would have named: < 0.15 um
    # (0.52 with the selection held fixed)
    assert 0.0 < _line(cyc, "laser_Y") < 0.15, u["budget_u"]
    assert u["U"] < 0.4, u                        # um; 1.04 before
    assert cyc.ci95[1] - cyc.ci95[0] < 0.8, cyc.ci95   # [0.435, 2.515] before
    assert cyc.ci95[0] < cyc.value < cyc.ci95[1]


def test_a_named_scale_keeps_the_temperature_line(tmp_path: Path) -> None:
    """alpha x 2 K of the laser class default (11.7 ppm/K, rectangular: 13.5 ppm standard)
    along the scale's own line: the scale is the effect the ramp would be."""
    eff = _run("scale_y", tmp_path)
    assert "scale_y" in eff, list(eff)
    line = _line(eff["scale_y"], "laser_Y")
    assert line > 0.5 * 2 * 11.7 / math.sqrt(3), eff["scale_y"].uncertainty["budget_u"]
    assert eff["scale_y"].uncertainty["U"] > 2 * line
