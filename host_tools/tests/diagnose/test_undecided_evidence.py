"""Issue 36, sixth round: "undecided" from the evidence, and a drift judged beside its scale.

* an alternative explanation is undecided when the part of the named signature it cannot
  reproduce is within the estimated noise (log likelihood ratio below log 19), not when
  its R^2 passes a fixed share (the old 0.98): describe._undecided;
* "A alone, or A + B": a candidate the named effect mostly reproduces, preferred by the
  held-out data, whose evidence ratio the prior decides (strong against for any
  plausible size, not for a typical one): tested._companions;
* a drift's held-out gain is computed with its axis' scale free, like its evidence ratio
  (the team suite's rise-and-fall drift beside a scale was named nothing).

The two suite cases are from the team's independent generator, seed 1315942918 (the fifth
round's report seed), where the fifth round's code missed them.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from abbe.diagnose.evidence import log_evidence
from abbe.diagnose.results import DiagnoseOptions, EffectResult

OPTS = DiagnoseOptions()
SEED = 1315942918


def _norm_logpdf(x: float, var: float) -> float:
    return -0.5 * math.log(2 * math.pi * var) - 0.5 * x * x / var


def test_typical_prior_evidence_is_the_gaussian_marginal_ratio() -> None:
    """log K under a Gaussian prior of the typical size: log N(t; 0, T^2 + c) - log N(t; 0, c)
    (exact for a linear Gaussian model), beside the uniform plausible-range value."""
    theta, c, typ, L = 2.0, 0.25, 3.0, 500.0
    ev = log_evidence(np.array([theta]), np.array([[c]]), theta ** 2 / c, 0.3,
                      np.array([L]), typical=np.array([typ]))
    want_t = _norm_logpdf(theta, typ ** 2 + c) - _norm_logpdf(theta, c)
    want_u = -_norm_logpdf(theta, c) - math.log(2 * L)
    assert ev["log_evidence_typical"] == pytest.approx(want_t, rel=1e-9)
    assert ev["log_evidence"] == pytest.approx(want_u, rel=1e-9)
    # the wide plausible range penalises the same data more than a typical-size prior
    assert ev["log_evidence"] < ev["log_evidence_typical"]


def _effect(key: str, value: float, unit: str) -> EffectResult:
    return EffectResult(id=key, key=key, value=value, unit=unit, ci95=(value - 1, value + 1),
                        params=[], compensable=True, where="table", physics="", remedy="",
                        evidence={}, axis=key[-1].upper())


class _Eng:
    opts = OPTS
    drift_unit = "h"


def _tested(**kw: float) -> dict:
    base = {"selected": False, "log_evidence": -8.7, "log_evidence_typical": 1.0,
            "heldout_gain": 41.3, "heldout_need": 6.0, "redundancy": 0.75,
            "redundant_with": "scale_z", "value": 0.2, "unit": "um", "heldout_in_time": True}
    base.update(kw)
    return base


def test_a_companion_the_prior_decides_is_undecided() -> None:
    from abbe.diagnose.effects import catalogue
    from abbe.diagnose.selection import _companions
    specs = {s.key: s for s in catalogue()}
    e = _effect("scale_z", 35.98, "ppm")
    _companions(_Eng(), [e], {"thermal_drift_z": _tested()}, specs)   # type: ignore[arg-type]
    d = e.to_json()
    assert d["state"] == "undecided"
    assert d["undecided_between"] == ["scale_z", "thermal_drift_z"]
    assert "reverse time order" in e.undecided["statement"]          # the separating test
    assert e.undecided["table_holds"] == {"scale_z": 35.98}          # the table: A alone
    # decided cases stay decided: strong against even for a typical size, held-out data
    # not preferring it, or a named effect reproducing less than half of it
    for kw in ({"log_evidence_typical": -4.0}, {"heldout_gain": 3.0}, {"redundancy": 0.3},
               {"log_evidence": 3.5}):
        e2 = _effect("scale_z", 35.98, "ppm")
        _companions(_Eng(), [e2], {"thermal_drift_z": _tested(**kw)}, specs)  # type: ignore[arg-type]
        assert e2.undecided is None, kw
    # a declared quantity is never "maybe changed"
    e3 = _effect("squareness_xy", 20.0, "urad")
    _companions(_Eng(), [e3], {"tool_offset": _tested(redundant_with="squareness_xy")}, specs)  # type: ignore[arg-type]
    assert e3.undecided is None


def _case(name: str, tmp_path: Path):
    from cases.independent.suite import build, run, score, suite
    c = next(x for x in suite(SEED) if x.name == name)
    b = build(c, tmp_path / "case")
    res = run(b)
    return res, score(b, res)


def test_drift_the_scale_takes_is_reported_undecided(tmp_path: Path) -> None:
    """x_thermal_time+scale_z: the Z line's per-run zeros take the drift between the runs, the
    scale its constant part; the drift's change in time is near the noise (log K -8.7 with
    the plausible range, +1.0 with a typical size). Fifth round: scale_z named alone, no
    undecided state. Now: "scale_z alone, or scale_z + thermal_drift_z", the table holding
    the scale alone."""
    res, sc = _case("x_thermal_time+scale_z", tmp_path)
    assert sc["named"] == ["scale_z"], sc
    e = res.effects[0]
    assert e.undecided is not None and e.undecided.get("companion")
    assert [a["key"] for a in e.undecided["alternatives"]] == ["scale_z", "thermal_drift_z"]
    assert res.to_json()["state"] == "undecided"


def test_rise_and_fall_drift_beside_its_scale_is_named(tmp_path: Path) -> None:
    """x_thermal_rise_fall+scale_x: each alone fails the held-out arbiter (the scale alone
    fitted on the early runs misses the late ones); the drift judged with the scale free on
    held-out data too. Fifth round: run 1 excluded as inconsistent, nothing named."""
    res, sc = _case("x_thermal_rise_fall+scale_x", tmp_path)
    assert not sc["misses"] and not sc["extra"], (sc["named"], res.notes)
    assert not res.outliers
    for k, v in sc["values"].items():
        assert v["ok"], (k, v)


def test_the_cyclic_effect_writes_its_second_harmonic_into_the_table() -> None:
    """A cyclic change with a second harmonic goes into one Fourier block with 2 harmonics
    (rows sin1, cos1, sin2, cos2), zero at the reference point; without it, 1 harmonic."""
    from abbe.diagnose.effects import PredParams, by_key
    from abbe.model.table import AxisTable, Table, basis_matrix
    ax = AxisTable(travel_mm=(0.0, 200.0), trend_degree=1,
                   coef={"dx": np.array([0.0, 0.0])})
    t = Table(axes={"X": ax}, reference_mm=(50.0, 0.0, 0.0))
    spec = by_key()["cyclic_x"]
    pp = PredParams()
    t2, _ = spec.apply(t, pp, np.array([1.0, 0.5, 0.2, -0.1]), scan_value=8.0)
    ax2 = t2.axes["X"]
    blk = [b for b in ax2.blocks if b is not None]
    assert len(blk) == 1 and blk[0].harmonics == 2 and blk[0].period_mm == 8.0
    p = np.array([50.0, 51.3, 77.7, 120.0])
    got = basis_matrix(ax2, p) @ ax2.coef["dx"]
    phi = 2 * np.pi * p / 8.0
    f = np.sin(phi) + 0.5 * np.cos(phi) + 0.2 * np.sin(2 * phi) - 0.1 * np.cos(2 * phi)
    assert np.allclose(got, f - f[0], atol=1e-9)
    t1, _ = spec.apply(t, pp, np.array([1.0, 0.5, 0.0, 0.0]), scan_value=8.0)
    assert [b.harmonics for b in t1.axes["X"].blocks if b is not None] == [1]


def test_a_screw_with_a_second_harmonic_is_one_cyclic_effect(tmp_path: Path) -> None:
    """cyclic_x of the team's generator: its screw error has a 20 % second harmonic (period
    lead / 2). The catalogue's cyclic effect keeps it (chosen by the evidence ratio), so no
    scale or bow takes the harmonic's residual (the fourth round named a spurious scale_x
    of -0.50 ppm on seed 1231424024)."""
    res, sc = _case("cyclic_x", tmp_path)
    assert not sc["misses"] and not sc["extra"], (sc["named"], res.notes)
    e = res.effects[0]
    p = {q["name"]: q["value"] for q in e.params}
    assert {"a2_sin", "a2_cos"} <= set(p)
    ratio = math.hypot(p["a2_sin"], p["a2_cos"]) / e.value
    assert 0.1 < ratio < 0.3, ratio
