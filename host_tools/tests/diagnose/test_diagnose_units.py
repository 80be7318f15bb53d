"""Building blocks of `abbe diagnose`: the effect catalogue's table edits, the direction
state, the noise estimate, signatures computed through the model, the C path."""

from __future__ import annotations

import numpy as np
import pytest

from abbe.diagnose.candidates import Engine
from abbe.diagnose.effects import (
    NotRepresentable,
    PredParams,
    add_block,
    by_key,
    catalogue,
    copy_table,
)
from abbe.diagnose.evaluator import Evaluator
from abbe.diagnose.problem import Problem, estimate_noise
from abbe.diagnose.recommend import ballbar_check_from, ballbar_geometry
from abbe.diagnose.results import DiagnoseOptions
from abbe.diagnose.selection import diagnose
from abbe.formats.blob import read_blob, write_blob
from abbe.model import clib
from abbe.model.backlash import direction_state
from abbe.model.examples import paper_table
from abbe.model.reference import term_values
from abbe.model.table import FourierBlock
from cases.hidden_effects import CENTER_MM, REFERENCE_MM, hidden_case

BACKEND = "c" if clib.available() else "reference"


@pytest.fixture(scope="module")
def table():
    return paper_table()


def test_catalogue_covers_the_issue_list() -> None:
    keys = {e.key for e in catalogue()}
    for k in ("squareness_xy", "squareness_xz", "squareness_yz", "backlash_x", "backlash_y",
              "backlash_z", "scale_x", "scale_y", "scale_z", "cyclic_x", "cyclic_y", "cyclic_z",
              "thermal_drift_x", "servo_mismatch_xy", "tool_offset", "straightness_xy"):
        assert k in keys
    fams = {e.family for e in catalogue()}
    assert {"thermal_drift", "servo_mismatch", "straightness", "tool_offset"} <= fams
    assert not by_key()["servo_mismatch_xy"].compensable


def test_squareness_backlash_tool_edit_the_table_fields(table) -> None:
    cat = by_key()
    t, p = cat["squareness_yz"].apply(table, PredParams(), np.array([7.0]))
    assert t.squareness_urad[2] == pytest.approx(table.squareness_urad[2] + 7.0)
    assert table.squareness_urad[2] != t.squareness_urad[2]  # the input is not modified
    t, _ = cat["backlash_y"].apply(table, PredParams(), np.array([4.0]), 0.2)
    assert t.axes["Y"].backlash_um == 4.0 and t.axes["Y"].backlash_takeup_mm == 0.2
    t, _ = cat["tool_offset"].apply(table, PredParams(), np.array([1.0, 2.0, 3.0]))
    assert np.allclose(np.array(t.tool_offset_mm) - np.array(table.tool_offset_mm), [1, 2, 3])
    _, p = cat["servo_mismatch_zx"].apply(table, PredParams(), np.array([0.8]))
    assert p.servo_mismatch_ms[2] == 0.8 and p.plane_lags_ms("ZX") == (-0.4, 0.4)
    # every edited table still writes and reads as a valid blob
    read_blob(write_blob(t))


def test_scale_adds_k_ppm_about_the_reference(table) -> None:
    t, _ = by_key()["scale_x"].apply(table, PredParams(), np.array([12.0]))
    p = np.linspace(0.0, 500.0, 11)
    d = term_values(t, "X", "dx", p) - term_values(table, "X", "dx", p)
    assert np.allclose(d, 12.0e-3 * (p - REFERENCE_MM[0]), atol=1e-9)


def test_straightness_bow_is_the_mid_travel_sag(table) -> None:
    t, _ = by_key()["straightness_yx"].apply(table, PredParams(), np.array([3.0]))
    p = np.array([-400.0, -200.0, 0.0, REFERENCE_MM[1]])
    d = term_values(t, "Y", "dx", p) - term_values(table, "Y", "dx", p)
    assert d[1] - 0.5 * (d[0] + d[2]) == pytest.approx(3.0, abs=1e-9)
    assert d[3] == pytest.approx(0.0, abs=1e-9)  # zero at the reference point


def test_cyclic_goes_into_a_fourier_block_zero_at_reference(table) -> None:
    t, _ = by_key()["cyclic_z"].apply(table, PredParams(), np.array([1.0, 0.5]), 7.5)
    blk = t.axes["Z"].blocks[1]
    assert blk is not None and blk.period_mm == 7.5 and blk.harmonics == 1
    p = np.linspace(-300.0, 0.0, 301)
    d = term_values(t, "Z", "dz", p) - term_values(table, "Z", "dz", p)
    phi = 2 * np.pi * (p + 300.0) / 7.5
    expect = np.sin(phi) + 0.5 * np.cos(phi)
    assert np.allclose(d - d.mean(), expect - expect.mean(), atol=1e-9)
    assert float(term_values(t, "Z", "dz", np.array([REFERENCE_MM[2]]))[0]) == pytest.approx(
        float(term_values(table, "Z", "dz", np.array([REFERENCE_MM[2]]))[0]), abs=1e-9)


