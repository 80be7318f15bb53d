#!/usr/bin/python3
"""LinuxCNC's own xyzac-trt-kins takes `abbe export --format linuxcnc-trt`'s files.

  flock /tmp/abbe-linuxcnc.lock python3 port/linuxcnc/tests/trt_sim_check.py [--json OUT]

A virtual xyzac machine with the sample config's nominal geometry (rotation point 0,
y-offset 20, z-offset 10 mm) and only the location errors trt holds (EX0C, EY0C,
EY0A, EZ0A, EA0A, EC0C); abbe exports them; a headless copy of the sample config
sim/axis/vismach/5axis/table-rotary-tilting/xyzac-trt.ini gets the setp values and
the HOME_OFFSETs (GUI, PYVCP and POSTGUI lines dropped, linuxcncrsh as display).
After homing, M428 (tool-centre-point kinematics) and `G0 X10 Y5 Z-20 A30 C90`, the
joints LinuxCNC commands (joint.N.motor-pos-cmd) must be what the exported geometry
predicts (export_readers.trt_joints, written from trtfuncs.c; the rotary motors at the
angle minus HOME_OFFSET) within GETP_TOL (halcmd getp prints 7 significant digits), and
differ from the nominal geometry's joints by far more (0.75 mm, 0.05 / 0.07 deg). Run as root: LinuxCNC runs as the test user
(lcnc_common.USER); every wait is bounded.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
SAMPLE = Path("/usr/share/doc/linuxcnc/examples/sample-configs/sim/axis/vismach/5axis/"
              "table-rotary-tilting")
#: halcmd getp prints 7 significant digits: 1e-5 of 90 deg / 25 mm, halved, with margin
GETP_TOL = 2e-5
PROGRAM_POINT = (10.0, 5.0, -20.0)
PROGRAM_ANGLES = (30.0, 90.0)
ERRORS = {"EX0C": 400.0, "EY0C": -300.0, "EY0A": 250.0, "EZ0A": -350.0, "EA0A": 800.0,
          "EC0C": -1200.0}
MACHINE = """[machine]
name = "xyzac-trt sample geometry"
[axes.X]
travel_mm = [-200.0, 200.0]
[axes.Y]
travel_mm = [-100.0, 100.0]
[axes.Z]
travel_mm = [-120.0, 120.0]
[reference]
point_mm = [0.0, 0.0, 0.0]
[rotary]
kinematics = "xyzac-trt"
x_rot_point_mm = 0.0
y_rot_point_mm = 0.0
z_rot_point_mm = 0.0
y_offset_mm = 20.0
z_offset_mm = 10.0
tool_length_mm = 0.0
[rotary.A]
travel_deg = [-100.0, 50.0]
[rotary.C]
travel_deg = [-360.0, 360.0]
[indexer.C]
file = "indexer_C.csv"
"""
#: the B/C sample config (xyzbc-trt.ini): x-offset -20, z-offset -15 mm, B joint -100..50 deg
MACHINE_BC = (MACHINE.replace("xyzac-trt", "xyzbc-trt")
              .replace("y_offset_mm = 20.0\nz_offset_mm = 10.0", "x_offset_mm = -20.0\nz_offset_mm = -15.0")
              .replace("[rotary.A]", "[rotary.B]"))
MACHINES = {"xyzac-trt": MACHINE, "xyzbc-trt": MACHINE_BC}


def headless_ini(text: str, pins: dict[str, float], home: dict[int, float],
                 kind: str = "xyzac-trt") -> str:
    """The sample INI of `kind` (xyzac-trt / xyzbc-trt) without GUI lines, linuxcncrsh as
    display, our values."""
    # here, not at the top: this file also runs as a copy beside sim_drive.py (the drive),
    # where lcnc_common is not
    from lcnc_common import headless_halfile
    offsets = ("y-offset", "z-offset") if kind == "xyzac-trt" else ("x-offset", "z-offset")
    out, section = [], ""
    for line in text.splitlines():
        s = line.strip()
        if s.startswith("["):
            section = s
        key = s.split("=")[0].strip()
        if key in ("PYVCP", "POSTGUI_HALFILE", "OPEN_FILE", "TKPKG", "NGCGUI_FONT",
                   "NGCGUI_SUBFILE", "INTRO_GRAPHIC", "INTRO_TIME") or f"{kind}-gui" in s:
            continue
        if key == "DISPLAY" and section == "[DISPLAY]":
            line = "DISPLAY = linuxcncrsh"
        if key == "PROGRAM_PREFIX":
            line = "PROGRAM_PREFIX = ."
        line = headless_halfile(line)
        sets = [o for o in offsets if key == "HALCMD" and f"sets :{o}" in s]
        if sets:
            line = f"HALCMD = sets :{sets[0]} {pins[sets[0]]!r}"
        elif key == "HALCMD" and "-rot-point" in s:
            pin = s.split()[3].split(".")[1]
            line = f"HALCMD = setp {kind}-kins.{pin} {pins[pin]!r}"
        out.append(line)
        if key == "HALCMD" and s.endswith(":tool-offset  motion.tooloffset.z"):
            # the dropped GUI lines netted the kinematics' pins to these signals
            out.append(f"HALCMD = net :tool-offset  {kind}-kins.tool-offset")
            for o in offsets:
                out.append(f"HALCMD = net :{o}  {kind}-kins.{o}")
        m = section.startswith("[JOINT_") and int(section[7:-1])
        if s == section and m in home:
            out.append(f"HOME_OFFSET = {home[m]!r}")
    return "\n".join(out) + "\n"


def export_to_sample(work: Path, errors, kind: str = "xyzac-trt") -> tuple[dict[str, float],
                                                                          dict[int, float], Path]:
    """The virtual machine (MACHINES[kind] with `errors`, a FiveAxisErrors, or the bytes
    of a fitted table) as work/model_five.bin, `abbe export -f linuxcnc-trt` into work/trt, and a headless copy
    of the sample config (SAMPLE/<kind>.ini) taking its values in work/config. Returns
    (pins, HOME_OFFSETs, the INI)."""
    from export_readers import read_linuxcnc_trt
    from lcnc_common import cli

    from abbe.formats.five_axis_blob import write_five_blob
    from abbe.formats.machine import load_machine
    (work / "machine.toml").write_text(MACHINES[kind])
    geom = load_machine(work / "machine.toml").five_axis.geometry
    # errors: a FiveAxisErrors written as the table, or a table's bytes (a fitted one)
    blob = bytes(errors) if isinstance(errors, (bytes, bytearray)) else write_five_blob(geom, errors)
    (work / "model_five.bin").write_bytes(blob)
    cli("export", str(work / "model_five.bin"), "-f", "linuxcnc-trt", "-o", str(work / "trt"),
        "--machine", str(work / "machine.toml"))
    _comp, pins, home = read_linuxcnc_trt(work / "trt")
    cfg = work / "config"
    shutil.copytree(SAMPLE, cfg)
    ini = cfg / f"{kind}.ini"
    ini.write_text(headless_ini(ini.read_text(), pins, home, kind))
    return pins, home, ini


def run_drive(work: Path, script: Path, ini: Path, result: str, timeout: float) -> dict | None:
    """Copy sim_drive.py and `script` into work, hand everything to the LinuxCNC user and
    run `script --drive INI WORK` as that user (bounded). Returns work/result's JSON, or
    None (the logs printed) when the run failed or its JSON says not ok."""
    from lcnc_common import as_user, give, hal_clean
    shutil.copy(HERE / "sim_drive.py", work / "sim_drive.py")
    shutil.copy(script, work / script.name)
    for p in [work, *work.rglob("*")]:
        give(p)
    hal_clean()
    r = subprocess.run(as_user(["/usr/bin/python3", str(work / script.name), "--drive", str(ini),
                                str(work)]), cwd=work, capture_output=True, text=True,
                       timeout=timeout, stdin=subprocess.DEVNULL)
    path = work / result
    got = json.loads(path.read_text()) if path.exists() else {}
    if r.returncode != 0 or not got.get("ok") or got.get("errors"):
        lc = work / "linuxcnc.log"
        print(r.stdout[-3000:], r.stderr[-3000:], lc.read_text()[-3000:] if lc.exists() else "",
              got.get("errors"), sep="\n")
        return None
    return got


def drive(ini: Path, out: Path) -> None:
    """As the LinuxCNC user: start, home, M428, the move; write joints.json."""
    sys.path.insert(0, str(out))
    import linuxcnc  # noqa: F401
    from sim_drive import bounded, connect, getp, launch, power_on, stop_linuxcnc, wait_for

    import linuxcnc as lc
    bounded(240)
    proc, lc_log = launch(ini, out)
    res: dict = {"ok": False}
    try:
        s, c, e = connect(proc)
        power_on(c, s)
        c.mode(lc.MODE_MANUAL)
        c.wait_complete()
        c.home(-1)
        c.wait_complete()
        wait_for(lambda: (s.poll() or True) and all(s.homed[:5]), 60, "homing all joints")
        c.mode(lc.MODE_MDI)
        c.wait_complete()
        x, y, z = PROGRAM_POINT
        a, cc = PROGRAM_ANGLES
        for cmd in ("M428", f"G0 X{x} Y{y} Z{z} A0 C0", f"G0 A{a} C{cc}"):
            c.mdi(cmd)
            c.wait_complete(60)
            wait_for(lambda: (s.poll() or True) and s.interp_state == lc.INTERP_IDLE
                     and s.inpos, 60, cmd)
        res["kinstype"] = getp("motion.switchkins-type")
        res["motor"] = [getp(f"joint.{j}.motor-pos-cmd") for j in range(5)]
        res["pins"] = {p: getp(f"xyzac-trt-kins.{p}") for p in
                       ("x-rot-point", "y-rot-point", "z-rot-point", "y-offset", "z-offset")}
        err = e.poll()
        res["errors"] = [str(err)] if err else []
        res["ok"] = True
    finally:
        res["stop"] = stop_linuxcnc(proc)
        lc_log.close()
        (out / "joints.json").write_text(json.dumps(res, indent=2))


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--drive", nargs=2, type=Path, metavar=("INI", "OUT"))
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    if args.drive:
        drive(*args.drive)
        return 0
    sys.path.insert(0, str(HERE))
    sys.path.insert(0, str(HERE.parents[2] / "host_tools" / "tests"))
    import numpy as np
    from export_readers import trt_joints
    from lcnc_common import cleanup, work_dir

    work = work_dir("abbe-trt-")
    try:
        sys.path.insert(0, str(HERE.parents[2] / "host_tools"))
        from abbe.model.five_axis import FiveAxisErrors
        pins, home, ini = export_to_sample(work, FiveAxisErrors(location=ERRORS))
        got = run_drive(work, Path(__file__), ini, "joints.json", 300)
        if got is None:
            return 1
        want = trt_joints("xyzac-trt", pins, np.array([PROGRAM_POINT]), np.array([PROGRAM_ANGLES]))[0]
        nominal = trt_joints("xyzac-trt", {"x-rot-point": 0.0, "y-rot-point": 0.0,
                                           "z-rot-point": 0.0, "y-offset": 20.0, "z-offset": 10.0},
                             np.array([PROGRAM_POINT]), np.array([PROGRAM_ANGLES]))[0]
        motor = np.array(got["motor"])
        want_rot = np.array(PROGRAM_ANGLES) - np.array([home[3], home[4]])
        dev_lin = float(np.max(np.abs(motor[:3] - want)))
        dev_rot = float(np.max(np.abs(motor[3:] - want_rot)))
        shift = float(np.max(np.abs(want - nominal)))
        pins_dev = max(abs(got["pins"][k] - v) for k, v in pins.items())
        report = {"pins_written": pins, "pins_in_hal": got["pins"], "home_offset_deg": home,
                  "kinstype": got["kinstype"], "motor_pos_cmd": got["motor"],
                  "predicted_linear_mm": want.tolist(), "predicted_rotary_deg": want_rot.tolist(),
                  "nominal_linear_mm": nominal.tolist(), "max_dev_linear_mm": dev_lin,
                  "max_dev_rotary_deg": dev_rot, "exported_vs_nominal_mm": shift,
                  "errors": got["errors"], "stop": got["stop"]}
        print(json.dumps(report, indent=2))
        if args.json:
            args.json.write_text(json.dumps(report, indent=2) + "\n")
        rot_shift = float(np.min(np.abs(want_rot - np.array(PROGRAM_ANGLES))))
        ok = (pins_dev < 1e-9 and got["kinstype"] == 1 and dev_lin < GETP_TOL
              and dev_rot < GETP_TOL and shift > 0.1 and rot_shift > 100 * GETP_TOL
              and not got["errors"])
        print("trt_sim_check:", "PASS" if ok else "FAIL")
        return 0 if ok else 1
    finally:
        cleanup(work)


if __name__ == "__main__":
    sys.exit(main())
