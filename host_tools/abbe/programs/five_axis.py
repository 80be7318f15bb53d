"""Five-axis measurement programs for LinuxCNC's trt sample machines (docs/programs.md,
"Five-axis programs").

* **Sphere probing** (KinematicsOpt style): at each (tilt, C) position of the plan, with
  identity kinematics (``M429``: the joints are the axes, so the probe reads machine
  positions), the program turns the table, goes to a safe height above where the nominal
  kinematics put the sphere, and probes ``n`` points on it: each ``G38.2`` move runs
  along the sphere's normal towards its centre, from ``clearance`` outside the surface
  (stylus radius included) to ``overtravel`` inside it; every trigger is logged
  (``LOGOPEN`` / ``LOG``) as a row of the probing CSV ``abbe fit`` reads
  (docs/formats.md), its ``t_s`` the program's estimated time. Between points the probe
  backs off along the same normal; between positions it retracts to the safe height.
* **R-test path**: tool-centre-point control on (``M428``, the trt kinematics), the
  programmed point held at the sphere's nominal centre while the rotary axes move
  (``G1`` with constant X Y Z and changing A/B, C); the R-test instrument logs.

Units: mm, mm/min, deg, s. Every point is checked against the axes' travel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from abbe.errors import AbbeInputError
from abbe.model.chain import KinematicChain
from abbe.model.five_axis import TrunnionGeometry, nominal_joints

FIVE_AXIS_TESTS: tuple[str, ...] = ("five-axis-probing", "five-axis-rtest")
#: Latitude (deg above the sphere's equator) of the points around the pole: a probe in a
#: vertical spindle reaches the upper cap of the sphere.
LATITUDE_DEG = 20.0


@dataclass(frozen=True)
class ProbingProgram:
    """The parameters of a probing program (mm, mm/min)."""

    sphere_mm: tuple[float, float, float]
    sphere_radius_mm: float
    stylus_radius_mm: float
    positions_deg: np.ndarray  # (M, 2) tilt, C
    n_points: int = 5
    clearance_mm: float = 3.0
    overtravel_mm: float = 2.0
    safe_z_mm: float = 50.0  # above the sphere's top at the position, mm
    probe_feed: float = 100.0
    move_feed: float = 2000.0
    log_file: str = "probe.csv"  # as LOGOPEN names it: LinuxCNC opens a relative path in its
    # configuration folder (the INI file's; its start script changes there)
    fit_reads: str = ""  # where abbe fit reads the log (relative to the machine file), stated


def _n(v: float) -> str:
    s = f"{v:.4f}"
    return "0.0000" if s == "-0.0000" else s


def _check(pos: np.ndarray, travel: dict[str, tuple[float, float]], what: str) -> None:
    for k, a in enumerate("XYZ"):
        lo, hi = travel[a]
        if not lo <= pos[k] <= hi:
            raise AbbeInputError(f"{what}: {a} = {pos[k]:.4f} mm is outside the travel "
                                 f"[{lo}, {hi}] mm", field=f"axes.{a}")


def _check_rot(geom: TrunnionGeometry | KinematicChain, ang: np.ndarray,
               section: str = "rotary") -> None:
    """Every rotary angle within its travel (``section``: the machine file's section
    that declares the travel, for the error's field)."""
    for k, a in enumerate(geom.rotaries):
        lo, hi = geom.travel_deg[a]
        bad = np.flatnonzero((ang[:, k] < lo) | (ang[:, k] > hi))
        if bad.size:
            raise AbbeInputError(f"{a} = {ang[bad[0], k]:.4f} deg is outside its travel "
                                 f"[{lo}, {hi}] deg", field=f"{section}.{a}")


def probe_directions(n_points: int) -> np.ndarray:
    """(n, 3) unit normals of the points, machine frame: the pole, then ``n - 1`` round
    the sphere at :data:`LATITUDE_DEG` (the sphere is round: the same cap at every angle,
    where a probe in a vertical spindle reaches)."""
    k = n_points - 1
    phi = np.arange(k) * 2 * np.pi / k
    lat = math.radians(LATITUDE_DEG)
    return np.vstack([[0.0, 0.0, 1.0], np.column_stack(
        [np.cos(lat) * np.cos(phi), np.cos(lat) * np.sin(phi), np.full(k, np.sin(lat))])])


def probing_gcode(geom: TrunnionGeometry, p: ProbingProgram,
                  travel: dict[str, tuple[float, float]], title: str) -> str:
    """The LinuxCNC program of a sphere-probing campaign (module docstring)."""
    tilt, table = geom.rotaries
    ang = np.asarray(p.positions_deg, dtype=np.float64).reshape(-1, 2)
    _check_rot(geom, ang)
    s = np.asarray(p.sphere_mm, dtype=np.float64)
    centres = nominal_joints(geom, np.repeat(s[None, :], len(ang), 0), ang)
    reach = p.sphere_radius_mm + p.stylus_radius_mm
    dirs_w = probe_directions(p.n_points)
    if ang.shape[0] == 0:
        raise AbbeInputError("a probing plan needs at least one position", field="positions")
    for name, text in (("--log-file", p.log_file), ("file", p.fit_reads)):
        if any(c in text for c in "()\r\n") or (name == "--log-file" and not text.strip()):
            raise AbbeInputError(f"the log file {text!r} cannot go into a G-code comment "
                                 "(LOGOPEN): no '(', ')' or line break, not empty", field=name)
    lines = [f"(abbe: {title})",
             f"(sphere {_n(s[0])} {_n(s[1])} {_n(s[2])} mm, radius {p.sphere_radius_mm} mm, "
             f"stylus {p.stylus_radius_mm} mm; {len(ang)} positions x {p.n_points} points)",
             "(machine coordinates: run with a zero work offset, G54 = 0)",
             "G21 G90 G94 G17 G40",
             "M429 (identity kinematics: the probe reads machine positions)",
             "G43 (the probe is the current tool: its length to the stylus centre)",
             f"(the log: LinuxCNC opens a relative LOGOPEN path in its configuration folder, "
             f"the INI file's; abbe fit reads {p.fit_reads or p.log_file}, the machine file's "
             "probing file)",
             f"(LOGOPEN,{p.log_file})",
             f"(LOG,position,t_s,{tilt.lower()}_deg,c_deg,x_mm,y_mm,z_mm)"]
    # One safe height above the highest place the sphere takes, on the way between the
    # positions too (the joints move linearly: the sphere may pass higher than at either
    # end): the table turns under it.
    steps = np.linspace(0.0, 1.0, 65)[:, None, None]
    sweep = (ang[:-1][None] * (1.0 - steps) + ang[1:][None] * steps).reshape(-1, 2)
    swept = nominal_joints(geom, np.repeat(s[None, :], len(sweep), 0), sweep) if len(sweep) \
        else centres
    top = float(max(np.max(centres[:, 2]), np.max(swept[:, 2]))) + reach + p.safe_z_mm
    t = 0.0
    for m, (a, c) in enumerate(ang):
        ctr = centres[m]
        lines.append(f"(position {m}: {tilt} {_n(a)} C {_n(c)} deg, sphere centre "
                     f"{_n(ctr[0])} {_n(ctr[1])} {_n(ctr[2])} mm)")
        lines.append(f"G0 Z{_n(top)}")
        lines.append(f"G0 {tilt}{_n(a)} {table}{_n(c)}")
        t += 20.0
        # Between points the probe goes round at `local`, just above the sphere's top:
        # every start point is above the centre, so the vertical moves stay outside it.
        local = ctr[2] + reach + p.clearance_mm
        for j, nv in enumerate(dirs_w):  # machine-frame normals: the probe reaches the top
            start = ctr + nv * (reach + p.clearance_mm)
            stop = ctr + nv * (reach - p.overtravel_mm)
            above = np.array([start[0], start[1], local])
            for q, what in ((np.array([start[0], start[1], top]), "above the point"),
                            (above, "over the point"), (start, "approach"),
                            (stop, "probe end")):
                _check(q, travel, f"position {m} point {j}: {what}")
            if j == 0:  # from the safe height, where the table turned
                lines.append(f"G0 X{_n(above[0])} Y{_n(above[1])}")
            lines.append(f"G0 Z{_n(local)}")
            if j > 0:
                lines.append(f"G0 X{_n(above[0])} Y{_n(above[1])}")
            lines.append(f"G1 X{_n(start[0])} Y{_n(start[1])} Z{_n(start[2])} F{p.move_feed:.1f}")
            lines.append(f"G38.2 X{_n(stop[0])} Y{_n(stop[1])} Z{_n(stop[2])} "
                         f"F{p.probe_feed:.1f}")
            t += 4.0
            lines.append(f"(LOG,{m},{t:.1f},{a:.6f},{c:.6f},#5061,#5062,#5063)")
            lines.append(f"G1 X{_n(start[0])} Y{_n(start[1])} Z{_n(start[2])} F{p.move_feed:.1f}")
    lines += [f"G0 Z{_n(top)}", "(LOGCLOSE)", "M2"]
    return "\n".join(lines) + "\n"


def rtest_path(geom: TrunnionGeometry, step_deg: float = 10.0) -> np.ndarray:
    """(M, 2) angles of an R-test path: C a full turn at tilt 0 and at half the tilt's
    travel (each way), then the tilt over 80 % of its travel and back at C = 0."""
    tilt, table = geom.rotaries
    lo, hi = geom.travel_deg[tilt]
    lo_c, hi_c = geom.travel_deg[table]
    c = np.arange(0.0, 360.0 + 1e-9, step_deg)
    if hi_c - lo_c < 360.0:  # a C with stops: its whole travel
        c = np.linspace(lo_c, hi_c, int(np.ceil((hi_c - lo_c) / step_deg)) + 1)
    elif lo_c > 0.0 or hi_c < 360.0:
        c = c + lo_c if hi_c < 360.0 else c
    t_half = 0.5 * (lo if abs(lo) > abs(hi) else hi)
    t_half = float(np.clip(t_half, max(lo, -90.0), min(hi, 90.0)))
    t = np.linspace(max(lo, -90.0) * 0.8, min(hi, 90.0) * 0.8,
                    int(np.ceil((min(hi, 90.0) - max(lo, -90.0)) * 0.8 / step_deg)) + 1)
    parts = [np.column_stack([np.zeros(c.size), c]),
             np.column_stack([np.full(c.size, t_half), c[::-1]]),
             np.column_stack([t, np.full(t.size, c[0])]),
             np.column_stack([t[::-1], np.full(t.size, c[0])])]
    return np.vstack(parts)


def rtest_gcode(geom: TrunnionGeometry, sphere_mm: tuple[float, float, float],
                path_deg: np.ndarray, travel: dict[str, tuple[float, float]], title: str,
                feed_deg_min: float = 1000.0, dwell_s: float = 0.0, safe_z_mm: float = 50.0) -> str:
    """The LinuxCNC program of an R-test path under tool-centre-point control (M428): the
    approach from ``safe_z_mm`` above the ball, a stop to fit the nest, then the path."""
    tilt, table = geom.rotaries
    ang = np.asarray(path_deg, dtype=np.float64).reshape(-1, 2)
    _check_rot(geom, ang)
    s = np.asarray(sphere_mm, dtype=np.float64)
    joints = nominal_joints(geom, np.repeat(s[None, :], len(ang), 0), ang)
    for i, q in enumerate(joints):  # what the kinematics will ask of the linear axes
        _check(q, travel, f"R-test step {i} ({tilt} {ang[i, 0]:.3f}, C {ang[i, 1]:.3f} deg)")
    safe = float(joints[0, 2]) + safe_z_mm
    _check(np.array([joints[0, 0], joints[0, 1], safe]), travel, "R-test approach")
    lines = [f"(abbe: {title})",
             f"(R-test: the sphere's nominal centre {_n(s[0])} {_n(s[1])} {_n(s[2])} mm held "
             "under tool-centre-point control; the instrument logs)",
             "G21 G90 G94 G17 G40",
             "M429 (identity kinematics for the approach)",
             "G43 (the nest is the current tool: its length to the ball's nominal centre)",
             f"G0 Z{_n(safe)}",
             f"G0 {tilt}{_n(ang[0, 0])} {table}{_n(ang[0, 1])}",
             f"G0 X{_n(joints[0, 0])} Y{_n(joints[0, 1])}",
             f"G1 Z{_n(joints[0, 2])} F{feed_deg_min:.1f}",
             "M0 (fit the R-test nest on the sphere, zero the sensors)",
             "M428 (tool-centre-point control: xyz%sc-trt kinematics)" % tilt.lower(),
             f"G1 X{_n(s[0])} Y{_n(s[1])} Z{_n(s[2])} F{feed_deg_min:.1f}"]
    for a, c in ang[1:]:
        lines.append(f"G1 {tilt}{_n(a)} {table}{_n(c)}")
        if dwell_s:
            lines.append(f"G4 P{dwell_s:.3f}")
    lines += ["M0 (lift the nest off the ball)", "M429", f"G0 Z{_n(safe)}", "M2"]
    return "\n".join(lines) + "\n"
