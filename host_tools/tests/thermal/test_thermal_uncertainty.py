"""Thermal results with U (k = 2) on the real record: the gains' U is identify's interval
at k = 2 (the covariance recomputed agrees), the predicted drift and held-out RMS carry U,
and where the first order and the Monte Carlo part by more than 10 % the MC's U is stated
(measured: ch1, ch3 drifts agree; ch5 and tilt_a do not, docs/uncertainty.md)."""

from __future__ import annotations

import pytest

from abbe.analysis.thermal.uncertainty import AGREEMENT, thermal_uncertainty


@pytest.fixture(scope="module")
def unc(real_fit):
    return thermal_uncertainty(real_fit, draws=300, seed=3)


def test_gain_U_is_identify_interval_at_k2(real_fit, unc) -> None:
    by = {s["name"]: s for s in unc["signals"]}
    for sig in real_fit.outputs:
        for t, row in zip(sig.fit.terms, by[sig.name]["terms"]):
            assert row["gain_U_typeA"] == pytest.approx(2.0 / 1.96 * t.gain_u95, rel=0.02), sig.name
            assert row["gain_U"] >= row["gain_U_typeA"]


def test_drift_and_heldout_rms_carry_U(unc) -> None:
    agree = 0
    for s in unc["signals"]:
        for key in ("drift", "heldout_rms"):
            d = s[key]
            assert d["U"] > 0 and d["U_mc"] > 0
            ok = abs(d["U_mc"] / d["U"] - 1.0) <= AGREEMENT
            assert d["U_stated"] == (d["U"] if ok else d["U_mc"])
            agree += ok
    # the check is not a formality: some results pass it, some do not
    assert 0 < agree < 2 * len(unc["signals"])
    ch3 = next(s for s in unc["signals"] if s["name"] == "ch3")
    assert abs(ch3["drift"]["U_mc"] / ch3["drift"]["U"] - 1.0) < AGREEMENT


def test_type_b_sensor_calibration(real_fit, unc) -> None:
    """The displacement sensors' calibration enters every figure: a channel's drift gains
    exactly |d| u_rel (its data scale, so do its gains and prediction); with every
    calibration declared 0 the budget is Type A alone; a tilt carries both its channels."""
    import dataclasses
    import numpy as np
    by = {s["name"]: s for s in unc["signals"]}
    ch1 = by["ch1"]["drift"]
    b = {c["name"]: c["u"] for c in ch1["budget"]}
    assert b["ch1 sensitivity"] == pytest.approx(abs(ch1["value"]) * 0.01 / 2, rel=1e-6)
    assert ch1["U"] == pytest.approx(2 * np.sqrt(sum(c["u"] ** 2 for c in ch1["budget"])))
    tilt = by["tilt_b"]["drift"]
    assert {c["name"] for c in tilt["budget"]} >= {"ch1 sensitivity", "ch2 sensitivity"}
    spec = real_fit.spec
    zero = dataclasses.replace(spec, temperature_calibration_U_pct=0.0, channels={
        n: dataclasses.replace(c, calibration_U_pct=0.0) for n, c in spec.channels.items()})
    u0 = thermal_uncertainty(dataclasses.replace(real_fit, spec=zero))
    for s in u0["signals"]:
        for key in ("drift", "heldout_rms"):
            if key in s:
                assert s[key]["U"] == pytest.approx(s[key]["U_typeA"])
        for row in s["terms"]:
            assert row["gain_U"] == pytest.approx(row["gain_U_typeA"])
