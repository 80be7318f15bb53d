"""Steps 3-5: run averaging, straightness detrending (Eq. 1), reference adaptation."""

from __future__ import annotations

import numpy as np
import pytest

from abbe.analysis.fit.prep import average_runs, detrend_line, relative_to_reference, value_at


def test_average_runs_mean_reversal_noise() -> None:
    rng = np.random.default_rng(1)
    T, n = 7, 5
    base = np.linspace(-2, 3, T)
    runs = np.empty((n, 2, T))
    runs[:, 0] = base + 1.5 + rng.normal(0, 0.2, (n, T))
    runs[:, 1] = base - 1.5 + rng.normal(0, 0.2, (n, T))
    st = average_runs(runs)
    np.testing.assert_allclose(st.mean, runs.mean(axis=(0, 1)))
    np.testing.assert_allclose(st.reversal, runs[:, 0].mean(0) - runs[:, 1].mean(0))
    assert np.mean(st.reversal) == pytest.approx(3.0, abs=0.15)
    s = runs.std(axis=0, ddof=1)
    assert st.noise == pytest.approx(np.sqrt(np.mean(s ** 2)))
    assert 0.15 < st.noise < 0.25
    with pytest.raises(ValueError):
        average_runs(np.zeros((5, 3, 4)))


def test_detrend_removes_exactly_the_least_squares_line() -> None:
    p = np.linspace(0, 500, 51)
    sag = -4 * (1 - ((2 * p - 500) / 500) ** 2)
    y = sag + 0.03 * p + 2.0  # 30 urad set-up slope, 2 um offset
    d, k, b = detrend_line(p, y)
    # The residual is orthogonal to [p, 1] (normal equations) ...
    assert abs(np.sum(d)) < 1e-9 and abs(np.sum(d * p)) < 1e-6
    # ... and equals the sag minus the sag's own LS line.
    ds, ks, bs = detrend_line(p, sag)
    np.testing.assert_allclose(d, ds, atol=1e-12)
    assert k == pytest.approx(0.03 + ks) and b == pytest.approx(2.0 + bs)
    # A pure line detrends to zero.
    z, k2, _ = detrend_line(p, 0.01 * p - 3)
    assert np.max(np.abs(z)) < 1e-12 and k2 == pytest.approx(0.01)


def test_relative_to_reference() -> None:
    p = np.array([0.0, 10.0, 20.0])
    y = np.array([1.0, 3.0, 7.0])
    assert value_at(p, y, 15.0) == pytest.approx(5.0)
    r, v = relative_to_reference(p, y, 15.0)
    assert v == pytest.approx(5.0)
    np.testing.assert_allclose(r, [-4.0, -2.0, 2.0])
    r, v = relative_to_reference(p, y, 15.0, value_at_ref=1.0)
    np.testing.assert_allclose(r, [0.0, 2.0, 6.0])


def test_estimate_thermal_recovers_offset_and_expansion() -> None:
    """Within-cell regression on the logged temperature: the geometric term cancels."""
    from abbe.analysis.fit.prep import estimate_thermal
    rng = np.random.default_rng(3)
    p = np.linspace(0.0, 500.0, 21)
    ref = 160.0
    T = 20.0 + np.linspace(0.0, 3.0, 5 * 2 * 21).reshape(5, 2, 21)
    geo = 4.0 * np.sin(p / 80.0)
    dT = T - 20.0
    y = geo + 1.5 * dT + 8.0 * dT * (p - ref) * 1e-3 + rng.normal(0, 0.1, T.shape)
    out = estimate_thermal(y, T, p, ref, 20.0)
    assert out["significant"]
    assert out["offset_um_per_k"] == np.float64(out["offset_um_per_k"])
    assert abs(out["offset_um_per_k"] - 1.5) < 4 * out["se_offset_um_per_k"]
    assert abs(out["expansion_ppm_per_k"] - 8.0) < 4 * out["se_expansion_ppm_per_k"]
    corrected = y - out["correction_um"]
    assert np.std(corrected - geo) < 0.15
    flat = estimate_thermal(y, np.full(T.shape, 21.0), p, ref, 21.0)
    assert not flat["significant"] and not np.any(flat["correction_um"])


def test_assess_reversal_position_dependent_or_not() -> None:
    """A reversal that grows along the travel is named position dependent (with its
    series); a constant one with noise is not."""
    from abbe.analysis.fit.prep import assess_reversal
    rng = np.random.default_rng(8)
    p = np.linspace(0.0, 400.0, 21)
    u = (2 * p - 400.0) / 400.0
    g = 3.0 * np.sin(p / 60.0)
    for slope, expect in ((6.0, True), (0.0, False)):
        B = -12.0 + slope * u
        runs = np.empty((5, 2, p.size))
        runs[:, 0] = g + B / 2 + rng.normal(0, 0.5, (5, p.size))
        runs[:, 1] = g - B / 2 + rng.normal(0, 0.5, (5, p.size))
        out = assess_reversal(average_runs(runs), p, (0.0, 400.0))
        assert out["position_dependent"] is expect, out
        if expect:
            c = out["chebyshev_um"]
            assert abs(c[0] + 12.0) < 0.5 and abs(c[1] - 6.0) < 0.6
        assert len(out["per_target_um"]) == p.size
