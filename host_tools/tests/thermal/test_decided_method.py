"""The "decided" identification (docs/thermal.md, "The decided method"): undecided choices go
to the input the spindle's heat input explains best, and the terms the data do not decide
(gain interval containing 0, time constant not known within a factor of 2, or held at the
cap) are dropped from the selected set."""

from __future__ import annotations

import math

import numpy as np

from abbe.analysis.thermal.identify import (TAU_BOUNDS_S, Candidate, bounded, candidates_of,
                                            identify_channel, prune, spindle_coupling)
from abbe.formats.thermal_record import read_thermal_csv
from abbe.model.thermal import SPEED, TEMPERATURE, ThermalTerm, lag_states


def test_bounded_rule():
    ok = ThermalTerm(input=0, tau_s=1000.0, gain=2.0, gain_u95=0.5, tau_u95_s=400.0)
    assert bounded(ok)
    assert bounded(ThermalTerm(input=0, tau_s=0.0, gain=2.0, gain_u95=1.9, tau_u95_s=0.0))
    # a gain interval containing 0, a tau not known within a factor of 2, an unbounded
    # tau, a tau held at the cap: not decided
    assert not bounded(ThermalTerm(input=0, tau_s=0.0, gain=2.0, gain_u95=2.1, tau_u95_s=0.0))
    assert not bounded(ThermalTerm(input=0, tau_s=1000.0, gain=2.0, gain_u95=0.5,
                                   tau_u95_s=1001.0))
    assert not bounded(ThermalTerm(input=0, tau_s=1000.0, gain=2.0, gain_u95=0.5,
                                   tau_u95_s=None))
    assert not bounded(ThermalTerm(input=0, tau_s=TAU_BOUNDS_S[1], gain=2.0, gain_u95=0.5,
                                   tau_u95_s=10.0))
    assert not bounded(ThermalTerm(input=0, tau_s=1000.0, gain=2.0, gain_u95=None,
                                   tau_u95_s=10.0))


def test_spindle_coupling_tells_a_heated_sensor_from_the_room():
    t = np.arange(0.0, 24 * 3600.0, 15.0)
    speed = np.where((t % 28800.0) < 14400.0, 1.0 + (t // 28800.0), 0.0)  # krpm steps
    heated = 3.0 * lag_states(speed, t, 1800.0)
    room = 1.5 * np.sin(2 * math.pi * t / 86400.0)  # a daily swing the speed does not cause
    cands = [Candidate("heated", TEMPERATURE, heated), Candidate("room", TEMPERATURE, room),
             Candidate("spindle", SPEED, speed)]
    c = spindle_coupling(t, cands, np.ones(t.size, bool))
    assert c[2] == 1.0
    assert c[0] > 0.99
    assert c[1] < 0.5
    # without a speed input no input has physical support
    assert spindle_coupling(t, cands[:2], np.ones(t.size, bool)) == [0.0, 0.0]


def test_prune_drops_an_input_that_explains_nothing(synthetic):
    """A noise input added to the true terms is dropped (its gain interval contains 0);
    the true terms stay."""
    folder, truth = synthetic
    r = read_thermal_csv(folder / "record.csv")
    cands = candidates_of(r.temps_c, list(r.temp_names), r.speed_rpm)
    rng = np.random.default_rng(7)
    cands.append(Candidate("noise", TEMPERATURE, np.cumsum(rng.normal(0, 1e-3, r.time_s.size))))
    ident = r.hours < 24.0
    k = list(r.channel_names).index("chx")
    y = r.disp_um[:, k] - r.disp_um[0, k]
    t1 = [c.name for c in cands].index("T1")
    keep, dropped = prune(r.time_s, y, cands, [(t1, 1500.0), (len(cands) - 1, 0.0)], ident)
    assert [i for i, _ in keep] == [t1]
    assert len(dropped) == 1 and dropped[0].startswith("noise")


def test_decided_method_recovers_the_independent_truth(synthetic):
    """The decided method on the independent network: the true inputs selected, gains and
    time constants within their intervals, every kept term decided by the data, the next
    24 h (other speeds) predicted to < 0.45 um RMS (noise 0.3 um). The speed's gain is
    allowed 1 % beyond its interval: the held speed acts half a sample before its reading,
    which the forward selection absorbs in a static speed term of gain 0.003 +/- 0.022
    (docs/thermal.md) and the decided method drops as undecided (-4.018 +/- 0.015 um/krpm
    against -4.0 remains)."""
    folder, truth = synthetic
    r = read_thermal_csv(folder / "record.csv")
    cands = candidates_of(r.temps_c, list(r.temp_names), r.speed_rpm)
    ident = r.hours < 24.0
    for k, ch in enumerate(r.channel_names):
        y = r.disp_um[:, k] - r.disp_um[0, k]
        fit = identify_channel(ch, r.time_s, y, cands, ident, 8 * 3600.0, decided_only=True)
        assert all(bounded(t) for t in fit.terms), (ch, fit.terms)
        found = {(cands[t.input].name, t.tau_s > 0): t for t in fit.terms}
        for true in truth[ch]:
            t = found.get((true.input, true.tau_s > 0))
            assert t is not None, f"{ch}: {true.input} not selected: {fit.steps} {fit.dropped}"
            slack = 0.01 * abs(true.gain) if true.input == "spindle" else 0.0
            assert abs(t.gain - true.gain) <= t.gain_u95 + slack, (ch, true, t)
            tau_be = (15.0 / math.expm1(15.0 / true.tau_s) if true.input == "spindle"
                      else true.tau_s)
            assert abs(t.tau_s - tau_be) <= (t.tau_u95_s or 0.0), (ch, true, t)
        pred = fit.offset_um + sum(t.gain * lag_states(cands[t.input].rise, r.time_s, t.tau_s)
                                   for t in fit.terms)
        held = ~ident
        assert float(np.sqrt(np.mean((y - pred)[held] ** 2))) < 0.45, ch
