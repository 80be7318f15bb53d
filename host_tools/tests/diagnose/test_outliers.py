"""Outlier runs and the robust noise scale of `abbe diagnose` (abbe.diagnose.outliers,
abbe.diagnose.problem.estimate_noise): a start-up outlier cycle is named with where it
is off, excluded, and the rest diagnosed; a run of inflated scatter is found after the
diagnosis; one bad run cannot inflate the noise estimate."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from abbe.diagnose.checks import LaserChannel, LaserCheck
from abbe.diagnose.outliers import gross_outliers, inconsistent_runs
from abbe.diagnose.problem import Problem, estimate_noise
from abbe.diagnose.run import diagnose_positioning
from fit_helpers import write_positioning_dat

TARGETS = np.array([-20.0, -15.0, -10.0, -5.0, 0.0, 5.0, 10.0, 15.0, 20.0])


def _runs(seed: int, n_runs: int = 5, noise: float = 1.0, reversal: float = -20.0):
    """(n_runs, 2, T) positioning deviations: a smooth error, a constant reversal, noise."""
    rng = np.random.default_rng(seed)
    g = 30.0 * np.sin(TARGETS / 9.0) + 0.05 * TARGETS ** 2
    v = np.empty((n_runs, 2, TARGETS.size))
    v[:, 0] = g + reversal / 2 + rng.normal(0, noise, (n_runs, TARGETS.size))
    v[:, 1] = g - reversal / 2 + rng.normal(0, noise, (n_runs, TARGETS.size))
    return v


def _check(v: np.ndarray) -> LaserCheck:
    n, _, T = v.shape
    order = np.zeros((n, 2, T), dtype=np.int64)
    for r in range(n):
        order[r, 0] = r * 2 * T + np.arange(T)
        order[r, 1] = r * 2 * T + T + np.arange(T)[::-1]
    return LaserCheck("positioning_X", "X", (0.0, 0.0, 0.0), TARGETS,
                      [LaserChannel("linear", "dx", 1, v)], order, (0.0, 0.0, 0.0))


def test_startup_outlier_cycle_is_named_with_where_it_is_off() -> None:
    v = _runs(1)
    v[0, 0, 7] += 85.0          # cycle 1, forward, at 15 mm
    v[0, 0, 2] -= 62.0          # cycle 1, forward, at -10 mm
    out = gross_outliers(_check(v))
    assert [(o.run, o.kind, o.excluded) for o in out] == [(1, "start-up outlier", True)]
    r = {(x["target_mm"], x["direction"]): x["deviation"] for x in out[0].readings}
    assert set(r) == {(15.0, "+"), (-10.0, "+")}
    assert r[(15.0, "+")] == pytest.approx(85.0, abs=4.0)
    msg = out[0].message()
    assert "start-up outlier, cycle 1" in msg and "at 15 mm (forward)" in msg and "excluded" in msg


def test_clean_runs_and_a_drift_are_not_outliers() -> None:
    v = _runs(2)
    assert gross_outliers(_check(v)) == []
    # a drift of 3 um per run (and 0.1 um/mm per run) moves whole passes, not readings
    drift = np.arange(5)[:, None, None] * (3.0 + 0.1 * TARGETS[None, None, :])
    assert gross_outliers(_check(v + drift)) == []


def test_outliers_in_too_many_runs_are_reported_not_excluded() -> None:
    v = _runs(3)
    for r in (0, 2, 4):
        v[r, 1, r] += 90.0
    out = gross_outliers(_check(v))
    assert len(out) == 3 and not any(o.excluded for o in out)
    assert "NOT excluded" in out[0].message()


def test_one_bad_run_does_not_inflate_the_noise_estimate() -> None:
    v = _runs(4, noise=1.0)
    v[0, 0, 3] += 85.0
    prob = Problem([_check(v)])
    resid = prob.y - np.tile(v.mean(axis=0), (5, 1, 1)).reshape(-1)
    sig, _, rep = estimate_noise(prob, resid)
    assert sig[0] < 1.5          # the plain scatter would be about 9 um
    assert rep["positioning_X:linear"].get("robust") is True
    clean = Problem([_check(_runs(4, noise=1.0))])
    sig_c, _, rep_c = estimate_noise(clean, clean.y - np.tile(_runs(4).mean(axis=0), (5, 1, 1)).reshape(-1))
    assert "robust" not in rep_c["positioning_X:linear"] and 0.7 < sig_c[0] < 1.3


def test_inconsistent_run_found_on_the_residual() -> None:
    rng = np.random.default_rng(5)
    v = rng.normal(0, 1.0, (5, 2, TARGETS.size))
    v[3] *= 4.0                  # run 4: scatter 4 x the others
    c = _check(v)
    out = inconsistent_runs(c, c.y)
    assert [(o.run, o.kind) for o in out] == [(4, "inconsistent run")]
    assert out[0].ratio > 4.0
    assert inconsistent_runs(c, rng.normal(0, 1.0, c.n)) == []


def test_positioning_diagnosis_excludes_the_outlier_and_names_the_reversal(tmp_path: Path) -> None:
    """The issue's real-data failure: one start-up cycle 60-110 um off at two targets made
    the diagnosis say 'nothing is missing' next to a 20 um reversal."""
    v = _runs(6, noise=1.5, reversal=-20.0)
    v[0, 0, 1] += 110.0
    v[0, 0, 6] += 60.0
    res = diagnose_positioning(write_positioning_dat(tmp_path / "x.dat", v, TARGETS), "X")
    assert [(o.run, o.excluded) for o in res.outliers] == [(1, True)]
    assert any(n.startswith("OUTLIER: positioning_X: start-up outlier, cycle 1") for n in res.notes)
    keys = {e.key: e for e in res.effects}
    assert "backlash_x" in keys and keys["backlash_x"].value == pytest.approx(-20.0, abs=2.0)
    assert res.noise["positioning_X:linear"]["sigma"] < 2.5
    assert res.checks[0].run_numbers == [2, 3, 4, 5]
    d = res.to_json()
    assert d["outliers"][0]["run"] == 1 and d["outliers"][0]["readings"][0]["target_mm"] == -15.0
    from abbe.diagnose.report import format_text
    txt = format_text(res, "m.bin")
    assert "outlier runs (excluded from the check; the rest is diagnosed):" in txt
    line = next(x for x in txt.splitlines() if "start-up outlier, cycle 1" in x)
    assert " um at -15 mm (forward)" in line and " um at 10 mm (forward)" in line
