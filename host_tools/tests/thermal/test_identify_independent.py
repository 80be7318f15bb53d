"""The independent check: a lumped thermal network integrated by scipy's ODE solver
(cases/thermal_independent.py, continuous-time lags, not abbe's backward Euler) with known
gains and time constants; identification on its first 24 h recovers them within its 95 %
intervals and predicts the next 24 h (other speeds) to the noise.

The backward-Euler lag's twin of a continuous lag tau: for a smooth input (a temperature)
tau itself (the same delay at low frequency); for an input held over each sample interval
(the speed: a sample shows the speed held since the previous one) the pole-matched
tau_BE = dt / (exp(dt / tau) - 1) ~ tau - dt / 2 (7.5 s at 15 s samples): the held input
acts half an interval before its sample (docs/thermal.md)."""

from __future__ import annotations

import math

import numpy as np

from abbe.analysis.thermal.identify import candidates_of, identify_channel
from abbe.formats.thermal_record import read_thermal_csv
from abbe.model.thermal import lag_states


def test_identification_recovers_the_truth_within_intervals(synthetic):
    folder, truth = synthetic
    r = read_thermal_csv(folder / "record.csv")
    cands = candidates_of(r.temps_c, list(r.temp_names), r.speed_rpm)
    ident = r.hours < 24.0
    held = r.hours >= 24.0
    for k, ch in enumerate(r.channel_names):
        y = r.disp_um[:, k] - r.disp_um[0, k]
        fit = identify_channel(ch, r.time_s, y, cands, ident, 8 * 3600.0)
        found = {(cands[t.input].name, t.tau_s > 0): t for t in fit.terms}
        for true in truth[ch]:
            t = found.pop((true.input, true.tau_s > 0), None)
            assert t is not None, f"{ch}: {true.input} not selected: {fit.steps}"
            assert abs(t.gain - true.gain) <= t.gain_u95, (ch, true, t)
            tau_be = (15.0 / math.expm1(15.0 / true.tau_s) if true.input == "spindle"
                      else true.tau_s)
            assert abs(t.tau_s - tau_be) <= (t.tau_u95_s or 0.0), (ch, true, t)
        for extra in found.values():  # anything else must be indistinguishable from zero
            assert abs(extra.gain) <= extra.gain_u95, (ch, extra)
        pred = fit.offset_um + sum(t.gain * lag_states(cands[t.input].rise, r.time_s, t.tau_s)
                                   for t in fit.terms)
        rms = float(np.sqrt(np.mean((y - pred)[held] ** 2)))
        assert rms < 0.45, (ch, rms)   # the displacement noise is 0.3 um
