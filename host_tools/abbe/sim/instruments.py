"""Virtual instruments: a 6D laser interferometer and a ballbar on the virtual machine.

6D laser (one line per axis, ISO 230-2 cycle): the receiver is fixed to the
moving carriage -- for X and Y on the table at the table point that is under
the spindle reference point when the machine is at the line's point with the
line's own coordinate at the reference point (so a line through the reference
point reads the axis' terms directly, an offset line picks up the Abbe terms
eps x offset); for Z on the spindle at the spindle reference point, the laser
head standing on the table. The laser head (beam) is aligned with the axis up to
``misalignment_urad`` (a straightness slope, removed by Eq. 1 detrending). Every
channel is zeroed at the first reading (run 1, + pass, first target). Reading of
a channel mapped to "+/-term": sign x the component of the receiver's position
deviation (linear terms, um) or rotation vector (angular terms, urad) along that
term's axis, in the instrument frame. Noise per reading; repeatability scatter
per target visit on the moving axis; thermal drift with campaign time.

Ballbar: the machine follows the commanded circle (with feed-in / feed-out arcs)
at the programmed feed; each axis lags its command by its servo lag; backlash
state follows the actual axis motion; the ballbar reads
``|p + E(p) - (centre + setup offset)| - R`` at the sample times, p the actual
axis positions, E the exact tool-to-workpiece error.
"""

from __future__ import annotations

import io
import math
import zlib
from dataclasses import dataclass

import numpy as np

from abbe.formats.ballbar_csv import BallbarTrace
from abbe.model.backlash import backlash_state
from abbe.model.geometry import CircleTest, circle_points, tangent_units
from abbe.model.table import LINEAR_TERMS
from abbe.sim.spec import CHANNELS, LaserLinePlan, NoiseSpec
from abbe.sim.virtual_machine import VirtualMachine, rotation_matrices

LASER_COLUMNS = ("run", "direction", "target_mm", "linear_um", "straight_h_um", "straight_v_um",
                 "pitch_urad", "yaw_urad", "roll_urad", "time_s")
_CH_COL = {"linear": "linear_um", "straight_h": "straight_h_um", "straight_v": "straight_v_um",
           "pitch": "pitch_urad", "yaw": "yaw_urad", "roll": "roll_urad"}


def rng_for(seed: int, kind: str, name: str) -> np.random.Generator:
    """Independent, reproducible random stream per test (PCG64 seeded by seed, kind, name)."""
    return np.random.default_rng([int(seed), zlib.crc32(kind.encode()), zlib.crc32(name.encode())])


@dataclass
class LaserRun:
    """Simulated readings of one laser line (rows in measuring order).

    run (N,), direction (N,) '+'/'-', target_mm (N,), channels[ch] (N,) in the
    instrument's units and signs, time_s (N,) since the line's start, temp_c (N,)
    or None; duration_s of the test; pos_mm (N, 3) commanded positions;
    dir_state (N, 3).
    """

    plan: LaserLinePlan
    run: np.ndarray
    direction: np.ndarray
    target_mm: np.ndarray
    channels: dict[str, np.ndarray]
    time_s: np.ndarray
    temp_c: np.ndarray | None
    duration_s: float
    pos_mm: np.ndarray
    dir_state: np.ndarray

    def to_csv(self) -> str:
        """Laser CSV text (docs/formats.md)."""
        cols = list(LASER_COLUMNS) + (["temp_c"] if self.temp_c is not None else [])
        out = io.StringIO()
        out.write(",".join(cols) + "\n")
        for i in range(self.run.size):
            cells = [str(int(self.run[i])), str(self.direction[i]), f"{self.target_mm[i]:.3f}"]
            cells += [f"{self.channels[ch][i]:.4f}" for ch in
                      ("linear", "straight_h", "straight_v", "pitch", "yaw", "roll")]
            cells.append(f"{self.time_s[i]:.2f}")
            if self.temp_c is not None:
                cells.append(f"{self.temp_c[i]:.3f}")
            out.write(",".join(cells) + "\n")
        return out.getvalue()


def _laser_schedule(plan: LaserLinePlan) -> tuple[np.ndarray, ...]:
    """ISO 230-2 cycle on the line's axis: returns path positions/times (waypoints) and,
    per reading, its run, direction, target, time and index into the path."""
    tg = plan.targets_mm()
    lo, hi = float(tg[0]), float(tg[-1])
    v = plan.feed_mm_min / 60.0
    path_p = [lo - plan.overrun_mm]
    path_t = [0.0]

    def move(p: float) -> None:
        if p != path_p[-1]:
            path_t.append(path_t[-1] + abs(p - path_p[-1]) / v)
            path_p.append(p)

    runs, dirs, targets, times, idx = [], [], [], [], []
    for run in range(1, plan.runs + 1):
        for d, seq, over in (("+", tg, hi + plan.overrun_mm), ("-", tg[::-1], lo - plan.overrun_mm)):
            for p in seq:
                move(float(p))
                path_t.append(path_t[-1] + plan.dwell_s)  # dwell, reading at its end
                path_p.append(float(p))
                runs.append(run)
                dirs.append(d)
                targets.append(float(p))
                times.append(path_t[-1])
                idx.append(len(path_p) - 1)
            if not (run == plan.runs and d == "-"):
                move(over)
    return (np.array(path_p), np.array(path_t), np.array(runs), np.array(dirs),
            np.array(targets), np.array(times), np.array(idx))


