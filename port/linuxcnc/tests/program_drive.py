#!/usr/bin/python3
"""Run measurement programs in the LinuxCNC simulator and record the commanded path
(runs as the LinuxCNC user; program_sim.py copies it beside sim_drive.py and starts it).

  program_drive.py --ini WORK/config/vmc500.ini --out WORK [--setp PROG:PIN=VALUE] PROG1.ngc ...

Starts `linuxcnc INI` headless (linuxcncrsh), e-stop reset, machine on, home all, then
runs each program, polling linuxcnc.stat every ~2 ms: time, the commanded position
(stat.position, machine coordinates: X Y Z and A B C; stat.joint_position, the joints), the
line being executed; a programmed stop (M0)
is answered with a resume, its time recorded. Writes NAME.path.json per program and
drive.json. LinuxCNC start, wait and stop: sim_drive.py's helpers.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import linuxcnc

from sim_drive import (Abort, bounded, connect, halcmd, home_all, launch, log, operator_errors,
                       power_on, shutdown)


def record(c, s, program: Path, timeout: float) -> dict:
    c.mode(linuxcnc.MODE_AUTO)
    c.wait_complete()
    c.program_open(str(program))
    c.wait_complete()
    t, pos, line, stops, rot, joints, spindle = [], [], [], [], [], [], []
    t0 = time.monotonic()
    c.auto(linuxcnc.AUTO_RUN, 0)
    started = False
    while True:
        s.poll()
        now = time.monotonic() - t0  # after the poll: the time of the state it read
        if now > timeout:
            raise RuntimeError(f"{program.name} did not finish within {timeout:.0f} s (at line "
                               f"{s.current_line}, position {list(s.position[:6])}, interp "
                               f"{s.interp_state}, paused {s.task_paused})")
        t.append(now)
        pos.append(list(s.position[:3]))
        rot.append(list(s.position[3:6]))  # A, B, C (deg): the five-axis programs
        joints.append(list(s.joint_position[:s.joints]))
        line.append(int(s.current_line))
        sp = s.spindle[0] if s.spindles else {}
        spindle.append([float(sp.get("speed", 0.0)), int(sp.get("direction", 0))])
        if s.interp_state != linuxcnc.INTERP_IDLE:
            started = True
        if s.task_paused or s.interp_state == linuxcnc.INTERP_PAUSED:
            if not stops or stops[-1][1] is not None:
                stops.append([now, None])
                time.sleep(0.2)  # the operator fits the ballbar
                c.auto(linuxcnc.AUTO_RESUME)
        elif stops and stops[-1][1] is None:
            stops[-1][1] = now
        if started and s.interp_state == linuxcnc.INTERP_IDLE and s.queue == 0 and s.inpos:
            break
        if not started and now > 10:
            raise RuntimeError(f"{program.name} did not start")
        time.sleep(0.002)
    return {"program": program.name, "t_s": t, "pos_mm": pos, "line": line, "stops": stops,
            "seconds": t[-1], "abc_deg": rot, "joints": joints,
            "spindle": spindle}  # commanded speed (rpm) and direction (1 M3, 0 stopped)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--ini", type=Path, required=True)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--program-timeout", type=float, default=300.0)
    ap.add_argument("--timeout", type=int, default=900, help="for everything, s")
    ap.add_argument("--setp", action="append", default=[], metavar="PROG:PIN=VALUE",
                    help="halcmd setp PIN VALUE before running the program named PROG")
    ap.add_argument("programs", type=Path, nargs="+")
    args = ap.parse_args()

    bounded(args.timeout)
    ini, out = args.ini.resolve(), args.out.resolve()
    result = {"ok": False, "errors": [], "programs": {}}
    proc, lc_log = launch(ini, out)
    try:
        s, c, e = connect(proc)
        power_on(c, s)
        home_all(c, s)
        for prog in args.programs:
            for sp in args.setp:
                name, _, assign = sp.partition(":")
                if name == prog.name:
                    halcmd("setp", *assign.split("=", 1))
            r = record(c, s, prog.resolve(), args.program_timeout)
            (out / f"{prog.stem}.path.json").write_text(json.dumps(r))
            result["programs"][prog.name] = {"seconds": r["seconds"], "samples": len(r["t_s"]),
                                             "stops": r["stops"]}
            log(f"{prog.name}: {r['seconds']:.1f} s, {len(r['t_s'])} samples")
        result["operator_errors"] = operator_errors(e)
        result["ok"] = True
    except (Exception, SystemExit, Abort) as exc:
        result["errors"].append(f"{type(exc).__name__}: {exc}")
        log(f"ERROR {exc}")
    finally:
        shutdown(proc, lc_log, result)
        (out / "drive.json").write_text(json.dumps(result, indent=1))
    return 0 if result["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