def test_no_free_block_is_not_representable(table) -> None:
    t = copy_table(table)
    ax = t.axes["X"]
    add_block(ax, 12.0, 0.0, 1)            # block 1 taken
    assert ax.blocks[1].period_mm == 12.0  # type: ignore[union-attr]
    with pytest.raises(NotRepresentable):
        add_block(ax, 7.0, 0.0, 1)        # block 0 is the long wave already
    assert add_block(ax, 12.0, 0.0, 2) == 1  # same period: reused, harmonics raised
    assert ax.blocks[1] == FourierBlock(12.0, 0.0, 2)


def test_direction_state_ramps_over_the_takeup() -> None:
    p = np.array([0.0, 1.0, 2.0, 1.95, 1.9, 1.0, 0.0])
    s = direction_state(p, 0.1)
    assert s[0] == 1.0 and s[2] == 1.0
    assert s[3] == pytest.approx(0.0) and s[4] == pytest.approx(-1.0) and s[6] == -1.0
    assert np.array_equal(direction_state(p, 0.0), [1, 1, 1, -1, -1, -1, -1])


def _ballbar(radial=None, step=2.0):
    g = ballbar_geometry("XY", CENTER_MM, step_deg=step)
    y = np.zeros(g["angle_deg"].size) if radial is None else radial
    return ballbar_check_from(g, y, REFERENCE_MM)


def test_noise_estimate_recovers_white_noise() -> None:
    rng = np.random.default_rng(5)
    c = _ballbar()
    th = np.radians(c.all_ang)
    y = 2.0 * np.sin(2 * th) + 0.8 * np.cos(3 * th) + rng.normal(0, 0.3, th.size)
    c = _ballbar(y)
    prob = Problem([c])
    sig, infl, rep = estimate_noise(prob, prob.y)
    assert sig[0] == pytest.approx(0.3, rel=0.15)
    assert infl[0] < 1.5


def test_squareness_signature_through_the_model_is_the_textbook_oval(table) -> None:
    """notes.md §4: S_xy gives (R S / 2) sin 2 theta after the circle fit."""
    c = _ballbar()
    eng = Engine(table, [c], DiagnoseOptions(backend=BACKEND))
    col = eng.sensitivity(by_key()["squareness_xy"], None, table, PredParams(), eng.y0)[:, 0]
    A = c.nuisance
    coef, *_ = np.linalg.lstsq(A, col, rcond=None)
    th = np.radians(c.x)
    expect = 0.5 * c.radius_mm * 1e-3 * np.sin(2 * th)  # um per urad
    assert np.allclose(col - A @ coef, expect, atol=2e-5)


def test_servo_signature_flips_with_direction(table) -> None:
    c = _ballbar()
    eng = Engine(table, [c], DiagnoseOptions(backend=BACKEND))
    col = eng.sensitivity(by_key()["servo_mismatch_xy"], None, table, PredParams(), eng.y0)[:, 0]
    th = np.radians(c.x)
    v = c.feed_mm_min / 60.0  # mm/s -> um per ms
    s = np.where(c.direction == "ccw", 1.0, -1.0)
    # (v dtau / 2) sin 2 theta, sign flipping between CCW and CW (notes.md §4)
    expect = -s * 0.5 * v * np.sin(2 * th)
    A = c.nuisance
    r = col - A @ np.linalg.lstsq(A, col, rcond=None)[0]
    assert np.corrcoef(r, expect)[0, 1] > 0.999
    assert np.std(r) == pytest.approx(np.std(expect), rel=0.01)


@pytest.mark.skipif(not clib.available(), reason="C library not built")
def test_c_and_reference_predictions_agree(table) -> None:
    case = hidden_case(3, ("backlash_x",), step_deg=6.0)
    pp = PredParams()
    pp.servo_mismatch_ms[0] = 0.5
    for c in case.checks:
        a = c.predict(Evaluator("c"), case.model, pp)
        b = c.predict(Evaluator("reference"), case.model, pp)
        assert np.max(np.abs(a - b)) < 2e-3  # um: float32 path vs float64 reference


def test_diagnose_uses_the_c_library_when_built(table) -> None:
    case = hidden_case(4, ("squareness_xy",), step_deg=6.0)
    res = diagnose(case.model, case.checks, DiagnoseOptions(backend=BACKEND))
    assert res.backend == BACKEND
    assert [e.key for e in res.effects] == ["squareness_xy"]
    # the updated table holds the squareness and predicts the checks better through the model
    assert res.table.squareness_urad[0] == pytest.approx(res.effects[0].value, abs=1e-6)
    assert res.gap["after"].rms_um < 0.5 * res.gap["before"].rms_um


