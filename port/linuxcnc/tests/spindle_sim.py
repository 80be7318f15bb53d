#!/usr/bin/python3
"""The ISO 230-3 spindle program of `abbe program --test iso230-3-spindle` run in LinuxCNC's
simulator (docs/thermal.md): wrap the run in `flock /tmp/abbe-linuxcnc.lock`.

  /usr/bin/python3 port/linuxcnc/tests/spindle_sim.py [--json FIGURES.json]

The real test lasts 46 h; here the same program with two speeds (1250, 3500 rpm) and short
phases (0.0025 h = 9 s on, 0.0035 h = 12.6 s off, a reading every 3 s: whole readings on,
four and a remainder off; on and off differ by more than twice the tolerance, so swapped
phases or a missing reading fail; CI time: the phase length itself is not what is checked), for
examples/vmc500/machine.toml, LinuxCNC dialect, run by program_drive.py (the vmc500
simulator config without the abbe component), which records the commanded position and
the commanded spindle (linuxcnc.stat spindle[0] speed and direction) every ~2 ms. Checks,
from the recorded run and what the program text says (its comments): the spindle runs
forward at each stated speed, in the stated order, for on_s, then stops for off_s (each
within 1.5 s: the polling and the simulator's task cycle), the position stays at the
machine file's reference point while the spindle phases run, the spindle is stopped at
the end, no LinuxCNC error.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import sys
import tomllib
from pathlib import Path

from lcnc_common import check, cleanup, cli, drive_programs, give, hal_clean, log, main_wrapper, work_dir

HERE = Path(__file__).resolve().parent
CONFIG = HERE.parent / "config"
MACHINE = HERE.parents[2] / "examples" / "vmc500" / "machine.toml"
SPEEDS = (1250.0, 3500.0)
TOL_S = 1.5


def phases(t: list[float], spindle: list[list[float]]) -> list[tuple[float, float, float]]:
    """(speed rpm, start s, end s) of every run of constant commanded spindle speed
    (0 when stopped)."""
    out: list[list[float]] = []
    for ti, (rpm, direction) in zip(t, spindle):
        v = rpm if direction != 0 else 0.0
        if not out or abs(out[-1][0] - v) > 0.5:
            out.append([v, ti, ti])
        else:
            out[-1][2] = ti
    return [tuple(p) for p in out]  # type: ignore[misc]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", type=Path, help="also write the figures here")
    args = ap.parse_args()
    work = work_dir("abbe-spindle-")
    try:
        m = tomllib.loads(MACHINE.read_text())
        ref = m["reference"]["point_mm"]
        prog = work / "iso230_3.ngc"
        cli("program", str(MACHINE), "--test", "iso230-3-spindle", "--dialect", "linuxcnc",
            "--speeds", ",".join(f"{v:g}" for v in SPEEDS), "--on-h", "0.0025", "--off-h", "0.0035",
            "--reading-s", "3", "-o", str(prog))
        text = prog.read_text()
        on_s = float(re.search(r"^\(on_s = ([0-9.]+)\)", text, re.M).group(1))
        off_s = float(re.search(r"^\(off_s = ([0-9.]+)\)", text, re.M).group(1))
        stated = [float(v) for v in re.search(r"^\(speeds_rpm = ([0-9. ]+)\)", text, re.M)
                  .group(1).split()]
        check(stated == list(SPEEDS), f"the program states speeds {stated}, asked {SPEEDS}")
        cfg = work / "config"
        shutil.copytree(CONFIG, cfg)
        ini = cfg / "vmc500.ini"
        ini.write_text("\n".join(ln for ln in ini.read_text().splitlines()
                                 if ln.strip() != "HALFILE = abbe.hal") + "\n")
        for f in ("sim_drive.py", "program_drive.py"):
            shutil.copy(HERE / f, work / f)
        for p in [work, *work.rglob("*")]:
            give(p)
        hal_clean()
        log(f"LinuxCNC simulator: {prog.name} ({len(SPEEDS)} speeds, {on_s:g} s on, {off_s:g} s off)")
        drive_programs(work, ini, ["--program-timeout", "400", str(prog)])
        rec = json.loads((work / f"{prog.stem}.path.json").read_text())
        ph = phases(rec["t_s"], rec["spindle"])
        ph = [p for p in ph if p[2] - p[1] > 0.2 or p[0] != 0.0]  # the start's stopped spindle
        on = [p for p in ph if p[0] != 0.0]
        check([round(p[0]) for p in on] == [round(v) for v in SPEEDS],
              f"spindle speeds run {[p[0] for p in on]}, the program states {list(SPEEDS)}")
        figures = {"on_s": on_s, "off_s": off_s, "phases": []}
        for k, p in enumerate(ph):
            if p[0] == 0.0 and k == 0:
                continue  # before the first M3 (the move to the reference point)
            dur = p[2] - p[1]
            if k == len(ph) - 1 and p[0] == 0.0:
                # the last stop: the program's dwell, then M2 ends the recording
                want = off_s
            else:
                want = on_s if p[0] != 0.0 else off_s
            figures["phases"].append({"rpm": p[0], "start_s": round(p[1], 3), "seconds": round(dur, 3)})
            check(abs(dur - want) <= TOL_S, f"spindle at {p[0]:g} rpm for {dur:.2f} s, expected {want:g} s")
            idx = [i for i, ti in enumerate(rec["t_s"]) if p[1] <= ti <= p[2]]
            dev = max(max(abs(rec["pos_mm"][i][a] - ref[a]) for a in range(3)) for i in idx)
            check(dev <= 1e-3, f"the position left the reference point by {dev:.4f} mm during a phase")
        check(rec["spindle"][-1][1] == 0, "the spindle still runs at the end")
        log("spindle program in the LinuxCNC simulator: OK " + json.dumps(figures))
        if args.json:
            args.json.parent.mkdir(parents=True, exist_ok=True)
            args.json.write_text(json.dumps(figures, indent=1))
    finally:
        hal_clean()
        cleanup(work)


if __name__ == "__main__":
    main_wrapper(main)
