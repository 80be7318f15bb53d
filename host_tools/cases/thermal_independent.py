"""A second thermal record generator, written apart from abbe's identification (it imports
nothing of ``abbe``): a lumped thermal network (spindle bearing, housing, column, room air)
heated by the spindle, integrated by scipy's adaptive ODE solver (``solve_ivp``, RK45, in
continuous time, not abbe's backward Euler), with displacement channels that are known
gains times first-order lags (continuous, d s / dt = (u - s) / tau) of the network's
sensed temperatures or of the spindle speed. It writes the documented thermal record CSV
(docs/formats.md, "Thermal record CSV") and returns the truth, so a test can check that
identification recovers the gains and time constants within its intervals.

The lags of the truth are continuous-time; abbe's model discretises them by backward Euler,
whose effective time constant differs from the continuous one by about dt/2 (7.5 s at
15 s samples): the test compares with that in mind (docs/thermal.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp


@dataclass(frozen=True)
class TrueTerm:
    """A channel's term: ``input`` ("T1".."T4" or "spindle"), gain um/K or um/krpm, tau s."""

    input: str
    gain: float
    tau_s: float


#: The truth of the default case: ch_z grows with the housing through a slow lag and with
#: the speed through a fast one; ch_x follows the bearing.
TRUTH: dict[str, tuple[TrueTerm, ...]] = {
    "chz": (TrueTerm("T2", 6.0, 2400.0), TrueTerm("spindle", -4.0, 900.0)),
    "chx": (TrueTerm("T1", 1.5, 1500.0),),
}
SCHEDULE_RPM = (1500.0, 3000.0, 4500.0, 2000.0, 4000.0, 2500.0)


def generate(seed: int = 1, dt_s: float = 15.0, on_s: float = 4 * 3600.0,
             off_s: float = 4 * 3600.0, schedule=SCHEDULE_RPM,
             noise_um: float = 0.1, noise_k: float = 0.01, idle_s: float = 360.0,
             truth: dict[str, tuple[TrueTerm, ...]] = TRUTH):
    """(csv text, truth, time s): the record of the network under the speed schedule."""
    # network: C dT/dt = sum of flows; T1 bearing, T2 housing, T3 column, T4 room air
    c = np.array([2.0e4, 1.2e5, 6.0e5])          # J/K
    g12, g23, g2a, g3a = 25.0, 12.0, 6.0, 10.0     # W/K
    names = ["T1", "T2", "T3", "T4"]
    terms = [(ch, k, t) for ch, ts in truth.items() for k, t in enumerate(ts)]

    def room(t: float) -> float:
        return 21.0 + 0.4 * np.sin(2 * np.pi * t / 86400.0)

    def rhs(t: float, x: np.ndarray, rpm: float) -> np.ndarray:
        t1, t2, t3 = x[:3]
        ta = room(t)
        q = 30.0 * (rpm / 1000.0) ** 1.6            # W: bearing friction
        d = np.empty_like(x)
        d[0] = (q - g12 * (t1 - t2)) / c[0]
        d[1] = (g12 * (t1 - t2) - g23 * (t2 - t3) - g2a * (t2 - ta)) / c[1]
        d[2] = (g23 * (t2 - t3) - g3a * (t3 - ta)) / c[2]
        temps = {"T1": t1, "T2": t2, "T3": t3, "T4": ta, "spindle": rpm / 1000.0}
        for j, (_, _, term) in enumerate(terms):
            u = temps[term.input] - (x0_in[term.input])
            d[3 + j] = (u - x[3 + j]) / term.tau_s if term.tau_s > 0 else 0.0
        return d

    x0 = np.array([room(0.0)] * 3 + [0.0] * len(terms))
    x0_in = {"T1": x0[0], "T2": x0[1], "T3": x0[2], "T4": room(0.0), "spindle": 0.0}
    segs = [(0.0, idle_s, 0.0)]  # a cold start, the spindle stopped (as the real test)
    t0 = idle_s
    for rpm in schedule:
        segs += [(t0, t0 + on_s, rpm), (t0 + on_s, t0 + on_s + off_s, 0.0)]
        t0 += on_s + off_s
    t_all = np.arange(0.0, t0 + dt_s / 2, dt_s)
    xs = np.empty((t_all.size, x0.size))
    rpm_all = np.zeros(t_all.size)
    x = x0
    for a, b, rpm in segs:
        sel = (t_all >= a) & ((t_all < b) | ((b == t0) & (t_all <= b)))
        sol = solve_ivp(rhs, (a, b), x, args=(rpm,), t_eval=t_all[sel], rtol=1e-9, atol=1e-9,
                        max_step=60.0)
        xs[sel] = sol.y.T
        # the speed a sample shows is the one that held since the previous sample (the
        # record's convention, docs/formats.md): a step at a sample's instant shows next
        rpm_all[(t_all > a) & (t_all <= b)] = rpm
        x = solve_ivp(rhs, (a, b), x, args=(rpm,), rtol=1e-9, atol=1e-9, max_step=60.0).y[:, -1]
    rng = np.random.default_rng(seed)
    temps = np.column_stack([xs[:, 0], xs[:, 1], xs[:, 2], [room(t) for t in t_all]])
    temps = temps + rng.normal(0.0, noise_k, temps.shape)
    sensed = {"T1": xs[:, 0], "T2": xs[:, 1], "T3": xs[:, 2],
              "T4": np.array([room(t) for t in t_all]), "spindle": rpm_all / 1000.0}
    chans = {}
    for ch in truth:
        v = np.zeros(t_all.size)
        for j, (name, _, term) in enumerate(terms):
            if name == ch:  # tau 0: a static term, the true (noise-free) input's rise
                v += term.gain * (xs[:, 3 + j] if term.tau_s > 0
                                  else sensed[term.input] - x0_in[term.input])
        chans[ch] = v + rng.normal(0.0, noise_um, v.size)
    head = ["time_s", "spindle_rpm"] + [f"{n}_c" for n in names] + [f"{c}_um" for c in chans]
    rows = [",".join(head)]
    cols = [t_all, rpm_all] + list(temps.T) + list(chans.values())
    for r in zip(*cols):
        rows.append(",".join(f"{v:.6f}" for v in r))
    return "\n".join(rows) + "\n", truth, t_all