def simulate_laser_line(vm: VirtualMachine, plan: LaserLinePlan, start_time_s: float,
                        noise: NoiseSpec, rng: np.random.Generator) -> LaserRun:
    """Simulate the 6D laser runs of one line (see module doc). Times in s: the line
    starts at campaign time ``start_time_s``; thermal drift uses campaign time."""
    j = plan.j
    truth = vm.truth
    e = truth.effects
    path_p, path_t, runs, dirs, targets, times, idx = _laser_schedule(plan)
    n = targets.size
    # Backlash state of the moving axis along its path (arrives at the park point moving -).
    s_axis = backlash_state(path_p, e.backlash_takeup_mm[j], -1.0)[idx]
    dir_state = np.ones((n, 3))
    dir_state[:, j] = s_axis
    pos = np.tile(np.asarray(plan.start_mm, dtype=np.float64), (n, 1))
    pos[:, j] = targets
    jitter = np.zeros((n, 3))
    jitter[:, j] = rng.normal(0.0, 1.0, n) * noise.repeatability_um[j]
    t_camp = start_time_s + times
    rel0 = np.asarray(plan.start_mm, dtype=np.float64) - vm.ref
    rel0[j] = 0.0
    if plan.axis in ("X", "Y"):
        point = np.array([-rel0[0], -rel0[1], rel0[2]])
    else:
        point = np.zeros(3)
    dev_um, rot_urad = vm.carriage_pose(plan.axis, pos, point, dir_state, t_camp, jitter)
    # Displacement from the datum (first reading) in mm, then into the instrument frame.
    disp = (pos - pos[0]) + (dev_um - dev_um[0]) * 1e-3
    pm = plan.parsed_map()
    beam = np.zeros(3)
    beam[j] = 1.0
    tilt = np.zeros(3)
    for ch, a in zip(("straight_h", "straight_v"), plan.misalignment_urad):
        k = LINEAR_TERMS.index(pm[ch][1])
        tilt[k] += a
    r_m = rotation_matrices(np.cross(beam, tilt)[None, :])[0]
    disp_i = disp @ r_m  # = R_m^T disp per row
    lin_um = (disp_i - (pos - pos[0])) * 1e3
    ang_urad = (rot_urad - rot_urad[0]) @ r_m
    sig = {"linear": noise.laser_linear_um, "straight_h": noise.laser_straightness_um,
           "straight_v": noise.laser_straightness_um, "pitch": noise.laser_angle_urad,
           "yaw": noise.laser_angle_urad, "roll": noise.laser_angle_urad}
    channels: dict[str, np.ndarray] = {}
    for ch in CHANNELS:
        sign, term = pm[ch]
        if term in LINEAR_TERMS:
            val = lin_um[:, LINEAR_TERMS.index(term)]
        else:
            val = ang_urad[:, ("ex", "ey", "ez").index(term)]
        channels[ch] = sign * val + rng.normal(0.0, 1.0, n) * sig[ch]
    temp = None
    if e.thermal_on():
        temp = truth.temperature_c(t_camp) + rng.normal(0.0, 1.0, n) * noise.temp_sensor_k
    return LaserRun(plan=plan, run=runs, direction=dirs, target_mm=targets, channels=channels,
                    time_s=times, temp_c=temp, duration_s=float(times[-1]), pos_mm=pos,
                    dir_state=dir_state)


