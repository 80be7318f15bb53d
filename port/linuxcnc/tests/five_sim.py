#!/usr/bin/python3
"""abbe's HAL component in five-axis mode inside LinuxCNC's trt simulators.

  flock /tmp/abbe-linuxcnc.lock python3 port/linuxcnc/tests/five_sim.py \
      [--kind xyzac-trt|xyzbc-trt] [--fitted] [--json OUT]

One mechanism for both table-table kinds of LinuxCNC's trt kinematics (CASES): the
sample configs sim/axis/vismach/5axis/table-rotary-tilting/xyzac-trt.ini (C on a
trunnion A) and xyzbc-trt.ini (C on B). The virtual machine (TRUTH): the sample
config's nominal geometry (rotation point 0; A/C: y-offset 20, z-offset 10 mm; B/C:
x-offset -20, z-offset -15 mm) with location errors trt can hold (A/C: EX0C, EY0C,
EY0A, EZ0A, EA0A, EC0C; B/C: EX0C, EY0C, EX0B, EZ0B, EB0B, EC0C), the tilts of both
axis lines it cannot (A/C: EB0A, EC0A, EA0C, EB0C; B/C: EA0B, EC0B, EA0C, EB0C),
error motions of both axes and the linear axes' squareness. Its table is written from
the truth (write_five_blob), not fitted: this test is about the chain table ->
component -> LinuxCNC -> joints; what the identification gets right is
host_tools/tests/analysis/test_five_axis_*'s. `abbe export -f linuxcnc-trt` writes
the trt pins, the HOME_OFFSETs and abbe-five.bin (what trt cannot hold); a headless
copy of the sample INI (trt_sim_check.headless_ini) takes them, with
port/linuxcnc/config/abbe-five.hal and abbe-five-hold.hal, and M428 / M429 remapped
to config/remap_subs/abbe_428.ngc / abbe_429.ngc (the wiring docs/linuxcnc.md shows).
Run as the LinuxCNC user, recorded every servo period (sampler, halsampler):

  1. tcp_off: the component disabled; M428 (tool-centre-point kinematics), the tool
     held on one workpiece point while the tilt (A or B) and C turn, then a short path;
  2. tcp_on: abbe enabled (abbe-hold.in0 1), the same program;
  3. joints_on: identity kinematics by the sample's own 429remap.ngc (no hold), a
     program of joint moves with the tilt and C;
  4. switch_on: M428 and M429 through abbe's remap (the correction held off across each
     switch), the M429 where run 3 switched, a move after each.

The checks use an INDEPENDENT forward kinematics of the true machine, written here
from the ISO 230-1 notation of docs/concepts.md ("Five-axis machines") and
trtfuncs.c's geometry (not abbe's model code; LinuxCNC commit f1270d6ed7, the Debian
2.9.0~pre1 package's source: xyzacKinematicsForward lines 147-191, xyzbcKinematicsForward
lines 251-295, whose world point is w = r + Rz(c)^T (R_tilt(t)^T (q - r - o) + o) with
o = (0, y-offset, z-offset) for A, (x-offset, 0, z-offset) for B, lines 268-284; the
inverse, lines 297-349, is export_readers.trt_joints): the joints LinuxCNC commands
(joint.N.motor-pos-cmd, the rotary motors turning the table by motor + E0) give
the true tool tip in workpiece coordinates, compared with the programmed point
(TCP: axis.L.pos-cmd; identity: trtfuncs.c's forward kinematics of the programmed
joints with the exported pins). The joints follow axis.L.pos-cmd by two periods
(checked in run 1).

  - tcp_off: the external offsets are exactly 0.0 all along and the joints are
    trtfuncs.c's inverse of the programmed point with the exported pins;
  - tcp_on and joints_on: on the path, the tool tip is within BOUND_UM of the
    programmed point, against the deviation of tcp_off (trt alone) and of the
    nominal machine without abbe (computed from the same path);
  - the frame: the joints move by the component's joint-frame correction, in TCP
    through workpiece-frame offsets (abbe.frame 1), in identity directly (frame 0);
  - the switch from trt to identity kinematics (M429 at A (B) -20, C 45 with the
    correction on) is measured: LinuxCNC 2.9.0~pre1 recomputes the world position
    from the joints WITH the offset in them, so the joints step by the offset in
    force (docs/linuxcnc.md: switch with the compensation off); checked to be no
    more than that plus the rate limit;
  - switch_on: at abbe's M429 the external offsets are 0.0, and from the last move
    before to the first after it the joints stay within FRAME_UM of trtfuncs.c's
    inverse of the point plus the component's correction (switch_metrics; run 3's
    switch measured the same way for comparison); on the moves after the switches
    the tool tip is within BOUND_UM again.

--fitted (run.sh's A/C run): the table is not written from the truth but FITTED, by
`abbe fit`, from a probing campaign of the virtual machine that this file simulates
with its own kinematics (probing_campaign: three spheres, 7 tilts x 12 C angles, five
touches each); the angular zeros the campaign cannot see (EA0A, EC0C) turn the
workpiece, so the tool tip is judged with the best rigid placement of the workpiece
taken out (one for the three compensated runs: a workpiece datum), within
FITTED_BOUND_UM; the raw deviation is reported beside it.

Every wait is bounded; LinuxCNC is stopped by the pid of its display.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
CONFIG = HERE.parent / "config"

# ---- the virtual machines -----------------------------------------------------------


@dataclass(frozen=True)
class Case:
    """One trt kind: its sample config's nominal geometry and the virtual machine's errors."""

    kind: str                    # xyzac-trt / xyzbc-trt (LinuxCNC's <kind>-kins, <kind>.ini)
    tilt: str                    # the tilt axis: A (about X) or B (about Y); joint 3
    nominal: dict[str, float]    # the sample config's trt pins, mm
    location: dict[str, float]   # location errors, um / urad (ISO 230-1)
    #: error motions (axis, component) -> [sin 1t, cos 1t, sin 2t, cos 2t], um / urad
    motions: dict[tuple[str, str], list[float]]
    squareness: tuple[float, float, float]  # Eq. 3's S_xy, S_xz, S_yz, urad


CASES = {
    "xyzac-trt": Case(
        "xyzac-trt", "A",
        {"x-rot-point": 0.0, "y-rot-point": 0.0, "z-rot-point": 0.0,
         "y-offset": 20.0, "z-offset": 10.0},
        {"EX0C": 40.0, "EY0C": -30.0, "EY0A": 25.0, "EZ0A": -35.0, "EA0A": 300.0,
         "EC0C": -400.0,
         "EB0A": 400.0, "EC0A": -300.0, "EA0C": 250.0, "EB0C": -200.0},
        {("A", "Y"): [0.0, 0.0, 2.0, 0.0], ("A", "Z"): [0.0, 0.0, 0.0, -1.5],
         ("A", "A"): [8.0, 0.0, 0.0, 0.0], ("A", "B"): [0.0, 0.0, 5.0, 0.0],
         ("C", "X"): [0.0, 0.0, 3.0, -2.0], ("C", "Y"): [0.0, 0.0, 0.0, 2.5],
         ("C", "Z"): [2.0, 0.0, 0.0, 0.0], ("C", "C"): [15.0, -10.0, 0.0, 0.0],
         ("C", "A"): [0.0, 0.0, 6.0, 0.0]},
        (80.0, -60.0, 50.0)),
    # B/C: B's line through r + (x-offset, 0, z-offset) along Y; trt holds its X, Z
    # position (EX0B, EZ0B) and zero (EB0B), not its tilts about X and Z (EA0B, EC0B).
    # B's radial error motions are X and Z (from the 2nd harmonic), Y is axial.
    "xyzbc-trt": Case(
        "xyzbc-trt", "B",
        {"x-rot-point": 0.0, "y-rot-point": 0.0, "z-rot-point": 0.0,
         "x-offset": -20.0, "z-offset": -15.0},
        {"EX0C": -35.0, "EY0C": 30.0, "EX0B": 30.0, "EZ0B": 40.0, "EB0B": -350.0,
         "EC0C": 300.0,
         "EA0B": -350.0, "EC0B": 250.0, "EA0C": -300.0, "EB0C": 200.0},
        {("B", "X"): [0.0, 0.0, -2.5, 0.0], ("B", "Z"): [0.0, 0.0, 0.0, 2.0],
         ("B", "Y"): [1.5, 0.0, 0.0, 0.0], ("B", "B"): [-9.0, 4.0, 0.0, 0.0],
         ("B", "C"): [0.0, 0.0, 5.0, 0.0], ("B", "A"): [0.0, 0.0, 0.0, -4.0],
         ("C", "X"): [0.0, 0.0, -2.0, 3.0], ("C", "Y"): [0.0, 0.0, 2.5, 0.0],
         ("C", "Z"): [0.0, -2.0, 0.0, 0.0], ("C", "C"): [-12.0, 8.0, 0.0, 0.0],
         ("C", "B"): [0.0, 0.0, -6.0, 0.0]},
        (-70.0, 55.0, 40.0)),
}
#: the ISO 230-1 names of each rotary axis' location errors: the two positions across the
#: axis and the two tilts (in the order of the other machine axes), then the zero
LOCATION_NAMES = {"A": ("EY0A", "EZ0A", "EB0A", "EC0A", "EA0A"),
                  "B": ("EX0B", "EZ0B", "EA0B", "EC0B", "EB0B"),
                  "C": ("EX0C", "EY0C", "EA0C", "EB0C", "EC0C")}
#: the machine axis each rotary axis turns about (0 X, 1 Y, 2 Z)
AXIS_OF = {"A": 0, "B": 1, "C": 2}


def tilt_offset(kind: str, pins: dict) -> np.ndarray:
    """o, the tilt axis' point relative to the C centre (mm): trtfuncs.c's (0, y-offset,
    z-offset) for xyzac, (x-offset, 0, z-offset) for xyzbc."""
    if kind == "xyzac-trt":
        return np.array([0.0, pins["y-offset"], pins["z-offset"]])
    return np.array([pins["x-offset"], 0.0, pins["z-offset"]])


def rot_point(pins: dict) -> np.ndarray:
    return np.array([pins["x-rot-point"], pins["y-rot-point"], pins["z-rot-point"]])


# ---- the programs -------------------------------------------------------------------
#: the programs, {T} the tilt axis' letter (A or B: the same angles, both within the
#: sample configs' joint 3 limits -100..50 deg)
TCP_PROGRAM = """(abbe five_sim: tool-centre-point kinematics, the tool on one workpiece point)
G21 G90 G94 G40 G49
M428
G0 X40 Y-25 Z20 {T}0 C0
G1 {T}-30 F1200
G1 C90
G1 {T}15 C150
G1 {T}-40 C60
G1 X10 Y15 Z35 F900
G1 X40 Y-25 Z20 {T}-20 C45 F1200
M2
"""
#: the switch to identity here is the sample config's own 429remap.ngc, called directly:
#: without abbe's hold (the INI remaps M428 / M429 to abbe's subroutines)
JOINT_PROGRAM = """(abbe five_sim: identity kinematics, joint moves with the tilt and C)
G21 G90 G94 G40 G49
o<429remap> call
G0 X30 Y-20 Z10 {T}0 C0
G1 {T}-35 C100 F1200
G1 X60 Y10 Z-15 {T}10 C200 F900
G1 X0 Y5 Z0 {T}0 C0 F900
M2
"""
#: M428 / M429 through abbe's remap (config/remap_subs/abbe_kins.ngc): the M429 at the
#: point and angles where JOINT_PROGRAM switched without it
SWITCH_PROGRAM = """(abbe five_sim: M428 / M429 with abbe's correction held off across the switch)
G21 G90 G94 G40 G49
M428
G1 X40 Y-25 Z20 {T}-20 C45 F1200
M429
G1 X30 Y-20 Z10 {T}0 C0 F1200
M2
"""
PROGRAMS = {"tcp.ngc": TCP_PROGRAM, "joints.ngc": JOINT_PROGRAM, "switch.ngc": SWITCH_PROGRAM}
#: the tool tip within this of the programmed point with abbe, on the path, um. What is
#: left: LinuxCNC's offset planner following a correction that turns with the table
#: (the lead extrapolates two periods), the first-order model (0.01 um here), the
#: recording's 1 nm / 1e-6 deg steps.
BOUND_UM = 0.5
#: rotary motors vs the programmed angle two periods earlier, deg: LinuxCNC's cubic
#: interpolation of the joints between trajectory points departs from the straight
#: two-period delay where the acceleration changes (5e-5 deg measured)
ROT_TOL_DEG = 1e-4
#: joints vs the correction they should carry (run 2/3), um
FRAME_UM = 0.5
INI_ABBE = """
[ABBE]
TABLE = abbe-five.bin
KINS_IDENTITY = 0
KINS_TCP = 1
WARN_MM = 0.2
LIMIT_MM = 0.3
RATE_MM_PER_S = 1.0
FADE_S = 0.5
ENABLE = 0
"""
#: the sample's M428 / M429 remaps replaced by abbe's (docs/linuxcnc.md, "Switching
#: kinematics"), abbe-five-hold.hal after abbe-five.hal
REMAPS = {"ngc=428remap": "ngc=abbe_428", "ngc=429remap": "ngc=abbe_429"}



def record(tilt: str) -> list[list[tuple[str, str]]]:
    """The pins recorded every servo period by two samplers (a HAL stream has at most 20
    pins), paired by abbe.cycles (sim_drive's recorder)."""
    t = tilt.lower()
    return [
        [("abbe.cycles", "u"),
         ("axis.x.pos-cmd", "f"), ("axis.y.pos-cmd", "f"), ("axis.z.pos-cmd", "f"),
         (f"axis.{t}.pos-cmd", "f"), ("axis.c.pos-cmd", "f"),
         ("joint.0.motor-pos-cmd", "f"), ("joint.1.motor-pos-cmd", "f"), ("joint.2.motor-pos-cmd", "f"),
         ("joint.3.motor-pos-cmd", "f"), ("joint.4.motor-pos-cmd", "f"),
         ("axis.x.eoffset", "f"), ("axis.y.eoffset", "f"), ("axis.z.eoffset", "f"),
         ("motion.program-line", "s"), ("motion.switchkins-type", "f"),
         ("motion.eoffset-limited", "b")],
        [("abbe.cycles", "u"),
         ("abbe.x.corr-mm", "f"), ("abbe.y.corr-mm", "f"), ("abbe.z.corr-mm", "f"),
         ("abbe.x.offset-mm", "f"), ("abbe.y.offset-mm", "f"), ("abbe.z.offset-mm", "f"),
         ("abbe.orient-x-urad", "f"), ("abbe.orient-y-urad", "f"), ("abbe.orient-z-urad", "f"),
         ("abbe.state", "s"), ("abbe.frame", "s"), ("abbe.flags", "u"),
         ("abbe.x.counts", "s"), ("abbe.y.counts", "s"), ("abbe.z.counts", "s"),
         ("abbe.enable", "b"), ("motion.digital-out-00", "b")],
    ]


RUNS = (("tcp_off", "tcp.ngc"), ("tcp_on", "tcp.ngc"), ("joints_on", "joints.ngc"),
        ("switch_on", "switch.ngc"))


# ---- the independent forward kinematics of the true machine ------------------------------

def _rot(i: int, t: np.ndarray) -> np.ndarray:
    """(N, 3, 3) right-handed rotations by t (rad) about machine axis i (0 X, 1 Y, 2 Z):
    Rodrigues, I + sin t K + (1 - cos t) K^2 with K the cross-product matrix of the axis."""
    k = np.zeros(3)
    k[i] = 1.0
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    t = np.asarray(t, dtype=float).reshape(-1, 1, 1)
    return np.eye(3)[None] + np.sin(t) * K[None] + (1.0 - np.cos(t)) * (K @ K)[None]


def _small(v: np.ndarray) -> np.ndarray:
    """Rx(a) Ry(b) Rz(c) of small angles (N, 3) rad (docs/concepts.md)."""
    return _rot(0, v[:, 0]) @ _rot(1, v[:, 1]) @ _rot(2, v[:, 2])


def _motion(case: Case, axis: str, t_deg: np.ndarray) -> np.ndarray:
    """(N, 6) error motions X, Y, Z um, A, B, C urad: Fourier series, period one turn."""
    t = np.radians(t_deg)
    out = np.zeros((len(t), 6))
    for j, comp in enumerate("XYZABC"):
        c = case.motions.get((axis, comp))
        if c:
            for h in range(len(c) // 2):
                out[:, j] += c[2 * h] * np.sin((h + 1) * t) + c[2 * h + 1] * np.cos((h + 1) * t)
    return out


def _axis(case: Case, axis: str, t_deg: np.ndarray):
    """(R (N,3,3), p (N,3)) of x -> R x + p, the carried frame of rotary `axis` at joint angle
    t into its carrier: the line moved rigidly about its nominal pivot P by its location
    errors, D = Tr(delta) Rot(phi), the error motion E(t) = Tr(m) Rot(r) at the pivot, the
    turn by t + E0: Tr(P) D E(t) Rot(t + E0) D^-1 Tr(-P). P: the C centre r for C, r + o
    for the tilt axis (tilt_offset)."""
    i = AXIS_OF[axis]
    others = [k for k in range(3) if k != i]
    names = LOCATION_NAMES[axis]
    loc = case.location
    delta, phi = np.zeros(3), np.zeros(3)
    delta[others] = [loc.get(n, 0.0) * 1e-3 for n in names[:2]]
    phi[others] = [loc.get(n, 0.0) * 1e-6 for n in names[2:4]]
    zero = loc.get(names[4], 0.0) * 1e-6
    P = rot_point(case.nominal) + (tilt_offset(case.kind, case.nominal) if axis != "C" else 0.0)
    n = len(t_deg)
    Rphi = _small(phi[None, :])[0]
    m = _motion(case, axis, t_deg)
    Rm = _small(m[:, 3:] * 1e-6)
    Rt = _rot(i, np.radians(t_deg) + zero)
    R = Rphi @ Rm @ Rt @ Rphi.T                     # the rotation part of D E Rot D^-1
    # point x: P + delta + Rphi (m + Rm Rt (Rphi^T (x - P - delta)))
    p = (P + delta)[None, :] + np.einsum("ij,nj->ni", Rphi, m[:, :3] * 1e-3) \
        - np.einsum("nij,j->ni", R, P + delta)
    assert R.shape == (n, 3, 3)
    return R, p


def true_tool_in_workpiece(case: Case, motor: np.ndarray) -> np.ndarray:
    """The true tool tip (N, 3) in workpiece coordinates for joint motor positions (N, 5):
    linear motors carry the tool with the squareness of Eq. 3 (dX = y S_xy - z S_xz,
    dY = -z S_yz, levers from the rotation point); the rotary motors (joint 3 the tilt,
    4 C) turn the table by motor + E0 (motor = the old joint angle, HOME_OFFSET 0; E0 is
    in case.location: _axis turns by t + E0)."""
    q = motor[:, :3]
    sxy, sxz, syz = (s * 1e-6 for s in case.squareness)
    lev = q - rot_point(case.nominal)
    tool = q + np.column_stack([lev[:, 1] * sxy - lev[:, 2] * sxz, -lev[:, 2] * syz,
                                np.zeros(len(q))])
    Rt, pt = _axis(case, case.tilt, motor[:, 3])
    Rc, pc = _axis(case, "C", motor[:, 4])
    R = Rt @ Rc                                       # workpiece -> machine
    p = np.einsum("nij,nj->ni", Rt, pc) + pt
    return np.einsum("nji,nj->ni", R, tool - p)       # R^T (tool - p)


def trt_forward(case: Case, pins: dict, joints: np.ndarray, angles_deg: np.ndarray) -> np.ndarray:
    """trtfuncs.c's forward kinematics (tool-offset 0; xyzacKinematicsForward,
    xyzbcKinematicsForward): the workpiece point under the tool at joints q,
    w = r + Rz(c)^T (R_tilt(t)^T (q - r - o) + o), R_tilt = Rx (A) or Ry (B)."""
    r, o = rot_point(pins), tilt_offset(case.kind, pins)
    t, c = np.radians(angles_deg[:, 0]), np.radians(angles_deg[:, 1])
    u = np.einsum("nji,nj->ni", _rot(AXIS_OF[case.tilt], t), joints - r - o) + o
    return np.einsum("nji,nj->ni", _rot(2, c), u) + r


def true_point(case: Case, w: np.ndarray, angles_deg: np.ndarray) -> np.ndarray:
    """Where the workpiece point w (mm) actually is, machine coordinates, at joint angles
    (N, 2) deg (tilt, C): the independent kinematics above (_axis)."""
    Rt, pt = _axis(case, case.tilt, angles_deg[:, 0])
    Rc, pc = _axis(case, "C", angles_deg[:, 1])
    return np.einsum("nij,nj->ni", Rt, np.einsum("nij,j->ni", Rc, w) + pc) + pt


# ---- a fitted table: a simulated probing campaign of the virtual machine -------------------
#: the campaign (--fitted): three spheres on the table at different heights, radii and
#: directions, probed at every tilt x C of the grid with five touches each, 0.2 um of
#: noise per touch. With the error motions to 2 harmonics and the squareness, one sphere
#: cannot tell a tilt motion from a radial one, and two (measured: 60 / 25 mm radius,
#: 10 / 50 mm high) still leave the C line's place and tilt confounded with C's motions:
#: 1.30 um left on the TCP path in LinuxCNC; three see everything but the angular zeros
FIT_SPHERES = {"S1": (60.0, 0.0, 10.0), "S2": (-15.0, 20.0, 50.0), "S3": (0.0, -35.0, 30.0)}
FIT_TILTS = (-90.0, -67.5, -45.0, -22.5, 0.0, 22.5, 45.0)
FIT_C_STEP = 30.0
FIT_RADIUS_MM, FIT_STYLUS_MM, FIT_NOISE_UM = 12.5, 1.5, 0.2
FIT_SQUARENESS = "true"
#: the fitted run's bound: the tool tip within this of the programmed point, the best rigid
#: placement of the workpiece taken out (a probing plan cannot see it: docs/concepts.md), um
FITTED_BOUND_UM = 1.0


def squareness_tool(case: Case, q: np.ndarray) -> np.ndarray:
    """The actual tool tip (N, 3) mm at joints q (N, 3): Eq. 3's squareness (levers from
    the rotation point), as true_tool_in_workpiece."""
    sxy, sxz, syz = (v * 1e-6 for v in case.squareness)
    lev = q - rot_point(case.nominal)
    return q + np.column_stack([lev[:, 1] * sxy - lev[:, 2] * sxz, -lev[:, 2] * syz,
                                np.zeros(len(q))])


def probing_campaign(case: Case, out: Path, machine_toml: str, seed: int = 33) -> Path:
    """Write the campaign's machine file and probe files into ``out`` (the documented
    formats, docs/formats.md "Five-axis machine file"): the touch points are where the
    stylus centre is when it touches the TRUE sphere (true_point), read as joint
    positions (the squareness undone). Returns the machine file."""
    rng = np.random.default_rng(seed)
    tilt = case.tilt.lower()
    dirs = [np.array([0.0, 0.0, 1.0])] + [
        np.array([np.cos(np.radians(30)) * np.cos(u), np.cos(np.radians(30)) * np.sin(u),
                  np.sin(np.radians(30))]) for u in np.arange(4) * np.pi / 2]
    reach = FIT_RADIUS_MM + FIT_STYLUS_MM
    toml = [line for line in machine_toml.splitlines()
            if not line.startswith("[indexer") and "indexer_C.csv" not in line]
    toml += ["[rotary.fit]", "harmonics = 2", f"squareness = {FIT_SQUARENESS}"]
    for name, centre in FIT_SPHERES.items():
        w = np.array(centre)
        rows = [f"position,t_s,{tilt}_deg,c_deg,x_mm,y_mm,z_mm"]
        t, k = 0.0, 0
        for a in FIT_TILTS:
            for c in np.arange(0.0, 360.0, FIT_C_STEP):
                ang = np.array([[a, c]])
                at = true_point(case, w, ang)[0]
                t += 30.0
                for n in dirs:
                    t += 5.0
                    stylus = at + n * reach
                    # joints whose actual tool tip is at the stylus centre (squareness undone
                    # by fixed point: its levers change by nanometres)
                    q = stylus.copy()
                    for _ in range(3):
                        q = stylus - (squareness_tool(case, q[None])[0] - q)
                    q = q + rng.normal(0.0, FIT_NOISE_UM * 1e-3, 3)
                    rows.append(f"{k},{t:.1f},{a:.6f},{c:.6f},{q[0]:.7f},{q[1]:.7f},{q[2]:.7f}")
                k += 1
        (out / f"probe_{name}.csv").write_text("\n".join(rows) + "\n")
        toml += [f"[probing.{name}]", f'file = "probe_{name}.csv"',
                 "sphere_mm = [" + ", ".join(f"{v:.6f}" for v in w) + "]",
                 f"sphere_radius_mm = {FIT_RADIUS_MM}", f"stylus_radius_mm = {FIT_STYLUS_MM}"]
    mf = out / "machine.toml"
    mf.write_text("\n".join(toml) + "\n")
    return mf


def without_placement(dev_um: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Deviations (N, 3) um of the tool tip from the programmed workpiece points w (N, 3)
    mm less the best rigid placement of the workpiece (a small rotation omega and a shift
    tau: omega x w + tau, least squares): what a workpiece
    datum absorbs and no probing plan of a sphere with an unknown place sees. Where the
    rotation is taken about does not matter: another point only changes tau."""
    v = w
    A = np.zeros((len(w), 3, 6))
    A[:, 0, 1], A[:, 0, 2] = v[:, 2], -v[:, 1]
    A[:, 1, 0], A[:, 1, 2] = -v[:, 2], v[:, 0]
    A[:, 2, 0], A[:, 2, 1] = v[:, 1], -v[:, 0]
    A[:, :, 3:] = np.eye(3)
    A2 = A.reshape(-1, 6)
    sol, *_ = np.linalg.lstsq(A2, dev_um.reshape(-1), rcond=None)
    return (dev_um.reshape(-1) - A2 @ sol).reshape(-1, 3)


# ---- as the LinuxCNC user -------------------------------------------------------------------

def kind_of(ini: Path) -> str:
    """The trt kind the INI's [KINS] KINEMATICS loads (xyzac-trt-kins / xyzbc-trt-kins)."""
    for line in ini.read_text().splitlines():
        key, _, value = line.partition("=")
        words = value.split()
        if key.strip() == "KINEMATICS" and words and words[0].removesuffix("-kins") in CASES:
            return words[0].removesuffix("-kins")
    raise ValueError(f"{ini}: KINEMATICS is none of {', '.join(k + '-kins' for k in CASES)}")


def drive(ini: Path, out: Path) -> None:
    """Start, home, the three runs recorded; write drive.json."""
    sys.path.insert(0, str(out))
    import linuxcnc as lc
    import sim_drive as sd

    sd.RECORD = record(CASES[kind_of(ini)].tilt)
    sd.bounded(200)
    proc, lc_log = sd.launch(ini, out)
    res: dict = {"ok": False, "runs": {}}
    try:
        s, c, e = sd.connect(proc)
        sd.add_recorder()
        sd.power_on(c, s)
        c.mode(lc.MODE_MANUAL)
        c.wait_complete()
        c.home(-1)
        c.wait_complete()
        sd.wait_for(lambda: (s.poll() or True) and all(s.homed[:5]), 60, "homing all joints")
        for name, prog in RUNS:
            if name == "tcp_on":
                sd.halcmd("setp", "abbe-hold.in0", "1")  # abbe.enable AND NOT the hold
                sd.wait_for(lambda: sd.getp("abbe.state") == 1
                            and int(sd.getp("abbe.flags")) & 0x0100 == 0, 10, "abbe faded in")
            rec = sd.Recorder(out, name)
            secs = sd.run_program(c, s, out / prog, 90)
            res["runs"][name] = {"seconds": secs, "overruns": rec.stop()}
            sd.log(f"{name}: {secs:.1f} s")
        res["errors"] = sd.operator_errors(e)
        res["ok"] = True
    finally:
        sd.shutdown(proc, lc_log, res)
        (out / "drive.json").write_text(json.dumps(res, indent=2))


# ---- as root: set up, run, check ----------------------------------------------------------

def load(work: Path, name: str, tilt: str) -> dict:
    from lcnc_common import check, read_samples
    parts = []
    for n, pins in enumerate(record(tilt)):
        d = read_samples(work / f"{name}.{n}.txt", len(pins))
        parts.append({pin: d[:, 1 + i] for i, (pin, _) in enumerate(pins)})
    check(len(parts[0]["abbe.cycles"]) == len(parts[1]["abbe.cycles"])
          and np.array_equal(parts[0]["abbe.cycles"], parts[1]["abbe.cycles"]),
          f"{name}: the two samplers' periods do not pair up")
    check(np.all(np.diff(parts[0]["abbe.cycles"]) == 1), f"{name}: periods missing")
    r = parts[0] | parts[1]
    col = lambda fmt, ax: np.column_stack([r[fmt.format(a)] for a in ax])  # noqa: E731
    return {"world": col("axis.{}.pos-cmd", "xyz"),
            "world_ang": col("axis.{}.pos-cmd", tilt.lower() + "c"),
            "motor": col("joint.{}.motor-pos-cmd", "01234"), "eoffset": col("axis.{}.eoffset", "xyz"),
            "line": r["motion.program-line"], "kinstype": r["motion.switchkins-type"],
            "limited": r["motion.eoffset-limited"], "corr": col("abbe.{}.corr-mm", "xyz"),
            "orient": col("abbe.orient-{}-urad", "xyz"), "state": r["abbe.state"],
            "frame": r["abbe.frame"], "counts": col("abbe.{}.counts", "xyz"),
            "enable": r["abbe.enable"], "hold": r["motion.digital-out-00"]}


def stats(d_mm: np.ndarray) -> dict:
    n = np.linalg.norm(d_mm, axis=1) * 1e3
    return {"max_um": round(float(n.max()), 4), "rms_um": round(float(np.sqrt(np.mean(n ** 2))), 4)}


def path_lines(program: str) -> list[int]:
    """Line numbers (1-based, as motion.program-line) of the program's G1 moves."""
    return [i + 1 for i, ln in enumerate(program.splitlines()) if ln.startswith("G1")]


def switch_metrics(r: dict, case: Case, pins: dict) -> dict:
    """The joints around a run's switch from trt to identity (M429), the machine standing:
    from the last programmed motion before it to the first rotary motion after it, the
    joints should stay at trtfuncs.c's inverse of the point where the machine stopped plus
    the component's joint-frame correction (two periods late). joint_error: what the
    switch did to them beyond that, um; joint_step: their largest change in one period,
    um; held_s: how long abbe's hold (motion.digital-out-00) was on."""
    from export_readers import trt_joints
    from lcnc_common import check
    k = r["kinstype"]
    sw = np.flatnonzero((k[:-1] == 1.0) & (k[1:] == 0.0))
    check(sw.size == 1, f"{sw.size} switches from trt to identity recorded, expected 1")
    sw = int(sw[0]) + 1                               # the first period in identity
    d, da = np.abs(np.diff(r["world"], axis=0)), np.abs(np.diff(r["world_ang"], axis=0))
    moving = np.flatnonzero(np.any(d > 1e-9, axis=1) | np.any(da > 1e-9, axis=1))
    start = int(moving[moving < sw - 1][-1]) + 1 if np.any(moving < sw - 1) else 0
    turning = np.flatnonzero(np.any(da > 1e-9, axis=1))
    check(np.any(turning >= sw), "no rotary motion after the switch")
    end = int(turning[turning >= sw][0])              # the last period before it
    lag = 2
    ideal = trt_joints(case.kind, pins, r["world"][start:start + 1], r["world_ang"][start:start + 1])[0]
    j = np.arange(start + lag, end + lag + 1)
    err = r["motor"][j, :3] - ideal - r["corr"][j - lag]
    step = np.abs(np.diff(r["motor"][start + lag:end + lag + 1, :3], axis=0))
    return {"periods": int(len(j)), "standing_before_switch": int(sw - start),
            "offset_at_switch_um": round(float(np.linalg.norm(r["eoffset"][sw - 1])) * 1e3, 4),
            "joint_error_max_um": round(float(np.linalg.norm(err, axis=1).max()) * 1e3, 4),
            "joint_step_max_um": round(float(step.max(initial=0.0)) * 1e3, 4),
            "held_s": round(float(np.sum(r["hold"][start:end + 1])) * 1e-3, 3)}


def analyse(work: Path, pins: dict, home: dict, case: Case, fitted: bool = False) -> dict:
    """The checks of the module docstring. ``fitted``: the table was fitted from a
    simulated probing campaign (--fitted), so the tool tip is judged against the
    programmed point with the best rigid placement of the workpiece taken out (one for
    all runs: a workpiece datum), within FITTED_BOUND_UM; the raw deviation is reported."""
    from export_readers import trt_joints
    from lcnc_common import check
    hoff = np.array([home[3], home[4]])
    report: dict = {"kind": case.kind}
    devs: dict[str, tuple[np.ndarray, np.ndarray]] = {}  # run -> (deviation um, point mm)
    for name, prog in RUNS[:3]:
        r = load(work, name, case.tilt)
        text = PROGRAMS[prog].format(T=case.tilt)
        tcp = prog == "tcp.ngc"
        lag = 2  # joints follow axis.L.pos-cmd by two servo periods
        world, wang = r["world"][:-lag], r["world_ang"][:-lag]
        motor, eoff = r["motor"][lag:], r["eoffset"][lag:]
        on_path = np.isin(r["line"][lag:], path_lines(text))
        check(on_path.sum() > 1000, f"{name}: only {on_path.sum()} periods on the path")
        check(np.all(r["kinstype"][lag:][on_path] == (1.0 if tcp else 0.0)),
              f"{name}: motion.switchkins-type is not {'1 (trt)' if tcp else '0 (identity)'}")
        check(not r["limited"].any(), f"{name}: motion.eoffset-limited")
        # the rotary motors: the joint angle minus HOME_OFFSET, in every run
        d_rot = motor[:, 3:] - (wang - hoff)
        check(float(np.max(np.abs(d_rot[on_path]))) < ROT_TOL_DEG,
              f"{name}: rotary motors differ from the programmed angles by {np.max(np.abs(d_rot))}")
        ang = wang  # the joint angles (true angles: HOME_OFFSET holds E0)
        intended = world if tcp else trt_forward(case, pins, world, ang)
        got = true_tool_in_workpiece(case, motor)
        dev = (got - intended)[on_path]
        devs[name] = (dev * 1e3, intended[on_path])
        ideal = trt_joints(case.kind, pins, intended, ang) if tcp else world
        moved = (motor[:, :3] - ideal)                 # what the offsets did to the joints
        res = {"periods_on_path": int(on_path.sum()), "deviation": stats(dev),
               "orientation_urad_max": round(float(np.max(np.abs(r["orient"][lag:][on_path]))), 3)}
        if name == "tcp_off":
            check(np.all(r["eoffset"] == 0.0), "tcp_off: an external offset with abbe disabled")
            check(np.all(r["state"] == 0) and np.all(r["counts"] == r["counts"][0]),
                  "tcp_off: the component ran or its counts moved while disabled")
            res["joints_vs_trt_inverse"] = stats(moved[on_path])
            check(res["joints_vs_trt_inverse"]["max_um"] < 2.0,
                  f"tcp_off: joints are not trtfuncs.c's inverse: {res['joints_vs_trt_inverse']}")
            # the same path on the nominal machine, no abbe, no exported pins or HOME_OFFSET
            q_nom = trt_joints(case.kind, case.nominal, intended, ang)
            nominal_motor = np.column_stack([q_nom, ang])
            res["nominal_no_abbe"] = stats((true_tool_in_workpiece(case, nominal_motor)
                                            - intended)[on_path])
        else:
            check(np.all(r["frame"][lag:][on_path] == (1 if tcp else 0)),
                  f"{name}: abbe.frame is not {1 if tcp else 0}")
            # the frame: the joints carry the component's joint-frame correction two periods on
            corr = r["corr"][:-lag]
            res["joints_minus_correction"] = stats((moved - corr)[on_path])
            res["correction"] = stats(corr[on_path])
            res["eoffset_minus_correction"] = stats((eoff - corr)[on_path])
            # the same joints without the offsets (trt alone), and with the joint-frame
            # correction written as world offsets unturned (the frame taken wrong)
            base = np.column_stack([ideal, motor[:, 3:]])
            res["without_offsets"] = stats((true_tool_in_workpiece(case, base) - intended)[on_path])
            t, c = np.radians(ang[:, 0]), np.radians(ang[:, 1])
            turn = _rot(AXIS_OF[case.tilt], t) @ _rot(2, c)
            wrong = np.einsum("nij,nj->ni", turn, corr) if tcp else \
                np.einsum("nji,nj->ni", turn, corr)
            res["deviation_if_frame_wrong"] = stats((true_tool_in_workpiece(
                case, np.column_stack([ideal + wrong, motor[:, 3:]])) - intended)[on_path])
            check(res["joints_minus_correction"]["max_um"] < FRAME_UM,
                  f"{name}: the joints do not carry the correction: {res['joints_minus_correction']}")
            if not fitted:
                check(res["deviation"]["max_um"] < BOUND_UM,
                      f"{name}: tool tip {res['deviation']} from the programmed point (bound "
                      f"{BOUND_UM} um)")
        if name == "joints_on":
            # M429 with the correction on, at A (B) -20 C 45: LinuxCNC takes the joints (offset
            # included) as the new world position and adds the offset again; the offsets
            # then move to the identity frame at the rate limit (1 um per period)
            k = r["kinstype"]
            sw = int(np.argmax(k == 0.0))
            check(k[0] == 1.0 and sw > 0, "joints_on: the switch to identity was not recorded")
            still = np.all(np.abs(np.diff(r["world"], axis=0)) < 1e-9, axis=1) & \
                np.all(np.abs(np.diff(r["world_ang"], axis=0)) < 1e-9, axis=1)
            end = sw + int(np.argmin(still[sw:]))  # the first motion after the switch
            step = np.abs(np.diff(r["motor"][:, :3], axis=0))[sw:end]
            res["switch"] = {"periods_before_motion": int(end - sw),
                             "joint_step_max_um": round(float(step.max(initial=0.0)) * 1e3, 4),
                             "joint_change_um": round(float(np.linalg.norm(
                                 r["motor"][end, :3] - r["motor"][sw, :3])) * 1e3, 4),
                             "offset_at_switch_um": round(float(np.linalg.norm(
                                 r["eoffset"][sw - 1])) * 1e3, 4)}
            jump = float(np.max(np.abs(r["motor"][end, :3] - r["motor"][sw, :3]))) * 1e3
            check(jump <= float(np.max(np.abs(r["eoffset"][sw - 1]))) * 1e3 + (end - sw) * 1.0 + 0.01,
                  f"joints_on: the kinematics switch moved the joints more than the offset: "
                  f"{res['switch']}")
            # the same switch measured as switch_on's, for the comparison
            res["switch_without_hold"] = switch_metrics(r, case, pins)
        report[name] = res
    # switch_on: M428 / M429 through abbe's remap (abbe_kins.ngc): at the M429 the
    # offsets are zero, the joints stay where the correction puts them, and the
    # correction is whole again on the moves after each switch
    r = load(work, "switch_on", case.tilt)
    sm = switch_metrics(r, case, pins)
    lag = 2
    world, wang, motor = r["world"][:-lag], r["world_ang"][:-lag], r["motor"][lag:]
    kin = r["kinstype"][lag:]
    on_path = np.isin(r["line"][lag:], path_lines(SWITCH_PROGRAM.format(T=case.tilt)))
    check(on_path.sum() > 500, f"switch_on: only {on_path.sum()} periods on the path")
    intended = np.where((kin == 1.0)[:, None], world, trt_forward(case, pins, world, wang))
    dev_sw = (true_tool_in_workpiece(case, motor) - intended)[on_path]
    devs["switch_on"] = (dev_sw * 1e3, intended[on_path])
    sm["deviation_on_moves_after_switches"] = stats(dev_sw)
    sm["held_total_s"] = round(float(np.sum(r["hold"])) * 1e-3, 3)
    report["switch_on"] = sm
    check(r["hold"][-1] == 0 and r["enable"][-1] == 1 and r["state"][-1] == 1
          and r["frame"][-1] == 0, "switch_on: abbe not on again in identity after the remap")
    check(sm["held_s"] > 0.0 and sm["offset_at_switch_um"] < 0.01,
          f"switch_on: the hold did not bring the offsets to zero before the switch: {sm}")
    check(sm["joint_error_max_um"] < FRAME_UM,
          f"switch_on: the switch moved the joints beyond the correction: {sm}")
    if not fitted:
        check(sm["deviation_on_moves_after_switches"]["max_um"] < BOUND_UM,
              f"switch_on: tool tip {sm['deviation_on_moves_after_switches']} after the switches")
    off, on = report["tcp_off"]["deviation"], report["tcp_on"]["deviation"]
    if fitted:
        # one rigid placement of the workpiece for the compensated runs (a datum), fitted
        # on their deviations together; tcp_off (trt alone) gets its own for comparison
        runs_on = ("tcp_on", "joints_on", "switch_on")
        left = without_placement(np.vstack([devs[n][0] for n in runs_on]),
                                 np.vstack([devs[n][1] for n in runs_on]))
        k = 0
        for n in runs_on:
            m = len(devs[n][0])
            part = left[k:k + m] * 1e-3
            k += m
            where = report[n] if n != "switch_on" else sm
            where["deviation_placement_out"] = stats(part)
            check(where["deviation_placement_out"]["max_um"] <= FITTED_BOUND_UM,
                  f"{n}: fitted table: tool tip {where['deviation_placement_out']} from the "
                  f"programmed point with the workpiece placement out (bound {FITTED_BOUND_UM} um)")
        report["tcp_off"]["deviation_placement_out"] = stats(
            without_placement(*devs["tcp_off"]) * 1e-3)
        off = report["tcp_off"]["deviation_placement_out"]
        on = report["tcp_on"]["deviation_placement_out"]
    check(on["max_um"] * 10 < off["max_um"], f"abbe does not take off 90 %: {on} vs {off}")
    # in TCP the offsets are NOT the joint-frame correction (the table turned them)
    check(report["tcp_on"]["eoffset_minus_correction"]["max_um"] > 5.0,
          "tcp_on: the offsets equal the joint-frame correction: no frame change seen")
    return report


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--drive", nargs=2, type=Path, metavar=("INI", "OUT"))
    ap.add_argument("--json", type=Path)
    ap.add_argument("--kind", choices=sorted(CASES), default="xyzac-trt",
                    help="the trt kind and its sample config (default xyzac-trt)")
    ap.add_argument("--fitted", action="store_true",
                    help="the table fitted by abbe fit from a simulated probing campaign of the "
                         "virtual machine (probing_campaign), not written from its truth")
    ap.add_argument("--analyse", type=Path, metavar="WORK",
                    help="check a kept work directory again (ABBE_LCNC_KEEP=1), no LinuxCNC")
    args = ap.parse_args()
    if args.drive:
        drive(*args.drive)
        return 0
    t_start = time.monotonic()
    sys.path.insert(0, str(HERE))
    sys.path.insert(0, str(HERE.parents[2] / "host_tools" / "tests"))
    sys.path.insert(0, str(HERE.parents[2] / "host_tools"))
    from export_readers import read_linuxcnc_trt
    from lcnc_common import TestFailure, cleanup, work_dir
    if args.analyse:
        comp, pins, home = read_linuxcnc_trt(args.analyse / "trt")
        print(json.dumps(analyse(args.analyse, pins, home, CASES[comp.removesuffix("-kins")],
                                 args.fitted), indent=2))
        return 0
    from lcnc_common import cli
    from trt_sim_check import MACHINES, export_to_sample, run_drive  # the sample machine and config

    from abbe.model.five_axis import FiveAxisErrors

    case = CASES[args.kind]
    work = work_dir("abbe-five-")
    try:
        errs = FiveAxisErrors(location=dict(case.location),
                              motions={k: np.array(v) for k, v in case.motions.items()},
                              squareness=case.squareness)
        fit_report = None
        if args.fitted:
            # the table abbe fit identifies from a probing campaign of the virtual machine
            camp = work / "campaign"
            camp.mkdir()
            t_fit = time.monotonic()
            mf = probing_campaign(case, camp, MACHINES[case.kind])
            cli("fit", str(mf), "-o", str(work / "fit"), "--no-report", "--quiet")
            doc = json.loads((work / "fit" / "five_axis.json").read_text())
            fit_report = {"seconds": round(time.monotonic() - t_fit, 1),
                          "spheres": {k: list(v) for k, v in FIT_SPHERES.items()},
                          "positions_per_sphere": len(FIT_TILTS) * int(360 / FIT_C_STEP),
                          "dispersion_um": doc["dispersion_um"],
                          "repredicted": doc["blob"]["repredicted"],
                          "convention": doc["blob"]["convention"]}
            errs = (work / "fit" / "model_five.bin").read_bytes()
        pins, home, ini = export_to_sample(work, errs, case.kind)
        cfg = ini.parent
        text = ini.read_text()
        lines = []
        for ln in text.splitlines():
            lines.append(ln)
            if ln.strip() in ("[AXIS_X]", "[AXIS_Y]", "[AXIS_Z]"):
                lines.append("OFFSET_AV_RATIO = 0.2")  # the external offsets' share of vel/acc
            if ln.strip().startswith("HALFILE") and "basic_sim.tcl" in ln:
                lines.append("HALFILE = abbe-five.hal")
                lines.append("HALFILE = abbe-five-hold.hal")
            if ln.strip().startswith("REMAP"):
                for old, new in REMAPS.items():
                    lines[-1] = lines[-1].replace(old, new)
        ini.write_text("\n".join(lines) + "\n" + INI_ABBE)
        for hal in ("abbe-five.hal", "abbe-five-hold.hal"):
            shutil.copy(CONFIG / hal, cfg / hal)
        for sub in sorted((CONFIG / "remap_subs").glob("abbe_*.ngc")):
            shutil.copy(sub, cfg / "remap_subs" / sub.name)
        shutil.copy(work / "trt" / "abbe-five.bin", cfg / "abbe-five.bin")
        for prog, text in PROGRAMS.items():
            (work / prog).write_text(text.format(T=case.tilt))
        drv = run_drive(work, Path(__file__), ini, "drive.json", 240)
        if drv is None:
            print(f"five_sim {case.kind}{' (fitted)' if args.fitted else ''}: FAIL (LinuxCNC run)")
            return 1
        try:
            report = analyse(work, pins, home, case, args.fitted)
        except TestFailure as e:
            print(f"five_sim {case.kind}{' (fitted)' if args.fitted else ''}: FAIL: {e}")
            return 1
        report["runs"] = drv["runs"]
        if fit_report is not None:
            report["fitted_table"] = fit_report
        report["seconds_total"] = round(time.monotonic() - t_start, 1)
        print(json.dumps(report, indent=2))
        if args.json:
            args.json.write_text(json.dumps(report, indent=2) + "\n")
        print(f"five_sim {case.kind}{' (fitted)' if args.fitted else ''}: PASS")
        return 0
    finally:
        cleanup(work)


if __name__ == "__main__":
    sys.exit(main())
