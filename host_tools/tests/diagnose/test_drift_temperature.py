"""A drift in a laser campaign tied to the campaign's temperatures (abbe.diagnose.drift_temperature).

The campaign is generated here, apart from abbe: a temperature history chosen independently
of the machine (a warm-up plus a ripple), the axis following it through a continuous
first-order lag integrated by scipy's ODE solver (not abbe's backward Euler), a known
expansion coefficient and offset per kelvin, a static error per target and direction,
noise; written as a laser CSV with ``time_s`` and ``temp_c`` and diagnosed by the CLI's
entry point."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from abbe.diagnose.drift_temperature import tie_drift
from abbe.diagnose.run import diagnose_positioning

K_PPM = 11.5      # expansion, ppm/K
O_UM = 0.8        # offset per kelvin, um/K
TAU_S = 1800.0    # the axis follows the temperature through this lag, s


def _temperature(t: np.ndarray) -> np.ndarray:
    """Material temperature, deg C: a warm-up and a ripple, unrelated to the readings."""
    return 20.3 + 2.0 * (1.0 - np.exp(-t / 7200.0)) + 0.5 * np.sin(2 * math.pi * t / 5000.0)


def _campaign(tmp_path, *, tied: bool, seed: int = 4) -> str:
    rng = np.random.default_rng(seed)
    targets = np.linspace(0.0, 600.0, 13)
    static = {(d, k): 3.0 * math.sin(x / 150.0) + (1.5 if d == "-" else 0.0)
              for d in "+-" for k, x in enumerate(targets)}
    rows, times = [], []
    t = 0.0
    for run in range(1, 9):
        for d in "+-":
            ks = range(len(targets)) if d == "+" else range(len(targets) - 1, -1, -1)
            for k in ks:
                rows.append((run, d, k))
                times.append(t)
                t += 40.0
        t += 600.0  # a pause between runs
    times_a = np.array(times)
    temp = _temperature(times_a)
    sol = solve_ivp(lambda tt, s: [(_temperature(np.array([tt]))[0] - temp[0] - s[0]) / TAU_S],
                    (0.0, times_a[-1]), [0.0], t_eval=times_a, rtol=1e-9, atol=1e-12, max_step=60.0)
    lag = sol.y[0]
    lines = ["run,direction,target_mm,linear_um,time_s,temp_c"]
    for (run, d, k), ti, tc, lg in zip(rows, times_a, temp, lag):
        x = targets[k]
        drift = ((O_UM + K_PPM * 1e-3 * x) * lg if tied
                 else 4.0 * ti / 3600.0 * (0.3 + x / 600.0))  # a drift in time, not in T
        v = static[(d, k)] + drift + rng.normal(0.0, 0.15)
        lines.append(f"{run},{d},{x:.3f},{v:.4f},{ti:.1f},{tc + rng.normal(0.0, 0.01):.4f}")
    p = tmp_path / ("tied.csv" if tied else "untied.csv")
    p.write_text("\n".join(lines) + "\n")
    return str(p)


def test_a_thermal_drift_is_tied_to_the_campaign_temperature(tmp_path):
    res = diagnose_positioning(_campaign(tmp_path, tied=True), "X")
    (tie,) = res.drift_ties
    assert tie.named, tie
    assert abs(tie.expansion_ppm_per_k - K_PPM) <= tie.expansion_u95, tie
    assert abs(tie.offset_um_per_k - O_UM) <= tie.offset_u95, tie
    assert tie.tau_u95_s is not None and abs(tie.tau_s - TAU_S) <= tie.tau_u95_s, tie
    assert tie.rms_temperature_um < 0.25 < tie.rms_time_only_um  # noise 0.15 um
    d = json.loads(json.dumps(res.to_json()))
    assert d["drift_temperature"][0]["named"] is True
    assert "follows the temperature through a lag" in tie.sentence()


def test_a_drift_in_time_is_not_blamed_on_the_temperature(tmp_path):
    res = diagnose_positioning(_campaign(tmp_path, tied=False), "X")
    (tie,) = res.drift_ties
    assert not tie.named, tie
    assert "not explained by the temperature" in tie.sentence()


def test_no_temperature_no_tie(tmp_path):
    p = _campaign(tmp_path, tied=True)
    lines = open(p).read().splitlines()
    stripped = [",".join(line.split(",")[:5]) for line in lines]
    q = tmp_path / "no_temp.csv"
    q.write_text("\n".join(stripped) + "\n")
    assert diagnose_positioning(str(q), "X").drift_ties == []


def test_tie_needs_readings_that_can_carry_it():
    t = np.arange(4.0)
    assert tie_drift("c", t, np.full(4, 20.0), t, t, np.arange(4)) is None  # no temperature change
    with pytest.raises(ValueError):
        tie_drift("c", np.arange(3.0), np.arange(3.0), np.arange(3.0), np.arange(4.0),
                  np.arange(3))
