"""Five-axis measurement programs for any kinematic chain: LinuxCNC's head-head
(5axiskins, bridgemill), head-table (maxkins, max5) and dual-rotary-table
(xyzab_tdr_kins) sample machines (docs/programs.md, "Five-axis programs").

The trunnion programs (:mod:`abbe.programs.five_axis`) with the chain's kinematics:

* **Sphere probing**: with identity kinematics (the probe reads machine positions) the
  rotary axes go to each position of the plan, the probe to a safe height above where
  the nominal chain puts the stylus on the sphere, and ``n`` points are probed along the
  sphere's normals (machine frame: the pole, then round at 20 deg latitude) from
  ``clearance`` outside to ``overtravel`` inside; a tool-side axis carries the stylus
  (``tip_mm``: the stylus centre relative to the controlled point at zero angles), and
  the linear axes move it without turning it, so a G38.2 straight line in the joints is
  a straight line of the stylus. Each trigger is logged as a row of the probing CSV
  (``position,t_s,<r1>_deg,<r2>_deg,x_mm,y_mm,z_mm``, the chain's rotary axes in
  alphabetical order) ``abbe fit`` reads.
* **R-test path**: tool-centre-point control on, the programmed point held at the
  sphere's nominal centre while the rotary axes move.

Identity and tool-centre-point modes: 5axiskins (bridgemill) and xyzab_tdr_kins switch
with ``M429`` (identity) / ``M428`` (TCP) as their samples' remaps define them; maxkins
has one mode (TCP): its probing program runs under the sample's trivkins configuration
(max5triv.ini), its R-test under max5kins.ini, as the programs' first lines say.

Units: mm, mm/min, deg, s. Every point is checked against the axes' travel.
"""

from __future__ import annotations

import numpy as np

from abbe.errors import AbbeInputError
from abbe.model.chain import KinematicChain, nominal_joints
from abbe.programs.five_axis import ProbingProgram, _check, _check_rot, _n, probe_directions

#: (identity, TCP) commands by chain name; None: the configuration decides (maxkins).
MODES: dict[str, tuple[str | None, str | None]] = {
    "5axiskins": ("M429", "M428"), "xyzab-tdr": ("M429", "M428"), "maxkins": (None, None)}
CONFIG_NOTE = {"maxkins": ("(maxkins has no identity mode: run this program under the "
                           "trivkins configuration, max5triv.ini of the max5 sample)",
                           "(maxkins is always tool-centre-point: run this program under "
                           "max5kins.ini)")}


def _modes(chain: KinematicChain) -> tuple[str | None, str | None]:
    return MODES.get(chain.name, ("M429", "M428"))


def _rot_words(chain: KinematicChain, ang: np.ndarray) -> str:
    r1, r2 = chain.rotaries
    return f"{r1}{_n(ang[0])} {r2}{_n(ang[1])}"