def test_ambiguity_named_with_the_separating_test() -> None:
    """An XY ballbar sees only kx - ky: a hidden X scale error alone cannot be told from a
    Y one; the answer must say so and name a test that separates them."""
    case = hidden_case(9, ("scale_x",), step_deg=4.0, checks=("ballbar_xy",))
    res = diagnose(case.model, case.checks, DiagnoseOptions(backend=BACKEND))
    assert len(res.effects) == 1
    e = res.effects[0]
    assert e.key in ("scale_x", "scale_y")
    other = "scale_y" if e.key == "scale_x" else "scale_x"
    amb = {a["key"]: a for a in e.ambiguous_with}
    assert other in amb and amb[other]["r2"] > 0.99
    assert "laser" in amb[other]["separating_test"] or "ballbar_yz" in amb[other]["separating_test"] \
        or "ballbar_zx" in amb[other]["separating_test"]


def test_model_for_another_machine_is_tentative_not_confident() -> None:
    """Same geometry, another machine's model: names (if any) are flagged tentative."""
    a = hidden_case(11, ("squareness_xy",), step_deg=3.0)
    b = hidden_case(12, (), step_deg=3.0)
    res = diagnose(b.model, a.checks, DiagnoseOptions(backend=BACKEND))
    assert res.tentative and res.lack_of_fit > 2.0
    assert all(e.tentative for e in res.effects)
    assert any("LACK OF FIT" in n for n in res.notes)
    assert res.to_json()["lack_of_fit"]["tentative"] is True


def test_reversal_adds_s_r_over_2_on_the_own_term() -> None:
    """The position-dependent reversal acts like the constant backlash: the own term gets
    + s R(p) / 2 (s = +1 for the + approach), R a Chebyshev series over the travel or
    per-target values (sum zero, linear between the targets)."""
    from abbe.diagnose.checks import LaserChannel, LaserCheck
    from abbe.diagnose.effects import REVERSAL_MAX_DEGREE
    table = paper_table()
    tg = np.linspace(20.0, 480.0, 7)
    order = np.arange(3 * 2 * tg.size).reshape(3, 2, tg.size)
    c = LaserCheck("laser_X", "X", REFERENCE_MM, tg, [LaserChannel("linear", "dx", 1, np.zeros((3, 2, tg.size)))],
                   order, REFERENCE_MM)
    eng = Engine(table, [c], DiagnoseOptions(backend=BACKEND))
    spec = by_key()["reversal_x"]
    assert [k is not None for k in eng.pp.reversal_knots_mm] == [True, False, False]
    th = np.zeros(len(spec.params))
    th[0] = 4.0                                   # r1: 4 um x T1(u)
    th[REVERSAL_MAX_DEGREE] = 2.0                 # t1: +2 um at the first target ...
    t2, p2 = spec.apply(table, eng.pp, th)
    d = (c.predict(eng.ev, t2, p2) - eng.y0).reshape(3, 2, tg.size)
    lo, hi = table.axes["X"].travel_mm
    u = (2 * tg - lo - hi) / (hi - lo)
    per = np.zeros(tg.size)
    per[0], per[-1] = 2.0, -2.0                   # ... and -2 um at the last (sum zero)
    R = 4.0 * u + per
    assert np.allclose(d[:, 0], R / 2, atol=2e-3) and np.allclose(d[:, 1], -R / 2, atol=2e-3)
    assert table.axes["X"].backlash_um == t2.axes["X"].backlash_um   # the table is untouched


def test_reversal_needs_bidirectional_runs_of_the_axis(table) -> None:
    c = _ballbar()
    eng = Engine(table, [c], DiagnoseOptions(backend=BACKEND))
    from abbe.diagnose.problem import qr_basis
    W = np.ones(eng.prob.N)
    cands = eng.build_candidates(table, eng.pp, eng.y0, W, qr_basis(eng.prob.nuis),
                                 [by_key()["reversal_x"]])
    assert not cands[0].observable and "bidirectional" in cands[0].why_not


def test_thermal_reference_is_the_models_temperature(table) -> None:
    """T_ref: the table's own, else the user's, else the lowest logged temperature (not
    the temperature of whichever check happens to be listed first)."""
    from abbe.diagnose.candidates import reference_temperature
    g = ballbar_geometry("XY", CENTER_MM)
    warm = ballbar_check_from(g, np.zeros(g["angle_deg"].size), REFERENCE_MM)
    warm.all_temp = np.full(g["angle_deg"].size, 24.0)
    cold = _ballbar()
    cold.all_temp = np.linspace(20.5, 21.0, cold.all_ang.size)
    assert reference_temperature(table, [warm, cold], None) == pytest.approx(20.5)
    assert reference_temperature(table, [warm, cold], 19.0) == pytest.approx(19.0)
    t = copy_table(table)
    t.axes["Y"].thermal_offset_um_per_k = 0.5
    t.axes["Y"].thermal_tref_c = 22.25
    assert reference_temperature(t, [warm, cold], 19.0) == pytest.approx(22.25)
