"""Issue 35, round 4 (docs/thermal.md, "Issue 35, fourth round"): the structure candidates
of :mod:`abbe.analysis.thermal.structure`, on records made here with known truth, and the
adopted one (R4d, a room-sensor term) on the real record's identification hours."""

from __future__ import annotations

import math

import numpy as np
import pytest

from abbe.analysis.thermal.identify import (Candidate, candidates_of, cycles_of,
                                            identify_channel)
from abbe.analysis.thermal.structure import (forward_chain_rms, loco_rms, room_term,
                                             speed_candidates)
from abbe.model.thermal import SPEED, TEMPERATURE, ThermalTerm, lag_states

CYCLE_S = 8 * 3600.0


def _record(seed: int = 4):
    """24 h, three 8-h cycles at 1, 2, 3 krpm (4 h on); three heated sensors (the speed
    through lags), three room sensors (a daily swing with phases), the speed."""
    t = np.arange(0.0, 24 * 3600.0, 15.0)
    speed = np.where((t % CYCLE_S) < 14400.0, 1.0 + (t // CYCLE_S), 0.0)
    rng = np.random.default_rng(seed)
    cands = [Candidate(f"h{k}", TEMPERATURE, (2.0 + k) * lag_states(speed, t, 1500.0 * (k + 1))
                       + 0.01 * rng.standard_normal(t.size)) for k in range(3)]
    cands += [Candidate(f"r{k}", TEMPERATURE,
                        0.8 * np.sin(2 * math.pi * t / 86400.0 + 1.3 * k)
                        + 0.01 * rng.standard_normal(t.size)) for k in range(3)]
    cands.append(Candidate("spindle", SPEED, speed))
    return t, cands, rng


def test_speed_candidates_raise_only_the_speed():
    t, cands, _ = _record()
    got = speed_candidates(cands, 1.5)
    np.testing.assert_array_equal(got[-1].rise, cands[-1].rise ** 1.5)
    for a, b in zip(got[:-1], cands[:-1]):
        assert a.rise is b.rise


def test_forward_chaining_scores_the_last_cycle_from_the_earlier_ones():
    """An exact model extrapolates (RMS 0); a term that only fits the first two cycles'
    speeds does not (the true lag replaced by a static speed term)."""
    t, cands, _ = _record()
    y = 4.0 * lag_states(cands[-1].rise, t, 2400.0) + 1.0
    cyc = cycles_of(t, np.ones(t.size, bool), CYCLE_S)
    exact = [ThermalTerm(6, 2400.0, 0.0)]
    assert forward_chain_rms(t, y, cands, exact, cyc) < 1e-9
    static = [ThermalTerm(6, 0.0, 0.0)]
    assert forward_chain_rms(t, y, cands, static, cyc) > 0.3
    # leave-one-cycle-out sees the same miss on every cycle, forward chaining on the last
    assert loco_rms(t, y, cands, static, cyc) > 0.3


def test_the_room_term_is_found_with_its_gain():
    """Truth: 3 um/K x h1 through a 40-min lag plus 5 um/K x the room sensor r1 (static):
    the heated selection explains the heated part, the room step adds r1 (its gain within
    2 %: a slow daily swing, the refined lag of some minutes barely changes it)."""
    t, cands, rng = _record()
    y = (3.0 * lag_states(cands[1].rise, t, 2400.0) + 5.0 * cands[4].rise
         + 0.05 * rng.standard_normal(t.size))
    mask = np.ones(t.size, bool)
    fit = room_term("c", t, y, cands, mask, CYCLE_S)
    names = [cands[tt.input].name for tt in fit.terms]
    assert "r1" in names and fit.input_set == "heated+room"
    r1 = fit.terms[names.index("r1")]
    assert r1.gain == pytest.approx(5.0, rel=0.02)
    assert fit.fit_rms_um < 0.2  # noise 0.05 um; the heated sensors are lags of one another
    assert fit.steps[-1][0] == "r1"


def test_the_room_run_reuses_the_default_heated_path_unchanged():
    """The room run built from the default's heated-input path equals a fresh one (the
    forward selection's first steps do not depend on its term limit)."""
    t, cands, rng = _record(7)
    y = (2.0 * lag_states(cands[-1].rise, t, 3000.0) - 1.5 * lag_states(cands[0].rise, t, 900.0)
         + 4.0 * cands[3].rise + 0.05 * rng.standard_normal(t.size))
    mask = np.ones(t.size, bool)
    default = identify_channel("c", t, y, cands, mask, CYCLE_S, inputs="by_cv")
    assert default.heated_path is not None
    fresh = room_term("c", t, y, cands, mask, CYCLE_S)
    reused = room_term("c", t, y, cands, mask, CYCLE_S, heated_run=default)
    assert [(a.input, a.tau_s, a.gain) for a in fresh.terms] == \
        [(a.input, a.tau_s, a.gain) for a in reused.terms]
    assert fresh.steps == reused.steps


def test_the_real_records_ch3_takes_a_room_term(real_fit):
    """On the real record's hours 0-24 (the default fit, R4d): ch3 takes the room sensor t8
    beside t4 and t7, its leave-one-cycle-out CV lower than the R3a terms' (t4 lagged, t7
    static); the other channels keep R3a's runs; garbage in the held-out displacements
    gives the same room run."""
    r = real_fit.record
    by = {s.name: s for s in real_fit.channels}
    own = {n: (by[n].direct or by[n].fit) for n in by}  # ch2, ch4: round 5 composes them
    assert [own[n].input_set for n in ("ch1", "ch2", "ch3", "ch4", "ch5")] == \
        ["all", "heated", "heated+room", "all", "all"]
    w = by["ch3"].fit
    names = real_fit.input_names
    assert [names[tt.input] for tt in w.terms] == ["t4", "t7", "t8"]
    # the grid's static t8, refined to a 13-s lag (not bounded); its gain barely decided
    assert w.terms[2].tau_s < 60.0 and w.terms[2].gain == pytest.approx(-6.42, abs=0.01)
    cands = candidates_of(r.temps_c, list(r.temp_names), r.speed_rpm)
    ident = real_fit.ident_mask
    cyc = cycles_of(r.time_s, ident, CYCLE_S)
    y = by["ch3"].measured
    r3a = [ThermalTerm(names.index("t4"), 4260.0, 0.0), ThermalTerm(names.index("t7"), 0.0, 0.0)]
    assert loco_rms(r.time_s, y, cands, w.terms, cyc) < 0.9 * loco_rms(r.time_s, y, cands, r3a, cyc)
    y2 = y.copy()
    y2[~ident] = 1e3 * np.cos(np.arange((~ident).sum()))
    again = room_term("ch3", r.time_s, y2, cands, ident, CYCLE_S)
    assert [(a.input, a.tau_s, a.gain) for a in again.terms] == \
        [(a.input, a.tau_s, a.gain) for a in w.terms]
