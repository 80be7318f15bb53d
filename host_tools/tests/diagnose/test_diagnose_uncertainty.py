"""U (k = 2) of abbe diagnose's named effects and gaps, checked by the Monte Carlo (GUM S1).

Repeated positioning runs written here, and the real ESS record (the ISO 230-2 file,
position-only model; the demo's ballbar diagnosis: tests/cli/test_demo.py): every named effect's U and
the gap figures' U agree with a Monte Carlo that re-runs the nonlinear final fit on new
readings within 10 %; a U halved on purpose is caught (the Monte Carlo's U is stated); the
competing-max rule of a gap's max |r| is checked against a direct simulation of its own.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from abbe.diagnose import uncertainty as dunc
from abbe.diagnose.run import diagnose_positioning

from real_data import ESS_DAT, needs_real_data

def _write_runs(path: Path, seed: int = 3) -> Path:
    """Five bidirectional ISO 230-2 runs (laser CSV, 11 targets over 400 mm) of an axis
    with a 4 um backlash, a drift of 0.8 um per run and 0.4 um noise: written here, not
    by abbe.sim."""
    rng = np.random.default_rng(seed)
    rows = ["run,direction,target_mm,linear_um"]
    targets = np.linspace(0.0, 400.0, 11)
    base = 6.0 * np.sin(targets / 90.0) + 0.01 * targets
    for run in range(1, 6):
        for d, sign, order in (("+", 1.0, targets), ("-", -1.0, targets[::-1])):
            for t in order:
                v = base[int(round(t / 40.0))] + sign * 2.0 + 0.8 * run + rng.normal(0, 0.4)
                rows.append(f"{run},{d},{t:.3f},{v:.4f}")
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory):
    f = _write_runs(tmp_path_factory.mktemp("runs") / "x.csv")
    return f, diagnose_positioning(f, "X")


def test_effects_and_gaps_U_agree_with_monte_carlo(runs) -> None:
    f, res = runs
    keys = {e.key for e in res.effects}
    assert "backlash_x" in keys, keys
    unc = dunc.diagnosis_uncertainty(res, dunc.budget_of_positioning_file(f), None, draws=400,
                                     model_from_the_data=True)
    figs = unc["monte_carlo"]["figures"]
    assert set(figs) == keys | {"before.rms_um", "before.max_um", "after.rms_um", "after.max_um"}
    for name, fig in figs.items():
        assert fig["U"] > 0 and abs(fig["agreement"]) <= 0.10, (name, fig)
    for e in res.effects:
        u = e.uncertainty
        assert u["U"] == pytest.approx(2 * u["u"], rel=1e-4) and u["U_from"] == "first order"
        # the budget's lines make u (quadrature): the fit's Type A and the instrument's
        assert math.sqrt(sum(v ** 2 for v in u["budget_u"].values())) == pytest.approx(u["u"], rel=1e-3)
        assert any(k.startswith("fit") for k in u["budget_u"])
        assert any("resolution" in k for k in u["budget_u"])
        # U (k = 2) and the t-based 95 % interval tell the same story
        assert u["U"] == pytest.approx((e.ci95[1] - e.ci95[0]) / 2.0, rel=0.2)
    backlash = next(e for e in res.effects if e.key == "backlash_x")
    # the written 4 um, within what a drift per run leaves confounded with it
    assert backlash.value == pytest.approx(4.0, abs=0.6)
    j = res.to_json()
    assert j["gap"]["after"]["rms_U_um"] > 0 and j["gap"]["before"]["max_U_um"] > 0
    assert all("U" in e and "budget_u" in e for e in j["effects"])
    assert j["uncertainty"]["monte_carlo"]["draws"] == 400


def test_a_halved_U_is_caught(runs, monkeypatch: pytest.MonkeyPatch) -> None:
    """Halve every effect's propagation (the headline's gradient): the Monte Carlo, which
    does not use it, parts by about +100 % and its U is the one stated."""
    f, res = runs
    real = dunc._grad
    monkeypatch.setattr(dunc, "_grad", lambda fn, v, C: 0.5 * real(fn, v, C))
    dunc.diagnosis_uncertainty(res, dunc.budget_of_positioning_file(f), None, draws=200,
                               model_from_the_data=True)
    assert res.effects
    for e in res.effects:
        u = e.uncertainty
        assert u["mc_agreement"] > 0.5, (e.key, u)
        # the draws hold the selection fixed: a drift's time-constant line (not simulated)
        # is added to their U in quadrature
        u_tau = u["budget_u"].get("drift time constant (the grid's alternatives, BIC weights)", 0.0)
        assert u["U_from"] == "Monte Carlo" and u["U"] == pytest.approx(
            math.hypot(u["U_mc"], 2.0 * u_tau), rel=1e-4)


@needs_real_data(ESS_DAT)
def test_ess_record_U_agrees_with_monte_carlo() -> None:
    res = diagnose_positioning(ESS_DAT, "X", mc_draws=500)
    assert {e.key for e in res.effects} == {"backlash_x", "reversal_x", "thermal_drift_x"}
    for name, f in res.uncertainty["monte_carlo"]["figures"].items():
        assert abs(f["agreement"]) <= 0.10, (name, f)
    # the triangulation sensor's class defaults, and its linearity left out: the
    # position-only model is built from the same readings
    assert "laser_triangulation" in res.uncertainty["budgets"]["positioning_X"]["instrument"]
    assert any("position-only" in a for a in res.uncertainty["assumptions"])
    backlash = next(e for e in res.effects if e.key == "backlash_x")
    assert 0.5 < backlash.uncertainty["U"] < 2.0  # um: 0.91 measured


def test_competing_max_with_shared_rectangular_errors() -> None:
    """_max_abs_variance against a direct simulation: 12 targets of 10 samples, each target
    with one rectangular error (+-3), normal noise 0.5 per sample, a curve of its own."""
    rng = np.random.default_rng(5)
    T, n = 12, 10
    r = np.repeat(np.sin(np.arange(T)) * 4.0, n) + rng.normal(0, 0.3, T * n)
    um = np.ones(T * n, dtype=bool)
    labels = np.repeat(np.arange(T), n)
    blocks = [np.flatnonzero(labels == t) for t in range(T)]
    rand = {"noise": (np.full(T * n, 0.25), []),
            "linearity": (np.full(T * n, 9.0 / 3.0), blocks)}
    var = dunc._max_abs_variance(r, um, rand)
    draws = 20000
    e = rng.uniform(-3, 3, (draws, T))[:, labels] + rng.normal(0, 0.5, (draws, T * n))
    sim = np.max(np.abs(r[None, :] + e), axis=1)
    assert math.sqrt(var) == pytest.approx(float(np.std(sim)), rel=0.05)
    # the normal approximation of the same errors (no blocks) is off by more
    rand_n = {"all": (np.full(T * n, 0.25 + 3.0), [])}
    err_normal = abs(math.sqrt(dunc._max_abs_variance(r, um, rand_n)) / float(np.std(sim)) - 1)
    err_blocks = abs(math.sqrt(var) / float(np.std(sim)) - 1)
    assert err_normal > 2 * err_blocks, (err_normal, err_blocks)