def chain_probing_gcode(chain: KinematicChain, p: ProbingProgram,
                        tip_mm: tuple[float, float, float],
                        travel: dict[str, tuple[float, float]], title: str) -> str:
    """The LinuxCNC program of a sphere-probing campaign on ``chain`` (module docstring)."""
    r1, r2 = chain.rotaries
    ang = np.asarray(p.positions_deg, dtype=np.float64).reshape(-1, 2)
    if ang.shape[0] == 0:
        raise AbbeInputError("a probing plan needs at least one position", field="positions")
    _check_rot(chain, ang, section="chain")
    for name, text in (("--log-file", p.log_file), ("file", p.fit_reads)):
        if any(c in text for c in "()\r\n") or (name == "--log-file" and not text.strip()):
            raise AbbeInputError(f"the log file {text!r} cannot go into a G-code comment "
                                 "(LOGOPEN): no '(', ')' or line break, not empty", field=name)
    s = np.asarray(p.sphere_mm, dtype=np.float64)
    tip = np.asarray(tip_mm, dtype=np.float64)
    centres = nominal_joints(chain, np.repeat(s[None, :], len(ang), 0), ang, tip)
    reach = p.sphere_radius_mm + p.stylus_radius_mm
    dirs = probe_directions(p.n_points)
    ident, _tcp = _modes(chain)
    lines = [f"(abbe: {title})"]
    if chain.name in CONFIG_NOTE:
        lines.append(CONFIG_NOTE[chain.name][0])
    lines += [f"(chain {chain.name}, {chain.kind}: sphere {_n(s[0])} {_n(s[1])} {_n(s[2])} mm, "
              f"radius {p.sphere_radius_mm} mm, stylus {p.stylus_radius_mm} mm at "
              f"{_n(tip[0])} {_n(tip[1])} {_n(tip[2])} mm from the controlled point; "
              f"{len(ang)} positions x {p.n_points} points)",
              "(machine coordinates: run with a zero work offset, G54 = 0)",
              "G21 G90 G94 G17 G40"]
    if ident:
        lines.append(f"{ident} (identity kinematics: the probe reads machine positions)")
    lines += ["G43 (the probe is the current tool: its length to the stylus centre)",
              f"(the log: LinuxCNC opens a relative LOGOPEN path in its configuration folder; "
              f"abbe fit reads {p.fit_reads or p.log_file}, the machine file's probing file)",
              f"(LOGOPEN,{p.log_file})",
              f"(LOG,position,t_s,{r1.lower()}_deg,{r2.lower()}_deg,x_mm,y_mm,z_mm)"]
    # One safe height above the highest place the stylus centre takes, on the way between
    # the positions too (the joints move linearly, the rotaries swing the sphere or the
    # stylus in between).
    steps = np.linspace(0.0, 1.0, 65)[:, None, None]
    sweep = (ang[:-1][None] * (1.0 - steps) + ang[1:][None] * steps).reshape(-1, 2)
    swept = nominal_joints(chain, np.repeat(s[None, :], len(sweep), 0), sweep, tip) \
        if len(sweep) else centres
    top = float(max(np.max(centres[:, 2]), np.max(swept[:, 2]))) + reach + p.safe_z_mm
    t = 0.0
    for m, a in enumerate(ang):
        ctr = centres[m]
        lines.append(f"(position {m}: {r1} {_n(a[0])} {r2} {_n(a[1])} deg, stylus on the "
                     f"sphere centre at {_n(ctr[0])} {_n(ctr[1])} {_n(ctr[2])} mm)")
        lines.append(f"G0 Z{_n(top)}")
        lines.append(f"G0 {_rot_words(chain, a)}")
        t += 20.0
        local = ctr[2] + reach + p.clearance_mm
        for j, nv in enumerate(dirs):
            start = ctr + nv * (reach + p.clearance_mm)
            stop = ctr + nv * (reach - p.overtravel_mm)
            above = np.array([start[0], start[1], local])
            for q, what in ((np.array([start[0], start[1], top]), "above the point"),
                            (above, "over the point"), (start, "approach"), (stop, "probe end")):
                _check(q, travel, f"position {m} point {j}: {what}")
            if j == 0:
                lines.append(f"G0 X{_n(above[0])} Y{_n(above[1])}")
            lines.append(f"G0 Z{_n(local)}")
            if j > 0:
                lines.append(f"G0 X{_n(above[0])} Y{_n(above[1])}")
            lines.append(f"G1 X{_n(start[0])} Y{_n(start[1])} Z{_n(start[2])} F{p.move_feed:.1f}")
            lines.append(f"G38.2 X{_n(stop[0])} Y{_n(stop[1])} Z{_n(stop[2])} F{p.probe_feed:.1f}")
            t += 4.0
            lines.append(f"(LOG,{m},{t:.1f},{a[0]:.6f},{a[1]:.6f},#5061,#5062,#5063)")
            lines.append(f"G1 X{_n(start[0])} Y{_n(start[1])} Z{_n(start[2])} F{p.move_feed:.1f}")
    lines += [f"G0 Z{_n(top)}", "(LOGCLOSE)", "M2"]
    return "\n".join(lines) + "\n"


def chain_rtest_path(chain: KinematicChain, step_deg: float = 10.0) -> np.ndarray:
    """(M, 2) angles (alphabetical columns) of an R-test path: the rotary axis with the
    longer travel (the turning one) a full turn (or its whole travel) with the other at
    0 and at half its travel (90 deg at most), then the other over 80 % of its travel
    (+-90 deg at most) and back with the turning one at the start."""
    r = chain.rotaries
    span = [chain.travel_deg[a][1] - chain.travel_deg[a][0] for a in r]
    turn = 1 if span[1] >= span[0] else 0
    lo, hi = chain.travel_deg[r[1 - turn]]
    lo_c, hi_c = chain.travel_deg[r[turn]]
    if hi_c - lo_c < 360.0:
        c = np.linspace(lo_c, hi_c, int(np.ceil((hi_c - lo_c) / step_deg)) + 1)
    else:
        c = np.arange(0.0, 360.0 + 1e-9, step_deg)
        c = np.clip(c, lo_c, hi_c)
    t_half = 0.5 * (lo if abs(lo) > abs(hi) else hi)
    t_half = float(np.clip(t_half, max(lo, -90.0), min(hi, 90.0)))
    lo80, hi80 = max(lo, -90.0) * 0.8, min(hi, 90.0) * 0.8
    t = np.linspace(lo80, hi80, int(np.ceil((hi80 - lo80) / step_deg)) + 1)
    zero = float(np.clip(0.0, lo, hi))
    parts = [(np.full(c.size, zero), c), (np.full(c.size, t_half), c[::-1]),
             (t, np.full(t.size, c[0])), (t[::-1], np.full(t.size, c[0]))]
    cols = [np.column_stack([tilt, turning] if turn == 1 else [turning, tilt])
            for tilt, turning in parts]
    return np.vstack(cols)


