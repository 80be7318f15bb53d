"""The fitted table's uncertainty (analysis/fit/uncertainty.py): the coefficient covariance
against a textbook line fit, the Monte Carlo check (GUM S1: redrawn means through the
pipeline's own steps and the reference evaluation) within 10 % on the vmc500 example and
the real ESS X record, the compensated residual, and a naive propagation the check catches."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from abbe.analysis.fit import uncertainty as fu_mod
from abbe.analysis.fit.pipeline import fit_machine, options_from_machine
from abbe.formats.machine import load_machine
from abbe.model.table import OWN_TERM, AxisTable, basis_matrix

from cases.ess_case import write_ess_case
from real_data import ESS_DAT, needs_real_data

REPO = Path(__file__).resolve().parents[3]
VMC = REPO / "examples" / "vmc500" / "machine.toml"
POINTS = np.array([[250.0, -200.0, -150.0], [0.0, 0.0, 0.0], [500.0, -400.0, -300.0],
                   [100.0, -350.0, -50.0]])
TOL = 0.10


def _fit(path: Path):
    m = load_machine(path)
    return fit_machine(m, options_from_machine(m))


@pytest.fixture(scope="module")
def vmc():
    return _fit(VMC)


@pytest.fixture(scope="module")
def vmc_mc(vmc):
    return fu_mod.monte_carlo(vmc, vmc.uncertainty, draws=800, seed=3, points_mm=POINTS)


def test_operator_reproduces_the_stored_coefficients(vmc) -> None:
    """G applied to the fitted means gives the stored coefficients: G is the fit's map."""
    for a, ar in vmc.axes.items():
        for t, tr in ar.terms.items():
            G = fu_mod.fit_operator(ar.targets_mm, ar.ref_mm, ar.table, tr.order,
                                    detrend=t in ("dx", "dy", "dz") and t != OWN_TERM[a])
            assert np.max(np.abs(G @ tr.stats.mean - tr.coef)) < 1e-8, (a, t)


def test_line_fit_matches_the_textbook_variance() -> None:
    """A straight line relative to a reference point: var e(p) = s^2 (p - ref)^2 / Sxx."""
    p = np.linspace(0.0, 100.0, 11)
    ref = 30.0
    tab = AxisTable(travel_mm=(0.0, 100.0), trend_degree=1, blocks=(None, None))
    G = fu_mod.fit_operator(p, ref, tab, (1, 0), detrend=False)
    s = 0.7
    cov = s * s * G @ G.T
    q = np.array([0.0, 12.5, 30.0, 77.0, 100.0])
    B = basis_matrix(tab, q)
    got = np.sqrt(np.einsum("ij,jk,ik->i", B, cov, B))
    want = s * np.abs(q - ref) / np.sqrt(np.sum((p - p.mean()) ** 2))
    assert np.allclose(got, want, rtol=1e-9, atol=1e-7)  # sqrt of a rounding-level variance at ref


def test_u_is_zero_at_the_reference_and_grows_with_the_scale(vmc) -> None:
    ar = vmc.axes["X"]
    tu = vmc.uncertainty.terms["X"]["dx"]
    u_ref = tu.u_at(ar.table, np.array([ar.ref_mm]))[0]
    assert u_ref < 1e-6
    ends = tu.u_at(ar.table, np.array(ar.table.travel_mm))
    # the scale input (ppm of the distance) dominates far from the reference
    assert tu.inputs["scale_u_ppm"] > 0
    assert ends[1] > ends[0] > 0  # the far end (500 mm) lies further from ref (163.6 mm)


@pytest.mark.parametrize("axis", ["X", "Y", "Z"])
def test_monte_carlo_agrees_along_each_axis(vmc, vmc_mc, axis: str) -> None:
    for t, v in vmc_mc["axes"][axis].items():
        assert fu_mod.worst_ratio(v["U_mc"], v["U"]) < TOL, (axis, t)


def test_monte_carlo_agrees_at_machine_points(vmc_mc) -> None:
    assert fu_mod.worst_ratio(vmc_mc["points_U_mc"], vmc_mc["points_U"], floor=0.0) < TOL


