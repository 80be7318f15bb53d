"""Drives, effects and instruments of the second independent generator.

From docs/formats.md (6D laser CSV, ballbar CSV and its conventions, machine
file) and docs/effects.md (what each catalogue effect is, physically). Own
choices, not the team's: the axis follows its command through a first-order
position loop integrated at 1 kHz; lost motion is the play operator (the
carriage stands until the command has crossed the play); the ballbar is sampled
in time at a fixed rate (angle steps of 1.5-2.5 deg at a random phase), its
angles written wrapped to [0, 360) in half of the files, its noise AR(1) in time
(correlation time 20-150 ms; first written as a per-sample correlation of
0.3-0.85, which at 1.5-2.5 deg steps is a wander over 10-40 deg: see
docs/effects.md) with the instrument's 0.1 um resolution; laser noise white per channel with a beam
tilt on the straightness channels and an arbitrary zero per channel.

Sign conventions: an effect is stated on the model term (d_j of the axis, um)
as the table would hold it; the tool-to-workpiece error along the axis is
``TO_E[a]`` times the term (docs/table-format.md: dX = -d_x(x) ..., dZ = +d_z(z)).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cases.independent2.machine import AXES, TERMS, Machine

TO_E = {"X": -1.0, "Y": -1.0, "Z": 1.0}
PLANES = {"XY": ("X", "Y"), "ZX": ("Z", "X"), "YZ": ("Y", "Z")}
CHANNEL_TERMS = {
    "X": {"linear": "dx", "straight_h": "dy", "straight_v": "dz", "yaw": "ez", "pitch": "ey", "roll": "ex"},
    "Y": {"linear": "dy", "straight_h": "dx", "straight_v": "dz", "yaw": "ez", "pitch": "ex", "roll": "ey"},
    "Z": {"linear": "dz", "straight_h": "dx", "straight_v": "dy", "yaw": "ey", "pitch": "ex", "roll": "ez"},
}


@dataclass
class Effects:
    """The machine's state at the checks (what the model may lack)."""
    play_um: dict[str, float] = field(default_factory=lambda: {a: 0.0 for a in AXES})
    scale_ppm: dict[str, float] = field(default_factory=lambda: {a: 0.0 for a in AXES})
    cyclic: dict[str, tuple[float, float, float]] = field(default_factory=dict)   # amp um, period mm, phase
    drift_um_per_h: dict[str, float] = field(default_factory=lambda: {a: 0.0 for a in AXES})
    lag_ms: dict[str, float] = field(default_factory=lambda: {a: 15.0 for a in AXES})

    def term_delta(self, a: str, q: np.ndarray, t_h: np.ndarray | float, ref: float) -> np.ndarray:
        """Change of the own positioning term d_a (um) at positions q, time t_h."""
        q = np.asarray(q, float)
        out = self.scale_ppm[a] * 1e-3 * (q - ref) + self.drift_um_per_h[a] * np.asarray(t_h, float)
        if a in self.cyclic:
            amp, per, ph = self.cyclic[a]
            out = out + amp * (np.sin(2 * np.pi * q / per + ph) - np.sin(2 * np.pi * ref / per + ph))
        return out


def first_order_lag(cmd: np.ndarray, dt_s: float, tau_ms: float) -> np.ndarray:
    """Axis position following ``cmd`` through a first-order loop (exact discretisation)."""
    if tau_ms <= 0:
        return cmd.copy()
    k = 1.0 - np.exp(-dt_s / (tau_ms * 1e-3))
    out = np.empty_like(cmd)
    y = cmd[0]
    for i, c in enumerate(cmd):
        y = y + k * (c - y)
        out[i] = y
    return out


def play(q: np.ndarray, width_mm: float) -> np.ndarray:
    """Play operator: the carriage moves only when the drive pushes it across the play."""
    if width_mm <= 0:
        return q.copy()
    h = width_mm / 2
    out = np.empty_like(q)
    y = q[0] - h          # starts having approached from below
    for i, v in enumerate(q):
        if v - y > h:
            y = v - h
        elif y - v > h:
            y = v + h
        out[i] = y
    return out


