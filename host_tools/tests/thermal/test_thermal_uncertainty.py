"""Thermal results with U (k = 2) on the real record: the gains' U is identify's interval
at k = 2 (the covariance recomputed agrees), the predicted drift and held-out RMS carry U,
and where the first order and the Monte Carlo part by more than 10 % the MC's U is stated
(measured: ch1, ch4 drifts agree; ch5 and tilt_a do not, docs/uncertainty.md). The analytic U
is the degree-5 cubature, the first order beside it (U_first_order)."""

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
    # ch2, composed of ch1's and tilt b's fits (issue 35, round 5): both fits' parameters
    # and the three sensors carried together
    ch2 = next(s for s in unc["signals"] if s["name"] == "ch2")
    assert ch2["composed"].startswith("ch1 + 0.1 x tilt_b")
    assert abs(ch2["drift"]["U_mc"] / ch2["drift"]["U"] - 1.0) < AGREEMENT
    assert {c["name"] for c in ch2["drift"]["budget"]} >= {"ch1 sensitivity", "ch2 sensitivity"}


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
    assert ch1["U_first_order"] == pytest.approx(2 * np.sqrt(sum(c["u"] ** 2 for c in ch1["budget"])))
    tilt = by["tilt_b"]["drift"]
    assert {c["name"] for c in tilt["budget"]} >= {"ch1 sensitivity", "ch2 sensitivity"}
    spec = real_fit.spec
    zero = dataclasses.replace(spec, temperature_calibration_U_pct=0.0, channels={
        n: dataclasses.replace(c, calibration_U_pct=0.0) for n, c in spec.channels.items()})
    u0 = thermal_uncertainty(dataclasses.replace(real_fit, spec=zero))
    for s in u0["signals"]:
        for key in ("drift", "heldout_rms"):
            if key in s:
                assert s[key]["U_first_order"] == pytest.approx(s[key]["U_typeA"])
        for row in s["terms"]:
            assert row["gain_U"] == pytest.approx(row["gain_U_typeA"])


def test_cubature_is_exact_for_a_quadratic() -> None:
    """The rule's variance of a quadratic form in Gaussian inputs is the exact one
    (2 tr((AC)^2) + 4 m^T A C A m, cross terms included), which the first order misses."""
    import numpy as np
    from abbe.analysis.thermal.uncertainty import cubature5
    rng = np.random.default_rng(4)
    n = 6
    B = rng.standard_normal((n, n))
    C = B @ B.T / n
    A = rng.standard_normal((n, n))
    A = A + A.T
    m = rng.standard_normal(n) * 0.3
    AC = A @ C
    for frames in (1, 3):  # exact in every frame, so in their average
        mean, sd = cubature5(lambda x: np.array([x @ A @ x]), m, C, frames=frames)
        assert mean[0] == pytest.approx(m @ A @ m + np.trace(AC), rel=1e-9)
        assert sd[0] ** 2 == pytest.approx(2 * np.trace(AC @ AC) + 4 * m @ A @ C @ A @ m, rel=1e-9)
    first_order = 4 * m @ A @ C @ A @ m
    assert abs(first_order / sd[0] ** 2 - 1) > 0.5


#: The figures the cubature carries (docs/uncertainty.md, measured with 3 x 1000 draws, seeds
#: 1-3: 41 of 42 within 10 %, the miss ch5's held-out RMS at +11 % with seed 2; +3 % with
#: the test's draws). Left out of the assertion: ch5's drift (+7 % at worst), ch2's and
#: tilt_a's held-out RMS (-7 %, -9 %; ch2's before round 5 composed it, -0.3 / +1.4 /
#: +0.1 % since, 3 x 1000 draws): with the test's 300 draws (about +-5 % of sampling
#: spread) they pass or fail with the draws. ch3's two figures left out since issue 35's
#: round 4 (its room-sensor term t8, gain interval reaching 0 and lag not bounded: the MC
#: parts from the cubature by +8..+11 % on the drift, +15..+26 % on the held-out RMS).
#: Since round 5 ch2 and ch4 are composed (partner + tilt, both fits' parameters): ch2's
#: figures within 4 % (3 x 1000 draws); ch4's two left out (it carries ch3's t8 term: drift
#: MC +14..+16 %, held-out RMS +20..+26 %).
CUBATURE_HOLDS = [(n, "drift") for n in ("ch1", "ch2", "tilt_b", "tilt_a")] + [
    (n, "heldout_rms") for n in ("ch1", "ch2", "ch5", "tilt_b")]


def test_cubature_agrees_with_the_monte_carlo_where_first_order_did_not(unc) -> None:
    """The analytic U (cubature) within 10 % of the Monte Carlo (300 draws, seed 3) on 8
    named figures; on two of them (ch1's and tilt_b's held-out RMS: the RMS near a minimum)
    the first order is more than 50 % off, so this test fails if the propagation falls back
    to it."""
    by = {s["name"]: s for s in unc["signals"]}
    fo_off = 0
    for name, key in CUBATURE_HOLDS:
        d = by[name][key]
        assert abs(d["U_mc"] / d["U"] - 1.0) <= AGREEMENT, (name, key, d["U"], d["U_mc"])
        assert d["U_stated"] == d["U"] and d["U_from"].startswith("degree-5 cubature")
        fo_off += abs(d["U_mc"] / d["U_first_order"] - 1.0) > 0.5
    assert fo_off >= 2
    lo, hi = by["ch5"]["heldout_rms"]["interval95_mc"]
    assert lo < by["ch5"]["heldout_rms"]["value"] < hi
