#!/usr/bin/python3
"""LinuxCNC's three other five-axis kinds in the simulator: the figure without abbe.

  flock /tmp/abbe-linuxcnc.lock python3 port/linuxcnc/tests/kinds_sim.py \
      [--kind bridgemill|max5|xyzab-tdr] [--json OUT]

The sample configurations LinuxCNC 2.9 ships beside the trt ones
(sim/axis/vismach/5axis/): `bridgemill/5axis.ini` (5axiskins: a head-head bridge mill,
C about Z carrying B about Y, both in the spindle head), `max5/max5kins.ini` (maxkins:
head-table, B tilting the head, C turning the table; `max5/max5triv.ini` is the same
machine with trivkins) and `table-dual-rotary/xyzab-tdr.ini` (xyzab_tdr_kins: two rotary
tables, B about Y and A about X). Each runs headless as five_sim.py / trt_sim_check.py
run theirs (a copy of the sample with the vismach and PYVCP parts taken out, linuxcncrsh
as display, run as the LinuxCNC user, every wait bounded, stopped by the pid of its
display), twice:

  1. tcp_on: the kinematics module's tool-centre-point mode (5axiskins: switchkins type
     0; xyzab_tdr_kins: type 1, set by `M68 E3 Qn` + `M66 E0 L0` as the samples' M428 /
     M429 remaps do; maxkins has no other mode), G0 to POSES (programmed point, angles);
  2. tcp_off: identity kinematics (5axiskins type 1, xyzab_tdr_kins type 0, max5triv.ini),
     G0 to the joints a CAM post-processor computes for the same poses from the nominal
     geometry (NOMINAL_IK below).

Per pose, the joints LinuxCNC commands (stat.joint_position) go through an INDEPENDENT
forward kinematics of a true machine: the module's nominal geometry written here as
rotations about axis lines (the product of exponentials at the home pose), from the
module's source in the Debian 2.9.0~pre1 package (LinuxCNC commit f1270d6ed7):
5axiskins.c kinematicsForward (tip = J + s2r(pivot, C, 180 - B) + (0, 0, pivot)),
maxkins.c kinematicsInverse (the VTKINEMATICS_VERSION1 one: j = Rz(-C) P - h(B), h the
head's offset L (sin B, 0, 1 - cos B)), xyzab_tdr_kins.comp kinematicsForward type 1 (w = Rx(a)(Ry(b) p - dz z)
+ dz z + rot_point). The true machine adds ISO 230-1 location errors of both rotary axis
lines (TRUE_ERRORS: the line's position across it, its two tilts, the angular zero). The
tool tip minus the programmed point is measured with TCP on and off. abbe is not in the
loop: the C runtime evaluates table-table kinds only (issue 39 item 3 is not built), so
this states the figure WITHOUT abbe.

Checks (they can fail): LinuxCNC's tcp_on joints are this file's reading of the module's
inverse (MODULE_IK) within JOINT_TOL_MM / JOINT_TOL_DEG, so the forward kinematics here
is the module's; the tcp_off joints are the programmed ones; the nominal machine (errors
0) puts the tool on the programmed point within NOMINAL_TOL_UM; the injected errors move
it by more than 1 um. maxkins 2.9.0~pre1's kinematicsForward is not the inverse of its
kinematicsInverse when B and C are both turned (it adds the head's B offset after the C
rotation; upstream has moved it since): TCP motion runs the inverse, which is the rigid
machine's, so the forward's gap is only reported (`module_forward_gap_um`: what LinuxCNC
would display as the position, not where the tool goes).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SAMPLES = Path("/usr/share/doc/linuxcnc/examples/sample-configs/sim/axis/vismach/5axis")
JOINT_TOL_MM = 1e-6
JOINT_TOL_DEG = 1e-9
NOMINAL_TOL_UM = 0.01
URAD = 1e-6
UM = 1e-3


@dataclass
class Case:
    name: str
    folder: str
    ini: str                      # the TCP configuration
    off_ini: str | None           # a second configuration for tcp_off (max5triv), or None
    gui: str                      # the vismach component whose pins are dropped
    rot: tuple[str, str]          # the rotary coordinates in the order of POSES' angles
    joint_of: dict[str, int]      # coordinate -> joint number
    tcp_type: int | None          # switchkins type of the TCP mode (None: not switchable)
    off_type: int | None          # switchkins type of identity
    geometry: dict[str, float]
    poses: list[tuple[tuple[float, float, float], tuple[float, float]]]
    errors: dict[str, float] = field(default_factory=dict)


PIVOT_BRIDGE = 250.0   # 5axiskins' own default pivot-length (its source); the GUI's sum is replaced
PIVOT_MAX5 = 60.0      # max5_base.inc ships B_PIVOT_LENGTH = 0 (B would not move the tip): 60 mm here

CASES = {
    "bridgemill": Case(
        "bridgemill", "bridgemill", "5axis.ini", None, "5axisgui", ("B", "C"),
        {"X": 0, "Y": 1, "Z": 2, "B": 3, "C": 4}, 0, 1, {"pivot": PIVOT_BRIDGE},
        [((10.0, 20.0, -30.0), (0.0, 0.0)), ((10.0, 20.0, -30.0), (30.0, 0.0)),
         ((10.0, 20.0, -30.0), (30.0, 90.0)), ((-40.0, 15.0, -60.0), (-45.0, 135.0)),
         ((60.0, -25.0, -10.0), (60.0, -120.0)), ((0.0, 0.0, -80.0), (-20.0, 300.0))],
        # C (outer, in the head): line at pivot + (EX0C, EY0C), tilts EA0C, EB0C, zero EC0C;
        # B (on C): line at pivot + (EX0B, EZ0B), tilts EA0B, EC0B, zero EB0B
        {"EX0C": 20.0, "EY0C": -15.0, "EA0C": 40.0, "EB0C": -30.0, "EC0C": 50.0,
         "EX0B": -25.0, "EZ0B": 30.0, "EA0B": 35.0, "EC0B": -45.0, "EB0B": 60.0}),
    "max5": Case(
        "max5", "max5", "max5kins.ini", "max5triv.ini", "max5gui", ("B", "C"),
        {"X": 0, "Y": 1, "Z": 2, "B": 4, "C": 5}, None, None, {"pivot": PIVOT_MAX5},
        [((20.0, 10.0, -60.0), (0.0, 0.0)), ((20.0, 10.0, -60.0), (20.0, 0.0)),
         ((20.0, 10.0, -60.0), (0.0, 90.0)), ((20.0, 10.0, -60.0), (20.0, 90.0)),
         ((-15.0, 25.0, -40.0), (-30.0, 200.0)), ((30.0, -5.0, -80.0), (40.0, -60.0))],
        # C (the table): line at (EX0C, EY0C), tilts EA0C, EB0C, zero EC0C;
        # B (the head, about Y): line at pivot + (EX0B, EZ0B), tilts EA0B, EC0B, zero EB0B
        {"EX0C": 20.0, "EY0C": -15.0, "EA0C": 40.0, "EB0C": -30.0, "EC0C": 50.0,
         "EX0B": -25.0, "EZ0B": 30.0, "EA0B": 35.0, "EC0B": -45.0, "EB0B": 60.0}),
    "xyzab-tdr": Case(
        "xyzab-tdr", "table-dual-rotary", "xyzab-tdr.ini", None, "xyzab-tdr-gui", ("A", "B"),
        {"X": 0, "Y": 1, "Z": 2, "A": 3, "B": 4}, 1, 0,
        {"x_offset": -20.0, "z_offset": -10.0, "rot_point": 0.0},
        [((10.0, 20.0, -30.0), (0.0, 0.0)), ((10.0, 20.0, -30.0), (30.0, 0.0)),
         ((10.0, 20.0, -30.0), (0.0, 40.0)), ((10.0, 20.0, -30.0), (30.0, 40.0)),
         ((-40.0, 15.0, -60.0), (-45.0, -70.0)), ((60.0, -25.0, 10.0), (120.0, 25.0))],
        # A (about X, next to the workpiece in this composition): line at rot_point + dz z +
        # (EY0A, EZ0A), tilts EB0A, EC0A, zero EA0A; B (about Y): line at rot_point +
        # (EX0B, EZ0B), tilts EA0B, EC0B, zero EB0B
        {"EY0A": 20.0, "EZ0A": -15.0, "EB0A": 40.0, "EC0A": -30.0, "EA0A": 50.0,
         "EX0B": -25.0, "EZ0B": 30.0, "EA0B": 35.0, "EC0B": -45.0, "EB0B": 60.0}),
}


# ---------------------------------------------------------------- the independent kinematics

def rodrigues(u: np.ndarray, t: float) -> np.ndarray:
    u = u / np.linalg.norm(u)
    k = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
    return np.eye(3) + np.sin(t) * k + (1.0 - np.cos(t)) * (k @ k)


def about_line(x: np.ndarray, point: np.ndarray, u: np.ndarray, t: float) -> np.ndarray:
    """x turned by t (rad) about the line through `point` along `u`."""
    return point + rodrigues(u, t) @ (x - point)


def _line(axis: str, e: dict[str, float], base: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """An axis line with its ISO 230-1 location errors (um, urad): (point, direction, zero
    offset rad). The position errors are the two components across the axis; the tilts
    turn the nominal direction about the other two machine axes (a tilt E_I0K about I
    moves the line's direction by E x k)."""
    k = {"A": 0, "B": 1, "C": 2}[axis]
    g = lambda n: e.get(n, 0.0)  # noqa: E731
    names = "XYZ"
    point = base.copy()
    tilt = np.zeros(3)
    for i in range(3):
        if i != k:
            point[i] += g(f"E{names[i]}0{axis}") * UM
            tilt[i] = g(f"E{'ABC'[i]}0{axis}") * URAD
    u = np.zeros(3)
    u[k] = 1.0
    u = u + np.cross(tilt, u)
    return point, u, g(f"E{axis}0{axis}") * URAD


def tool_in_workpiece(case: Case, joints: dict[str, float], errors: dict[str, float],
                      rigid: bool = True) -> np.ndarray:
    """The tool tip in workpiece coordinates (mm) of the machine `case` describes, at the
    joint positions (mm, deg), with `errors` (ISO 230-1 location errors, um / urad).

    rigid=False (maxkins only): the module's own composition (the head's offset added after
    the table's rotation), to compare with LinuxCNC's numbers."""
    j = np.array([joints["X"], joints["Y"], joints["Z"]])
    d2r = np.pi / 180.0
    if case.name == "bridgemill":
        L = case.geometry["pivot"]
        pivot = j + np.array([0.0, 0.0, L])
        pc, uc, zc = _line("C", errors, pivot)
        pb, ub, zb = _line("B", errors, pivot)
        # 5axiskins: tip = J + L (sin B cos C, sin B sin C, 1 - cos B): B turns the tool by -B
        tip = about_line(j, pb, ub, -joints["B"] * d2r + zb)
        return about_line(tip, pc, uc, joints["C"] * d2r + zc)
    if case.name == "max5":
        L = case.geometry["pivot"]
        pb, ub, zb = _line("B", errors, j + np.array([0.0, 0.0, L]))
        # maxkins (2.9): x += L sin B, z += L (1 - cos B): the head turns the tool by -B
        tip = about_line(j, pb, ub, -joints["B"] * d2r + zb)
        pc, uc, zc = _line("C", errors, np.zeros(3))
        if rigid:
            return about_line(tip, pc, uc, joints["C"] * d2r + zc)
        return about_line(j, pc, uc, joints["C"] * d2r + zc) + (tip - j)
    if case.name == "xyzab-tdr":
        rp = np.full(3, case.geometry["rot_point"])
        dz = case.geometry["z_offset"]
        pb, ub, zb = _line("B", errors, rp)
        pa, ua, za = _line("A", errors, rp + np.array([0.0, 0.0, dz]))
        # xyzab_tdr_kins type 1: w = Rx(a) (Ry(b) p - dz z) + dz z + rot_point (tool offset 0)
        m = about_line(j, pb, ub, joints["B"] * d2r + zb)
        return about_line(m, pa, ua, joints["A"] * d2r + za)
    raise ValueError(case.name)


def nominal_ik(case: Case, point, angles, module: bool = False) -> dict[str, float]:
    """The joints that put the NOMINAL machine's tool on `point` at `angles` (a CAM post's
    arithmetic; module=True: maxkins 2.9's own inverse, which LinuxCNC runs)."""
    a, b = angles
    rot = dict(zip(case.rot, (a, b)))
    p = np.array(point, dtype=float)
    d2r = np.pi / 180.0
    if case.name == "bridgemill":
        L = case.geometry["pivot"]
        B, C = rot["B"] * d2r, rot["C"] * d2r
        j = p - L * np.array([np.sin(B) * np.cos(C), np.sin(B) * np.sin(C), 1.0 - np.cos(B)])
    elif case.name == "max5":
        L = case.geometry["pivot"]
        B, C = rot["B"] * d2r, rot["C"] * d2r
        h = L * np.array([np.sin(B), 0.0, 1.0 - np.cos(B)])
        rz = np.array([[np.cos(-C), -np.sin(-C), 0.0], [np.sin(-C), np.cos(-C), 0.0], [0, 0, 1.0]])
        # maxkins.c's kinematicsInverse: j = Rz(-C) P - h (its forward, Rz(C) j + h, is not
        # its inverse for B and C both non-zero; the inverse is what TCP motion runs)
        j = rz @ p - h
    else:
        rp = np.full(3, case.geometry["rot_point"])
        dz = case.geometry["z_offset"]
        A, B = rot["A"] * d2r, rot["B"] * d2r
        ca, sa, cb, sb = np.cos(A), np.sin(A), np.cos(B), np.sin(B)
        rx = np.array([[1.0, 0, 0], [0, ca, -sa], [0, sa, ca]])
        ry = np.array([[cb, 0, sb], [0, 1.0, 0], [-sb, 0, cb]])
        c = rp + np.array([0.0, 0.0, dz])
        j = ry.T @ (rx.T @ (p - c) + c - rp) + rp
    out = {"X": j[0], "Y": j[1], "Z": j[2]}
    out.update(rot)
    return out


# ---------------------------------------------------------------- the headless configuration

ARROWS = ("<=", "=>", "<=>")


def _net_without(words: list[str], gui: str) -> str | None:
    """A `net SIGNAL pins...` line without the GUI's pins (and without arrows), or None
    when no pin is left."""
    kept = [w for w in words[2:] if w not in ARROWS and not w.startswith((gui + ".", "pyvcp.", "vismach."))]
    return " ".join(words[:2] + kept) if kept else None


def _strip_gui_hal(text: str, gui: str) -> str:
    """A HAL file without the vismach component: its loadusr, setp and every pin of it
    taken out of the nets (a net left without a pin is dropped)."""
    out = []
    for line in text.splitlines():
        s = line.strip()
        words = s.split()
        if not words or words[0].startswith("#"):
            out.append(line)
            continue
        if (words[0] == "loadusr" and gui in s) or (words[0] == "setp" and words[1].startswith(gui + ".")):
            continue
        if words[0] == "net":
            line = _net_without(words, gui)
            if line is None:
                continue
        out.append(line)
    return "\n".join(out) + "\n"


def headless(case: Case, cfg: Path, ini_name: str) -> Path:
    """Rewrite cfg/ini_name (a copy of the sample) and what it #INCLUDEs to run without a
    display (once: a second call finds the files done)."""
    ini = cfg / ini_name
    if (cfg / (ini_name + ".headless")).exists():
        return ini
    (cfg / (ini_name + ".headless")).write_text("")
    for inc in [ln.split(None, 1)[1].strip() for ln in ini.read_text().splitlines()
                if ln.startswith("#INCLUDE")]:
        if not (cfg / (inc + ".headless")).exists():
            (cfg / (inc + ".headless")).write_text("")
            _headless_ini(case, cfg / inc)
    _headless_ini(case, ini)
    if (cfg / ".hal-done").exists():
        return ini
    (cfg / ".hal-done").write_text("")
    for hal in cfg.glob("*.hal"):
        hal.write_text(_strip_gui_hal(hal.read_text(), case.gui))
    if case.name == "bridgemill":
        # 5axisgui.hal summed the GUI's pivot_len and the tool length into the pin: fixed here
        hal = cfg / "5axisgui.hal"
        hal.write_text("\n".join(ln for ln in hal.read_text().splitlines()
                                 if "pivotsum" not in ln and ":pivot-len" not in ln
                                 and ":gui-pivot-len" not in ln)
                       + f"\nsetp 5axiskins.pivot-length {PIVOT_BRIDGE!r}\n")
    if case.name == "max5":
        inc = cfg / "max5_base.inc"
        inc.write_text(inc.read_text().replace("B_PIVOT_LENGTH = 0", f"B_PIVOT_LENGTH = {PIVOT_MAX5!r}"))
    return ini


def _headless_ini(case: Case, ini: Path) -> None:
    # here, not at the top: this file also runs as a copy beside sim_drive.py (the drive),
    # where lcnc_common is not
    from lcnc_common import headless_halfile
    out, section = [], ""
    text = ini.read_text()
    for line in text.splitlines():
        s = line.strip()
        if s.startswith("["):
            section = s
        key = s.split("=")[0].strip()
        if key in ("PYVCP", "POSTGUI_HALFILE", "OPEN_FILE", "INTRO_GRAPHIC", "INTRO_TIME", "TOOL_EDITOR"):
            continue
        if key == "HALCMD" and case.gui in s:
            words = s.split("=", 1)[1].split()
            net = _net_without(words, case.gui) if words[0] == "net" else None
            if net is None:
                continue
            line = "HALCMD = " + net
        if key == "DISPLAY" and section == "[DISPLAY]":
            line = "DISPLAY = linuxcncrsh"
        if key == "PROGRAM_PREFIX":
            line = "PROGRAM_PREFIX = ."
        out.append(headless_halfile(line))
        if s == "[RS274NGC]" and "HAL_PIN_VARS" not in text:  # the remaps' and M68's pin reads
            out.append("HAL_PIN_VARS = 1")
    ini.write_text("\n".join(out) + "\n")


# ---------------------------------------------------------------- the driver (LinuxCNC user)

def drive(case_name: str, ini: Path, out: Path, mode: str, program: list[str], njoints: int) -> None:
    sys.path.insert(0, str(out))
    import linuxcnc as lc
    from sim_drive import bounded, connect, launch, power_on, stop_linuxcnc, wait_for
    bounded(400)
    proc, lc_log = launch(ini, out)
    res: dict = {"ok": False, "poses": [], "errors": []}
    try:
        s, c, e = connect(proc)
        power_on(c, s)
        c.mode(lc.MODE_MANUAL)
        c.wait_complete()
        c.home(-1)
        c.wait_complete()
        wait_for(lambda: (s.poll() or True) and all(s.homed[:njoints]), 120, "homing all joints")
        c.mode(lc.MODE_MDI)
        c.wait_complete()
        for cmd in program:
            c.mdi(cmd)
            c.wait_complete(60)
            wait_for(lambda: (s.poll() or True) and s.interp_state == lc.INTERP_IDLE and s.inpos, 90, cmd)
            if "(pose)" in cmd:
                s.poll()
                res["poses"].append({"cmd": cmd, "joints": list(s.joint_position[:njoints]),
                                     "world": list(s.position[:6])})
        while True:
            m = e.poll()
            if not m:
                break
            res["errors"].append(str(m[1]))
        res["ok"] = True
    except BaseException as exc:  # noqa: BLE001 - reported by the caller
        res["errors"].append(f"{type(exc).__name__}: {exc}")
    finally:
        res["stop"] = stop_linuxcnc(proc)
        lc_log.close()
        (out / f"{mode}.json").write_text(json.dumps(res, indent=1))


def _moves(case: Case, values: dict[str, float], tcp: bool) -> list[str]:
    """The moves to one pose, the last one marked (pose): one G0, or (maxkins under TCP) the
    angles then the point at G1 F600 (10 deg/s, 10 mm/s): maxkins' joints follow the
    rotations on the radius and the pivot, and at the sample's joint speeds (20 mm/s,
    limit3 in its HAL file) a G0 ends in a following error."""
    fmt = lambda keys: " ".join(f"{k}{values[k]:.9f}" for k in keys)  # noqa: E731
    if case.name == "max5" and tcp:
        return [f"G1 {fmt(case.rot)} F600", f"G1 {fmt(('X', 'Y', 'Z'))} F600 (pose)"]
    return [f"G0 {fmt(('X', 'Y', 'Z', *case.rot))} (pose)"]


def programs(case: Case) -> dict[str, list[str]]:
    on, off = [], []
    if case.tcp_type is not None:
        on += [f"M68 E3 Q{case.tcp_type}", "M66 E0 L0"]
        off += [f"M68 E3 Q{case.off_type}", "M66 E0 L0"]
    for point, angles in case.poses:
        world = {"X": point[0], "Y": point[1], "Z": point[2], **dict(zip(case.rot, angles))}
        on += _moves(case, world, True)
        off += _moves(case, nominal_ik(case, point, angles), False)
    return {"tcp_on": on, "tcp_off": off}


def run_case(case: Case, keep: bool) -> dict:
    import subprocess

    from lcnc_common import as_user, cleanup, give, hal_clean, work_dir
    work = work_dir(f"abbe-kinds-{case.name}-")
    result: dict = {"kind": case.name, "errors_injected": case.errors}
    try:
        cfg = work / "config"
        shutil.copytree(SAMPLES / case.folder, cfg)
        shutil.copy(HERE / "sim_drive.py", work / "sim_drive.py")
        shutil.copy(Path(__file__), work / Path(__file__).name)
        progs = programs(case)
        njoints = max(case.joint_of.values()) + 1
        for mode in ("tcp_on", "tcp_off"):
            ini_name = case.off_ini if (mode == "tcp_off" and case.off_ini) else case.ini
            ini = headless(case, cfg, ini_name)
            (work / f"{mode}.program.json").write_text(json.dumps(progs[mode]))
            for p in [work, *work.rglob("*")]:
                give(p)
            hal_clean()
            r = subprocess.run(as_user(["/usr/bin/python3", str(work / Path(__file__).name), "--drive",
                                        case.name, str(ini), str(work), mode, str(njoints)]),
                               cwd=work, capture_output=True, text=True, timeout=460, stdin=subprocess.DEVNULL)
            path = work / f"{mode}.json"
            got = json.loads(path.read_text()) if path.exists() else {"ok": False, "errors": ["no result"]}
            if r.returncode != 0 or not got.get("ok") or got.get("errors"):
                lc_log = work / "linuxcnc.log"
                print(r.stdout[-2000:], r.stderr[-2000:], lc_log.read_text()[-3000:] if lc_log.exists() else "",
                      got.get("errors"), sep="\n")
                result[mode] = {"ok": False, "errors": got.get("errors")}
                continue
            result[mode] = evaluate(case, mode, got)
            result[mode]["stop"] = got.get("stop")
        return result
    finally:
        if not keep:
            cleanup(work)


def evaluate(case: Case, mode: str, got: dict) -> dict:
    """Tool tip minus programmed point per pose (um), true machine and nominal machine, and
    LinuxCNC's joints against this file's reading of the module."""
    dev_true, dev_nom, dev_mod, joint_dev = [], [], [], []
    for (point, angles), pose in zip(case.poses, got["poses"]):
        jl = pose["joints"]
        joints = {k: jl[i] for k, i in case.joint_of.items()}
        if mode == "tcp_on":
            want = nominal_ik(case, point, angles, module=True)
        else:
            want = nominal_ik(case, point, angles)
        joint_dev.append(max(abs(joints[k] - want[k]) for k in want))
        p = np.array(point)
        dev_true.append((tool_in_workpiece(case, joints, case.errors) - p) / UM)
        dev_nom.append((tool_in_workpiece(case, joints, {}) - p) / UM)
        if case.name == "max5":
            dev_mod.append((tool_in_workpiece(case, joints, {}, rigid=False) - p) / UM)
    dev_true, dev_nom = np.array(dev_true), np.array(dev_nom)
    out = {"ok": True, "poses": len(dev_true),
           "max_joint_dev_vs_source": float(max(joint_dev)),
           "tip_minus_programmed_um": [[round(float(v), 4) for v in row] for row in dev_true],
           "max_norm_um": float(np.max(np.linalg.norm(dev_true, axis=1))),
           "nominal_max_norm_um": float(np.max(np.linalg.norm(dev_nom, axis=1)))}
    if dev_mod:
        out["module_forward_gap_um"] = float(np.max(np.linalg.norm(np.array(dev_mod), axis=1)))
    return out


def verdict(case: Case, res: dict) -> list[str]:
    fails = []
    for mode in ("tcp_on", "tcp_off"):
        r = res.get(mode, {})
        if not r.get("ok"):
            fails.append(f"{mode}: the run failed")
            continue
        if r["poses"] != len(case.poses):
            fails.append(f"{mode}: {r['poses']} poses recorded of {len(case.poses)}")
        if r["max_joint_dev_vs_source"] > JOINT_TOL_MM:
            fails.append(f"{mode}: LinuxCNC's joints differ from the source's by {r['max_joint_dev_vs_source']:.3g}")
        if r["nominal_max_norm_um"] > NOMINAL_TOL_UM:
            fails.append(f"{mode}: the nominal machine misses by {r['nominal_max_norm_um']:.3g} um")
        if r["max_norm_um"] < 1.0:
            fails.append(f"{mode}: the injected errors move the tip by only {r['max_norm_um']:.3g} um")
    return fails


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--kind", choices=sorted(CASES), action="append")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--keep", action="store_true", help="keep the work directories")
    ap.add_argument("--drive", nargs=5, metavar=("KIND", "INI", "OUT", "MODE", "NJOINTS"))
    args = ap.parse_args()
    if args.drive:
        kind, ini, out, mode, nj = args.drive
        prog = json.loads((Path(out) / f"{mode}.program.json").read_text())
        drive(kind, Path(ini), Path(out), mode, prog, int(nj))
        return 0
    sys.path.insert(0, str(HERE))
    report, failed = {}, []
    for name in args.kind or sorted(CASES):
        case = CASES[name]
        res = run_case(case, args.keep)
        fails = verdict(case, res)
        res["verdict"] = "PASS" if not fails else "FAIL: " + "; ".join(fails)
        report[name] = res
        print(f"[kinds] {name}: tcp_on {res.get('tcp_on', {}).get('max_norm_um')} um, "
              f"tcp_off {res.get('tcp_off', {}).get('max_norm_um')} um: {res['verdict']}", flush=True)
        failed += fails
    text = json.dumps(report, indent=2)
    print(text)
    if args.json:
        args.json.write_text(text + "\n")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