def chain_rtest_gcode(chain: KinematicChain, sphere_mm: tuple[float, float, float],
                      tip_mm: tuple[float, float, float], path_deg: np.ndarray,
                      travel: dict[str, tuple[float, float]], title: str,
                      feed_deg_min: float = 1000.0, safe_z_mm: float = 50.0) -> str:
    """The LinuxCNC program of an R-test path on ``chain`` under tool-centre-point control:
    the approach (identity kinematics where the module switches, else in TCP), a stop to
    fit the nest, then the path holding the ball's nominal centre."""
    ang = np.asarray(path_deg, dtype=np.float64).reshape(-1, 2)
    _check_rot(chain, ang, section="chain")
    s = np.asarray(sphere_mm, dtype=np.float64)
    tip = np.asarray(tip_mm, dtype=np.float64)
    joints = nominal_joints(chain, np.repeat(s[None, :], len(ang), 0), ang, tip)
    for i, q in enumerate(joints):  # what the kinematics will ask of the linear axes
        _check(q, travel, f"R-test step {i} ({_rot_words(chain, ang[i])} deg)")
    ident, tcp = _modes(chain)
    lines = [f"(abbe: {title})"]
    if chain.name in CONFIG_NOTE:
        lines.append(CONFIG_NOTE[chain.name][1])
    lines += [f"(R-test on chain {chain.name}, {chain.kind}: the sphere's nominal centre "
              f"{_n(s[0])} {_n(s[1])} {_n(s[2])} mm held under tool-centre-point control; "
              "the instrument logs)",
              "G21 G90 G94 G17 G40",
              "G43 (the nest is the current tool: its length to the ball's nominal centre)"]
    if ident:
        safe = float(joints[0, 2]) + safe_z_mm
        _check(np.array([joints[0, 0], joints[0, 1], safe]), travel, "R-test approach")
        lines += [f"{ident} (identity kinematics for the approach)",
                  f"G0 Z{_n(safe)}", f"G0 {_rot_words(chain, ang[0])}",
                  f"G0 X{_n(joints[0, 0])} Y{_n(joints[0, 1])}",
                  f"G1 Z{_n(joints[0, 2])} F{feed_deg_min:.1f}",
                  "M0 (fit the R-test nest on the sphere, zero the sensors)",
                  f"{tcp} (tool-centre-point control: {chain.name} kinematics)",
                  f"G1 X{_n(s[0])} Y{_n(s[1])} Z{_n(s[2])} F{feed_deg_min:.1f}"]
    else:
        safe = float(s[2]) + safe_z_mm
        # in TCP the programmed point is the workpiece's: above the sphere, then down
        lift = nominal_joints(chain, np.array([[s[0], s[1], safe]]), ang[:1], tip)[0]
        _check(lift, travel, "R-test approach")
        lines += [f"G0 Z{_n(safe)}", f"G0 {_rot_words(chain, ang[0])}",
                  f"G0 X{_n(s[0])} Y{_n(s[1])}",
                  f"G1 Z{_n(s[2])} F{feed_deg_min:.1f}",
                  "M0 (fit the R-test nest on the sphere, zero the sensors)"]
    for a in ang[1:]:
        lines.append(f"G1 {_rot_words(chain, a)}")
    lines += ["M0 (lift the nest off the ball)"]
    if ident:
        up = joints[-1] + np.array([0.0, 0.0, safe_z_mm])
        _check(up, travel, "R-test retract")
        lines += [ident, f"G0 Z{_n(float(up[2]))}"]
    else:
        lines.append(f"G0 Z{_n(safe)}")
    lines += ["M2"]
    return "\n".join(lines) + "\n"