@dataclass
class CircleTimeline:
    """Commanded motion of a ballbar test: CCW run, pause, CW run (local time, s)."""

    test: CircleTest
    t_ccw_end: float
    t_cw_start: float
    t_end: float

    @classmethod
    def of(cls, test: CircleTest) -> "CircleTimeline":
        span = 360.0 + 2.0 * test.feed_arc_deg
        t1 = span / test.omega_deg_s
        return cls(test, t1, t1 + test.pause_s, 2.0 * t1 + test.pause_s)

    def theta(self, t: np.ndarray) -> np.ndarray:
        """Commanded angle (deg) at local time t (held before start / after end)."""
        a = self.test.feed_arc_deg
        return np.interp(t, [0.0, self.t_ccw_end, self.t_cw_start, self.t_end],
                         [-a, 360.0 + a, 360.0 + a, -a])

    def theta_rate_sign(self, t: np.ndarray) -> np.ndarray:
        """+1 during the CCW run, -1 during the CW run, 0 at rest."""
        t = np.asarray(t, dtype=np.float64)
        return np.where((t >= 0) & (t < self.t_ccw_end), 1.0,
                        np.where((t >= self.t_cw_start) & (t < self.t_end), -1.0, 0.0))

    def samples(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Recorded samples: direction, angle (deg), local time (s)."""
        t = self.test
        a = t.feed_arc_deg
        k = int(math.floor((360.0 + 2 * a) / t.sample_deg + 1e-9))
        ang_ccw = -a + t.sample_deg * np.arange(k + 1)
        ang_cw = 360.0 + a - t.sample_deg * np.arange(k + 1)
        tm_ccw = (ang_ccw + a) / t.omega_deg_s
        tm_cw = self.t_cw_start + (360.0 + a - ang_cw) / t.omega_deg_s
        dirs = np.array(["ccw"] * ang_ccw.size + ["cw"] * ang_cw.size)
        return dirs, np.concatenate([ang_ccw, ang_cw]), np.concatenate([tm_ccw, tm_cw])


def _actual_positions(vm: VirtualMachine, tl: CircleTimeline, t: np.ndarray,
                      corr: np.ndarray | None, cycle_hz: float) -> np.ndarray:
    """Actual axis positions (N, 3) mm at local times t: command (plus held correction)
    delayed by each axis' servo lag."""
    lags = np.asarray(vm.truth.effects.servo_lag_ms) * 1e-3
    out = np.empty((t.size, 3))
    for j in range(3):
        tj = t - lags[j]
        out[:, j] = circle_points(tl.test, tl.theta(tj))[:, j]
        if corr is not None:
            k = np.floor(tj * cycle_hz + 1e-9).astype(np.int64)
            ok = k >= 0
            kk = np.clip(k, 0, corr.shape[0] - 1)
            out[:, j] += np.where(ok, corr[kk, j], 0.0)
    return out


def simulate_circle(vm: VirtualMachine, test: CircleTest, start_time_s: float,
                     noise_um: float, rng: np.random.Generator,
                     corr: np.ndarray | None = None, cycle_hz: float = 1000.0,
                     temp_sensor_k: float = 0.0) -> BallbarTrace:
    """Ballbar trace of ``test`` (see module doc); with thermal drift on, the machine
    temperature of each sample (+ sensor noise, drawn after the radial noise) as temp_c."""
    tl = CircleTimeline.of(test)
    dirs, ang, tm = tl.samples()
    e = vm.truth.effects
    # Fine time grid for the backlash state (resolves the take-up along the path).
    if e.backlash_on():
        step_mm = max(min(e.backlash_takeup_mm) / 20.0, 1e-4)
        dt = min(step_mm / (test.feed_mm_min / 60.0), test.sample_deg / test.omega_deg_s)
        n = int(min(math.ceil(tl.t_end / dt), 400_000))
        grid = np.union1d(np.linspace(0.0, tl.t_end, n + 1), tm)
        p_grid = _actual_positions(vm, tl, grid, corr, cycle_hz)
        at = np.searchsorted(grid, tm)
        # Initial state: each axis as if it had arrived moving the way it starts.
        v0 = tangent_units(test.plane, np.array([-test.feed_arc_deg]))[0]
        s = np.empty((tm.size, 3))
        for j in range(3):
            s0 = 1.0 if v0[j] >= 0 else -1.0
            s[:, j] = backlash_state(p_grid[:, j], e.backlash_takeup_mm[j], s0)[at]
        p = p_grid[at]
    else:
        p = _actual_positions(vm, tl, tm, corr, cycle_hz)
        s = None
    err = vm.tool_error_um(p, s, start_time_s + tm)
    centre = np.asarray(test.center_mm) + np.asarray(test.setup_offset_um) * 1e-3
    tool = p + err * 1e-3
    radial = (np.linalg.norm(tool - centre, axis=1) - test.radius_mm) * 1e3
    radial = radial + rng.normal(0.0, 1.0, radial.size) * noise_um
    temp = None
    if e.thermal_on():
        temp = vm.truth.temperature_c(start_time_s + tm) + rng.normal(0.0, 1.0, tm.size) * temp_sensor_k
    return BallbarTrace(direction=dirs, angle_deg=ang, radial_um=radial, time_s=tm, temp_c=temp)


def simulate_ballbar(vm: VirtualMachine, test: CircleTest, start_time_s: float = 0.0,
                     noise_um: float = 0.0, rng: np.random.Generator | None = None,
                     temp_sensor_k: float = 0.0) -> BallbarTrace:
    """Simulated ballbar trace (CCW then CW, feed arcs included) of ``test``, starting
    at campaign time ``start_time_s`` (with thermal drift on: temp_c per sample)."""
    rng = rng if rng is not None else np.random.default_rng(0)
    return simulate_circle(vm, test, start_time_s, noise_um, rng, temp_sensor_k=temp_sensor_k)


def circle_duration_s(test: CircleTest) -> float:
    """Duration of a ballbar test (both runs, feed arcs and the pause), s."""
    return CircleTimeline.of(test).t_end
__all__ = ["LaserRun", "simulate_laser_line", "simulate_ballbar", "simulate_circle",
           "circle_duration_s", "rng_for", "CircleTimeline"]
