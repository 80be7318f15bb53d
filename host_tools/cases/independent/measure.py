"""Instruments of the independent generator: 6D laser ISO 230-2 cycles, a time-sampled
ballbar, and one-axis positioning runs (the ESS ``.dat`` family).

Laser (ISO 230-2, notes.md §3): per run a + pass over the targets ascending and a -
pass descending, each target approached from the pass direction after an overrun
at the ends; a reading at the end of the dwell; the readings relative to the first
one; repeatability as a per-visit scatter of the carriage along the axis; beam
misalignment adds a line to the straightness channels.

Ballbar (ISO 230-4, notes.md §4): the commanded angle runs from -arc to 360 + arc
(CCW), pause, back (CW), at the programmed feed; each axis follows with its servo
(delay or first-order lag, integrated on a fine time grid from rest), its lost
motion state is taken along the *actual* motion; samples every ``step_deg`` of
commanded angle *in time*, starting at a random phase (samples need not fall on
the axis reversals); the bar reads |p + E - (c + set-up offset)| - R, plus white
or slightly correlated noise.

Units: mm, um, urad, s, ms.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from cases.independent.chain import carriage_reading, tool_error_um
from cases.independent.physics import AXES, OWN_TERM, Machine, lost_motion_state

PLANE_AXES = {"XY": (0, 1), "YZ": (1, 2), "ZX": (2, 0)}
CHANNELS = ("linear", "straight_h", "straight_v", "pitch", "yaw", "roll")


@dataclass
class LaserPlan:
    axis: str
    line_mm: tuple[float, float, float]      # a point of the line (the other coordinates)
    targets_mm: np.ndarray                   # ascending
    runs: int = 5
    feed_mm_min: float = 1000.0
    dwell_s: float = 4.0
    overrun_mm: float = 4.0
    #: channel -> "+term" / "-term" (reading = sign x term)
    map: dict[str, str] | None = None
    misalignment_urad: tuple[float, float] = (0.0, 0.0)
    noise_lin_um: float = 0.1
    noise_str_um: float = 0.15
    noise_ang_urad: float = 0.3
    repeat_um: float = 0.1


@dataclass
class LaserRecord:
    run: np.ndarray
    direction: np.ndarray
    target_mm: np.ndarray
    values: dict[str, np.ndarray]
    time_s: np.ndarray
    temp_c: np.ndarray | None
    duration_s: float


def _schedule(targets: np.ndarray, runs: int, v: float, dwell: float, over: float):
    """Path (positions, times) and the reading index of each (run, dir, target)."""
    lo, hi = float(targets[0]), float(targets[-1])
    pp, tt = [lo - over], [0.0]
    rows = []

    def go(p: float) -> None:
        if p != pp[-1]:
            tt.append(tt[-1] + abs(p - pp[-1]) / v)
            pp.append(p)
    for r in range(1, runs + 1):
        for d, seq, end in (("+", targets, hi + over), ("-", targets[::-1], lo - over)):
            for p in seq:
                go(float(p))
                tt.append(tt[-1] + dwell)
                pp.append(float(p))
                rows.append((r, d, float(p), tt[-1], len(pp) - 1))
            go(end)
    return np.array(pp), np.array(tt), rows


def measure_laser(m: Machine, plan: LaserPlan, t0_s: float, rng: np.random.Generator
                  ) -> LaserRecord:
    """One laser line's readings in the instrument's units and signs."""
    j = AXES.index(plan.axis)
    pp, tt, rows = _schedule(np.asarray(plan.targets_mm), plan.runs, plan.feed_mm_min / 60.0,
                             plan.dwell_s, plan.overrun_mm)
    idx = np.array([r[4] for r in rows])
    n = idx.size
    lm = m.effects.lost_motion.get(plan.axis)
    state = np.zeros((n, 3))
    if lm is not None:
        dense, at = _densify(pp, max(min(lm.takeup_up_mm, lm.takeup_down_mm,
                                         lm.b_um * 1e-3 if lm.shape == "play" else 1.0) / 20.0, 1e-4))
        state[:, j] = lost_motion_state(dense, lm, -1.0)[at][idx]
    pos = np.tile(np.asarray(plan.line_mm, dtype=np.float64), (n, 1))
    pos[:, j] = pp[idx]
    t_camp = t0_s + tt[idx]
    jit = np.zeros((n, 3))
    jit[:, j] = rng.normal(0.0, plan.repeat_um, n)
    dev, ang = carriage_reading(m, plan.axis, pos, state, t_camp, jit)
    dev -= dev[0]
    ang -= ang[0]
    along = pos[:, j] - pos[0, j]
    mp = plan.map or default_map(plan.axis)
    vals: dict[str, np.ndarray] = {}
    mis = {"straight_h": plan.misalignment_urad[0], "straight_v": plan.misalignment_urad[1]}
    for ch in CHANNELS:
        sgn = 1.0 if mp[ch][0] == "+" else -1.0
        term = mp[ch][1:]
        comp = "xyz".index(term[1])
        if term[0] == "d":
            v = sgn * dev[:, comp]
            if ch in mis:
                v = v + mis[ch] * along * 1e-3
            sd = plan.noise_lin_um if ch == "linear" else plan.noise_str_um
        else:
            v = sgn * ang[:, comp]
            sd = plan.noise_ang_urad
        vals[ch] = v + rng.normal(0.0, sd, n)
    th = m.effects.thermal
    temp = None
    if th is not None and th.record_temp:
        temp = th.temperature(t_camp) + rng.normal(0.0, th.sensor_k, n)
    return LaserRecord(run=np.array([r[0] for r in rows]), direction=np.array([r[1] for r in rows]),
                       target_mm=np.array([r[2] for r in rows]), values=vals,
                       time_s=tt[idx] - tt[idx][0], temp_c=temp, duration_s=float(tt[-1]))


def default_map(axis: str) -> dict[str, str]:
    own = OWN_TERM[axis]
    others = [t for t in ("dx", "dy", "dz") if t != own]
    rot = {"X": ("ex", "ey", "ez"), "Y": ("ey", "ex", "ez"), "Z": ("ez", "ex", "ey")}[axis]
    return {"linear": "+" + own, "straight_h": "+" + others[0], "straight_v": "+" + others[1],
            "roll": "+" + rot[0], "pitch": "-" + rot[1], "yaw": "-" + rot[2]}


def _densify(path: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """A polyline resampled every ``step`` mm; index of each original vertex."""
    pts, at = [path[:1]], [0]
    k = 0
    for a, b in zip(path[:-1], path[1:]):
        m = max(1, int(math.ceil(abs(b - a) / step)))
        seg = np.linspace(a, b, m + 1)[1:]
        pts.append(seg)
        k += seg.size
        at.append(k)
    return np.concatenate(pts), np.array(at)


@dataclass
class CirclePlan:
    name: str
    plane: str
    center_mm: tuple[float, float, float]
    radius_mm: float
    feed_mm_min: float
    step_deg: float = 1.0
    arc_deg: float = 30.0
    pause_s: float = 1.5
    setup_um: tuple[float, float] = (0.0, 0.0)
    noise_um: float = 0.15
    noise_rho: float = 0.0


@dataclass
class CircleRecord:
    direction: np.ndarray
    angle_deg: np.ndarray
    radial_um: np.ndarray
    time_s: np.ndarray
    temp_c: np.ndarray | None
    duration_s: float


def _command(plan: CirclePlan, t: np.ndarray) -> np.ndarray:
    """Commanded angle (deg) at local time t: CCW, pause, CW; held outside."""
    om = math.degrees(plan.feed_mm_min / 60.0 / plan.radius_mm)
    a = plan.arc_deg
    t1 = (360.0 + 2 * a) / om
    t2 = t1 + plan.pause_s
    return np.interp(t, [0.0, t1, t2, t2 + t1], [-a, 360.0 + a, 360.0 + a, -a])


def measure_circle(m: Machine, plan: CirclePlan, t0_s: float, rng: np.random.Generator
                   ) -> CircleRecord:
    """One ballbar test (CCW then CW) on the machine."""
    om = math.degrees(plan.feed_mm_min / 60.0 / plan.radius_mm)
    a = plan.arc_deg
    t_run = (360.0 + 2 * a) / om
    t_end = 2 * t_run + plan.pause_s
    a_i, b_i = PLANE_AXES[plan.plane]
    c = np.asarray(plan.center_mm, dtype=np.float64)
    v = plan.feed_mm_min / 60.0
    lms = [m.effects.lost_motion.get(ax) for ax in AXES]
    L = [(lm.b_um * 1e-3 if lm.shape == "play" else min(lm.takeup_up_mm, lm.takeup_down_mm))
         for lm in lms if lm is not None]
    dt = min(1e-3, (min(L) / 25.0 / v) if L else 1e-3)
    n = int(min(math.ceil(t_end / dt), 3_000_000))
    grid = np.linspace(0.0, t_end, n + 1)

    def cmd_pos(t: np.ndarray) -> np.ndarray:
        th = np.radians(_command(plan, t))
        p = np.tile(c, (t.size, 1))
        p[:, a_i] += plan.radius_mm * np.cos(th)
        p[:, b_i] += plan.radius_mm * np.sin(th)
        return p
    act = _follow(m, cmd_pos, grid)
    # samples in time, random phase
    dt_s = plan.step_deg / om
    ph = rng.uniform(0.0, dt_s)
    ts_ccw = np.arange(ph, t_run, dt_s)
    ts_cw = np.arange(t_run + plan.pause_s + ph, t_end, dt_s)
    ts = np.concatenate([ts_ccw, ts_cw])
    k = np.searchsorted(grid, ts)
    p = np.empty((ts.size, 3))
    for j in range(3):
        p[:, j] = np.interp(ts, grid, act[:, j])
    state = None
    if any(lm is not None for lm in lms):
        state = np.zeros((ts.size, 3))
        for j, lm in enumerate(lms):
            if lm is None:
                continue
            s0 = float(rng.choice([-1.0, 1.0]))
            s_grid = lost_motion_state(act[:, j], lm, s0)
            state[:, j] = np.interp(ts, grid, s_grid)
    del k
    e = tool_error_um(m, p, state, t0_s + ts)
    cen = c.copy()
    cen[a_i] += plan.setup_um[0] * 1e-3
    cen[b_i] += plan.setup_um[1] * 1e-3
    radial = (np.linalg.norm(p + e * 1e-3 - cen, axis=1) - plan.radius_mm) * 1e3
    w = rng.normal(0.0, plan.noise_um, ts.size)
    if plan.noise_rho > 0:
        for i in range(1, w.size):
            w[i] = plan.noise_rho * w[i - 1] + math.sqrt(1 - plan.noise_rho ** 2) * w[i]
    radial = radial + w
    ang = _command(plan, ts)
    th = m.effects.thermal
    temp = None
    if th is not None and th.record_temp:
        temp = th.temperature(t0_s + ts) + rng.normal(0.0, th.sensor_k, ts.size)
    d = np.where(ts < t_run, "ccw", "cw")
    return CircleRecord(direction=d, angle_deg=ang, radial_um=radial, time_s=ts, temp_c=temp,
                        duration_s=t_end)


def _follow(m: Machine, cmd_pos, grid: np.ndarray) -> np.ndarray:
    """Actual axis positions (G, 3) on the time grid under the servo model."""
    u = cmd_pos(grid)
    sv = m.effects.servo
    if sv is None:
        return u
    out = u.copy()
    for j in range(3):
        tau = sv.tau_ms[j] * 1e-3
        if tau <= 0:
            continue
        if sv.model == "delay":
            out[:, j] = cmd_pos(np.maximum(grid - tau, 0.0))[:, j]
            continue
        # first-order lag tau x' = u - x, exact for a command linear between the (uniform)
        # grid points: x[i+1] = e x[i] + f[i], from rest at the start point
        h = float(grid[1] - grid[0])
        e = math.exp(-h / tau)
        uj = u[:, j]
        slope = np.diff(uj) / h
        f = uj[1:] - tau * slope - e * (uj[:-1] - tau * slope)
        x = np.empty(grid.size)
        x[0] = uj[0]
        x[1:], _ = lfilter([1.0], [1.0, -e], f, zi=[e * uj[0]])
        out[:, j] = x
    return out


def positioning_runs(m: Machine, axis: str, targets: np.ndarray, cycles: int, rng: np.random.Generator,
                     noise_um: float, drift_um_per_cycle: float = 0.0,
                     drift_mid_um_per_cycle: float = 0.0, overrun_mm: float = 2.0,
                     outliers: list[tuple[int, str, int, float]] | None = None,
                     noisy_cycle: tuple[int, float] | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """ISO 230-2 positioning runs of one axis as (cycles, T) deviations (um) forward and
    backward: the own positioning term + lost motion + a drift growing with the
    fractional cycle index (uniform ``drift_um_per_cycle`` and one concentrated at
    mid-travel ``drift_mid_um_per_cycle``) + repeatability; ``outliers`` (cycle,
    "fwd"/"bwd", target index, um) added as is; ``noisy_cycle`` (cycle, noise factor)."""
    j = AXES.index(axis)
    T = targets.size
    lo, hi = m.travel[axis]
    own = OWN_TERM[axis]
    g = m.geometric(axis, own, targets)
    lm = m.effects.lost_motion.get(axis)
    fw = np.zeros((cycles, T))
    bw = np.zeros((cycles, T))
    mid = 0.5 * (targets[0] + targets[-1])
    width = 0.25 * (targets[-1] - targets[0])
    bump = np.exp(-0.5 * ((targets - mid) / width) ** 2)
    for c in range(cycles):
        for d, arr in (("fwd", fw), ("bwd", bw)):
            s = 1.0 if d == "fwd" else -1.0
            lmv = 0.0 if lm is None else -s * lm.b_at(targets, (lo, hi)) / 2.0
            order = np.arange(T) if d == "fwd" else np.arange(T)[::-1]
            frac = c + (0.5 if d == "bwd" else 0.0) + (order.argsort() + 0.5) / (2.0 * T)
            drift = drift_um_per_cycle * frac + drift_mid_um_per_cycle * frac * bump
            sd = noise_um * (noisy_cycle[1] if noisy_cycle and noisy_cycle[0] == c + 1 else 1.0)
            arr[c] = g + lmv + drift + rng.normal(0.0, sd, T)
    for (cyc, d, ti, um) in outliers or []:
        (fw if d == "fwd" else bw)[cyc - 1, ti] += um
    del j
    return fw, bw