def ar1(rng: np.random.Generator, n: int, sigma: float, rho: float) -> np.ndarray:
    e = rng.normal(0.0, sigma * np.sqrt(1 - rho * rho), n)
    out = np.empty(n)
    prev = rng.normal(0.0, sigma)
    for i in range(n):
        prev = rho * prev + e[i]
        out[i] = prev
    return out


@dataclass
class Circle:
    name: str
    plane: str
    center: np.ndarray
    radius: float
    feed: float


def trace_um(m: Machine, eff: Effects, c: Circle, direction: str, arc: float, step: float,
             phase: float, t0_h: float, t_start: float,
             setup_mm: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free radial deviation (um) of one run of circle ``c`` and its sample times
    (s, from the run's start): the axes follow the command through their lag and play,
    the effects move the own terms, the machine's error motions move the tool tip."""
    a, b = PLANES[c.plane]
    ia, ib = AXES.index(a), AXES.index(b)
    v = c.feed / 60.0                                 # mm/s
    dt_sample = np.radians(step) * c.radius / v
    sweep = 360.0 + 2 * arc
    dur = np.radians(sweep) * c.radius / v
    fine = np.arange(0.0, dur + 1e-9, 1e-3)
    sgn = 1.0 if direction == "ccw" else -1.0
    th0 = -arc if direction == "ccw" else 360.0 + arc
    theta_f = th0 + sgn * np.degrees(v * fine / c.radius)
    cmd = np.tile(c.center, (len(fine), 1))
    cmd[:, ia] += c.radius * np.cos(np.radians(theta_f))
    cmd[:, ib] += c.radius * np.sin(np.radians(theta_f))
    act = cmd.copy()
    for j, ax in enumerate(AXES):
        if j in (ia, ib):
            act[:, j] = play(first_order_lag(cmd[:, j], 1e-3, eff.lag_ms[ax]), eff.play_um[ax] * 1e-3)
    ts = np.arange(phase, dur - 1e-9, dt_sample)
    idx = np.clip(np.round(ts / 1e-3).astype(int), 0, len(fine) - 1)
    t_abs_h = t0_h + (t_start + ts) / 3600.0
    q = act[idx]
    for j, ax in enumerate(AXES):
        q[:, j] = q[:, j] + TO_E[ax] * eff.term_delta(ax, q[:, j], t_abs_h, m.ref[j]) * 1e-3
    E = m.error_um(q) * 1e-3
    tip = q + E
    setup = np.zeros(3) if setup_mm is None else setup_mm
    return ts, (np.linalg.norm(tip - c.center - setup, axis=1) - c.radius) * 1e3


def ballbar_rows(rng: np.random.Generator, m: Machine, eff: Effects, c: Circle,
                 t0_h: float, noise: dict[str, float], wrap: bool,
                 runs_out: list[dict[str, Any]] | None = None) -> list[str]:
    """CSV rows of a CCW then CW run of circle ``c`` (header included). ``runs_out``
    receives each run's sampling (direction, arc, step, phase, t0_h, t_start), so the
    same run can be traced again noise-free (``trace_um``)."""
    v = c.feed / 60.0                                 # mm/s
    arc = float(rng.uniform(15, 40))
    step = float(rng.uniform(1.5, 2.5))               # deg per sample
    dt_sample = np.radians(step) * c.radius / v
    rows = ["direction,angle_deg,radial_um,time_s"]
    t_start = 0.0
    for direction in ("ccw", "cw"):
        sweep = 360.0 + 2 * arc
        dur = np.radians(sweep) * c.radius / v
        sgn = 1.0 if direction == "ccw" else -1.0
        th0 = -arc if direction == "ccw" else 360.0 + arc
        phase = float(rng.uniform(0, dt_sample))
        ts, radial = trace_um(m, eff, c, direction, arc, step, phase, t0_h, t_start,
                              noise["setup_mm"])
        if runs_out is not None:
            runs_out.append({"direction": direction, "arc": arc, "step": step, "phase": phase,
                             "t0_h": t0_h, "t_start": t_start})
        # correlated in time (vibration, the bar's own dynamics): a correlation time of
        # 20-150 ms, so the correlation between samples depends on the feed and sampling
        rho = float(np.exp(-dt_sample / noise["corr_s"]))
        radial = radial + noise["bar_um"] + ar1(rng, len(ts), noise["ballbar_um"], rho)
        radial = np.round(radial, 1)                  # 0.1 um resolution
        angles = th0 + sgn * np.degrees(v * ts / c.radius)
        if wrap:
            angles = np.mod(angles, 360.0)
        for ang, r, t in zip(angles, radial, t_start + ts):
            rows.append(f"{direction},{ang:.4f},{r:.1f},{t:.4f}")
        t_start += dur + float(rng.uniform(1.0, 3.0))
    return rows


def laser_rows(rng: np.random.Generator, m: Machine, eff: Effects | None, axis: str,
               targets: np.ndarray, signs: dict[str, float], runs: int, t0_h: float,
               noise: dict[str, float],
               effect_out: list[float] | None = None) -> tuple[list[str], float]:
    """A 6D laser line through the reference point along ``axis`` (docs/formats.md).

    A line through the reference reads sign x (term(p) - term(p0)) per channel
    (docs/formats.md, "6D laser"), plus a beam tilt on the straightness channels,
    an arbitrary zero per channel and white noise. The own term carries the
    effects at the actual (played, scaled) position. Returns rows and the duration (h);
    ``effect_out`` receives the effects' noise-free part of each linear reading (um).
    """
    j = AXES.index(axis)
    lo, hi = targets[0], targets[-1]
    tilt = {"straight_h": rng.normal(0, 80.0), "straight_v": rng.normal(0, 80.0)}   # urad
    zero = {ch: rng.normal(0, 2.0) for ch in CHANNEL_TERMS[axis]}
    feed_mm_s = float(rng.uniform(8, 20))
    dwell = float(rng.uniform(3, 6))
    rows = ["run,direction,target_mm,linear_um,straight_h_um,straight_v_um,pitch_urad,yaw_urad,roll_urad,time_s"]
    t = 0.0
    own = TERMS[j]
    play_um = eff.play_um[axis] if eff else 0.0
    for run in range(1, runs + 1):
        for d in ("+", "-"):
            seq = targets if d == "+" else targets[::-1]
            s = 1.0 if d == "+" else -1.0
            for k, p in enumerate(seq):
                t += (abs(seq[k] - seq[k - 1]) if k else 5.0) / feed_mm_s + dwell
                vals = {}
                for ch, term in CHANNEL_TERMS[axis].items():
                    f = m.motions[axis][term]
                    val = float(f(np.array([p]))[0])
                    if term == own and eff is not None:
                        # the lost motion: the carriage short of the target by half the play
                        e_um = TO_E[axis] * (-s * play_um / 2.0)
                        e_um += float(eff.term_delta(axis, np.array([p]), t0_h + t / 3600.0, m.ref[j])[0])
                        val += e_um
                        if effect_out is not None:
                            effect_out.append(e_um)
                    if ch in tilt:
                        val += tilt[ch] * 1e-3 * (p - lo)
                    sig = noise["laser_um"] if ch == "linear" else (
                        noise["straight_um"] if ch.startswith("straight") else noise["angle_urad"])
                    vals[ch] = signs[ch] * val + zero[ch] + rng.normal(0, sig)
                rows.append(f"{run},{d},{p:.3f},{vals['linear']:.4f},{vals['straight_h']:.4f},"
                            f"{vals['straight_v']:.4f},{vals['pitch']:.4f},{vals['yaw']:.4f},"
                            f"{vals['roll']:.4f},{t:.2f}")
            t += 5.0 / feed_mm_s
    return rows, t / 3600.0


def map_text(axis: str, signs: dict[str, float]) -> str:
    parts = [f'{ch} = "{"+" if signs[ch] > 0 else "-"}{term}"' for ch, term in CHANNEL_TERMS[axis].items()]
    return "{ " + ", ".join(parts) + " }"


def toml_vec(v: Any) -> str:
    return "[" + ", ".join(f"{float(x):.4f}" for x in v) + "]"