def test_monte_carlo_agrees_on_the_compensated_residual(vmc_mc) -> None:
    for a, d in vmc_mc["axes"].items():
        for t, v in d.items():
            for q in ("max_abs", "rms"):
                mc, an = v[f"compensated_{q}_U_mc"], v[f"compensated_{q}_U"]
                assert abs(mc / an - 1.0) < TOL, (a, t, q, an, mc)


def test_a_naive_propagation_fails_the_check(vmc, vmc_mc) -> None:
    """Dropping the coefficients' correlations (diagonal C) is what a per-coefficient
    interval would give: the check must see it."""
    worst = 0.0
    for a, ar in vmc.axes.items():
        for t, v in vmc_mc["axes"][a].items():
            tu = vmc.uncertainty.terms[a][t]
            B = basis_matrix(ar.table, v["grid_mm"])
            naive = 2 * np.sqrt(B ** 2 @ np.diag(tu.cov))
            worst = max(worst, fu_mod.worst_ratio(v["U_mc"], naive))
    assert worst > 3 * TOL


def test_residual_summary_exact_max_against_sampling() -> None:
    """The max |r| distribution (normal + rectangular per target) against direct sampling."""
    rng = np.random.default_rng(5)
    r = np.array([3.0, -2.5, 0.5, 2.9, -1.0])
    s, L = 0.8, 2.0
    got = fu_mod.residual_summary(r, s, L)
    e = rng.normal(0, s, (200000, r.size)) + rng.uniform(-L, L, (200000, r.size))
    mx = np.max(np.abs(r + e), axis=1)
    assert abs(got["max_abs_u"] / mx.std() - 1.0) < 0.02
    rms = np.sqrt(np.mean((r + e) ** 2, axis=1))
    assert abs(got["rms_u"] / rms.std() - 1.0) < 0.05


def test_model_json_carries_the_block(vmc) -> None:
    u = vmc.model_json["uncertainty"]
    assert u["k"] == 2.0 and u["budget_inputs"]["instrument"] == "laser_interferometer"
    d = u["axes"]["Y"]["terms"]["dy"]
    assert len(d["U_um"]) == len(d["grid_mm"]) == len(d["value_um"])
    assert d["U_max_um"] == max(d["U_um"])
    text = json.dumps(u, allow_nan=False)  # nothing NaN / Inf is written
    assert "covariance_urad2" in text
    back = fu_mod.terms_from_json(json.loads(text), vmc.table, "model.json")
    for a in back:
        for t, tu in back[a].items():
            assert np.allclose(tu.cov, vmc.uncertainty.terms[a][t].cov, rtol=1e-6, atol=1e-12)


@needs_real_data(ESS_DAT)
def test_monte_carlo_agrees_on_ess(tmp_path: Path) -> None:
    res = _fit(write_ess_case(ESS_DAT, tmp_path))
    mc = fu_mod.monte_carlo(res, res.uncertainty, draws=1500, seed=4)
    v = mc["axes"]["X"]["dx"]
    assert fu_mod.worst_ratio(v["U_mc"], v["U"]) < TOL
    for q in ("max_abs", "rms"):
        assert abs(v[f"compensated_{q}_U_mc"] / v[f"compensated_{q}_U"] - 1.0) < TOL, q
    # the triangulation sensor's linearity is in the budget: U well above repeatability alone
    tu = res.uncertainty.terms["X"]["dx"]
    assert tu.inputs["u_instrument"] > 5 * tu.inputs["u_repeatability"]


def test_residual_summary_of_a_perfect_noiseless_fit_is_zero() -> None:
    """One run fitted exactly (no spread, no residual): every figure 0, nothing divided by 0
    (the hostile corpus' one-run campaign crashed here once)."""
    got = fu_mod.residual_summary(np.zeros(6), 0.0)
    assert got["rms_U"] == 0.0 and got["max_abs"] == 0.0 and got["max_abs_U"] < 1e-8
