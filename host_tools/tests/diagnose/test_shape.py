"""Shape parameters of named effects (abbe.diagnose.shape, abbe.diagnose.describe): the
backlash take-up is estimated with a profile interval from a sharp step to a soft
take-up (the issue's miss: a sharp step gave a spurious servo mismatch), a
positioning bow rides on the scale effect, the servo statement says what circles
can and cannot tell."""

from __future__ import annotations

import numpy as np
import pytest

from abbe.diagnose.effects import PredParams, by_key
from abbe.diagnose.results import DiagnoseOptions
from abbe.diagnose.selection import diagnose
from abbe.model import clib
from abbe.model.reference import term_values
from cases.hidden_effects import REFERENCE_MM, hidden_case

BACKEND = "c" if clib.available() else "reference"


@pytest.mark.parametrize("takeup,seed", [(0.008, 41), (0.05, 42), (0.6, 45)])
def test_takeup_estimated_with_interval(takeup: float, seed: int) -> None:
    case = hidden_case(seed, ("backlash_x",), step_deg=1.0, takeup_mm=takeup,
                       checks=("ballbar_xy", "laser_x"))
    res = diagnose(case.model, case.checks, DiagnoseOptions(backend=BACKEND))
    assert [e.key for e in res.effects] == ["backlash_x"], res.notes
    e = res.effects[0]
    lo, hi = e.scan_ci95["takeup_mm"]
    assert (lo is None or lo <= takeup) and (hi is None or takeup <= hi), (e.scan, e.scan_ci95)
    assert hi is not None                      # the interval is bounded above
    assert e.value == pytest.approx(case.expected["backlash_x"], rel=0.1)
    # the residual falls to the noise: nothing left for a spurious servo mismatch
    assert res.lack_of_fit < 1.3


def test_scale_bow_parameter_is_the_mid_travel_sag() -> None:
    from abbe.model.examples import paper_table
    t0 = paper_table()
    t, _ = by_key()["scale_x"].apply(t0, PredParams(), np.array([5.0, 3.0]))
    p = np.array([0.0, 250.0, 500.0, REFERENCE_MM[0]])
    d = term_values(t, "X", "dx", p) - term_values(t0, "X", "dx", p)
    lin = 5.0e-3 * (p - REFERENCE_MM[0])
    sag = (d - lin)
    assert sag[1] - 0.5 * (sag[0] + sag[2]) == pytest.approx(3.0, abs=1e-9)
    assert d[3] == pytest.approx(0.0, abs=1e-9)


def test_servo_statement_without_the_feed_squared_oval() -> None:
    case = hidden_case(52, ("servo_mismatch_xy",), step_deg=2.0)
    res = diagnose(case.model, case.checks, DiagnoseOptions(backend=BACKEND))
    e = next(x for x in res.effects if x.key == "servo_mismatch_xy")
    assert e.shape is not None and "not resolved" in e.shape["servo_model"]
    assert any("second, higher feed" in n for n in e.shape_notes)


def test_servo_gain_term_is_the_feed_squared_oval() -> None:
    """q = kappa tau_mean dtau gives R w^2 q cos 2 theta, the same in CW and CCW."""
    from abbe.diagnose.recommend import ballbar_check_from, ballbar_geometry
    from abbe.diagnose.evaluator import Evaluator
    from abbe.model.examples import paper_table
    from cases.hidden_effects import CENTER_MM
    t = paper_table()
    out = {}
    for feed in (1000.0, 3000.0):
        g = ballbar_geometry("XY", CENTER_MM, feed_mm_min=feed, step_deg=2.0)
        c = ballbar_check_from(g, np.zeros(g["angle_deg"].size), REFERENCE_MM)
        pp = PredParams()
        y0 = c.predict(Evaluator(BACKEND), t, pp)
        pp.servo_gain_ms2[0] = 40.0
        d = c.predict(Evaluator(BACKEND), t, pp) - y0
        th = np.radians(c.x)
        A = np.column_stack([np.ones_like(th), np.cos(2 * th), np.sin(2 * th)])
        for lab in ("ccw", "cw"):
            m = c.direction == lab
            out[(feed, lab)] = np.linalg.lstsq(A[m], d[m], rcond=None)[0][1]
    w = 1000.0 / 60.0 / 100.0
    assert out[(1000.0, "ccw")] == pytest.approx(100e3 * w ** 2 * 40e-6, rel=0.02)
    assert out[(1000.0, "cw")] == pytest.approx(out[(1000.0, "ccw")], rel=0.02)
    assert out[(3000.0, "ccw")] == pytest.approx(9.0 * out[(1000.0, "ccw")], rel=0.02)
