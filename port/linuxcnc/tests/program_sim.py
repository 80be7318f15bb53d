#!/usr/bin/python3
"""The measurement programs of `abbe program` run in LinuxCNC's simulator (docs/programs.md,
"Checked in LinuxCNC"): wrap the run in `flock /tmp/abbe-linuxcnc.lock`.

  /usr/bin/python3 port/linuxcnc/tests/program_sim.py [--json FIGURES.json]

1. `abbe program` writes, for examples/vmc500/machine.toml (the ballbar feed raised to
   6000 mm/min to keep the run short): ISO 230-2 positioning of X (linear sequence) and
   of Y (pendulum sequence), and the XY ballbar circle, LinuxCNC dialect.
2. The simulator (port/linuxcnc/config without the abbe component) runs them;
   program_drive.py records the commanded path every ~2 ms.
3. Checks (host_tools/cases/program_path.py, shared with grblHAL's proof), from the
   recorded path and what the program text says (its comments: targets,
   runs, dwell, sequence; centre, radius, feed arcs): every target visited in order, each
   approached from the stated side, the dwell at each target as long as stated, every
   point inside the machine file's travel; the circle's recorded arc covers the data arc
   [0, 360] deg with the feed-in and feed-out arcs each side, CCW then CW, on the radius,
   at the feed, with the pause between the runs and one programmed stop.
4. Closed loop: the capture positions of the X program, with the virtual machine's
   errors applied (examples/vmc500/truth, abbe.sim), written as a Renishaw .rtl file
   and read by `abbe iso230-2`, give back the machine's positioning error within the
   noise (host_tools/cases/closed_loop.py, run with the .venv's python).
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

from lcnc_common import (ABBE_CLI, REPO, TestFailure, as_user, check, cleanup, cli, give,
                         hal_clean, log, main_wrapper, work_dir)

sys.path.insert(0, str(REPO / "host_tools"))
from cases.program_path import check_ballbar, check_positioning, params_of  # noqa: E402

HERE = Path(__file__).resolve().parent
CONFIG = HERE.parent / "config"
MACHINE = REPO / "examples" / "vmc500" / "machine.toml"
VENV_PY = REPO / ".venv" / "bin" / "python"
PROGRAMS = {
    "x_linear": ["--test", "positioning", "--axis", "X", "--feed", "12000", "--dwell-s", "0.3"],
    "y_pendulum": ["--test", "positioning", "--axis", "Y", "--sequence", "pendulum",
                   "--feed", "3000", "--dwell-s", "0.2"],
    "ballbar_xy": ["--test", "ballbar", "--plane", "XY", "--pause-s", "1"],
}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", type=Path, help="also write the figures here")
    args = ap.parse_args()
    work = work_dir("abbe-programs-")
    try:
        m = tomllib.loads(MACHINE.read_text())
        travel = {a: m["axes"][a]["travel_mm"] for a in "XYZ"}
        mf = work / "machine.toml"
        mf.write_text(MACHINE.read_text().replace("feed_mm_min = 200.0", "feed_mm_min = 6000.0"))
        progs = []
        for name, opts in PROGRAMS.items():
            p = work / f"{name}.ngc"
            cli("program", str(mf), *opts, "--dialect", "linuxcnc", "-o", str(p))
            progs.append(p)
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
        log("LinuxCNC simulator: " + ", ".join(p.name for p in progs))
        proc = subprocess.Popen(as_user(["/usr/bin/python3", str(work / "program_drive.py"),
                                         "--ini", str(ini), "--out", str(work), "--timeout", "600",
                                         *map(str, progs)]),
                                cwd=work, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        try:
            out, err = proc.communicate(timeout=660)
        except subprocess.TimeoutExpired:
            proc.terminate()
            out, err = proc.communicate(timeout=90)
        drive = json.loads((work / "drive.json").read_text()) if (work / "drive.json").exists() else {}
        if proc.returncode != 0 or not drive.get("ok"):
            lc = (work / "linuxcnc.log").read_text() if (work / "linuxcnc.log").exists() else ""
            raise TestFailure(f"driving LinuxCNC failed: {drive.get('errors')}\n{out}\n{err}\n"
                              f"--- linuxcnc.log ---\n{lc[-3000:]}")
        check(not drive.get("operator_errors"), f"LinuxCNC errors: {drive.get('operator_errors')}")
        figures = {}
        for p in progs:
            rec = json.loads((work / f"{p.stem}.path.json").read_text())
            prm = params_of(p.read_text())
            if prm["test"] == "ballbar":
                figures[p.stem] = check_ballbar(rec, prm, travel)
            else:
                axis = prm["axis"]
                line = m["laser"][axis]["start_mm"]
                figures[p.stem] = check_positioning(rec, prm, travel, line)
            log(f"{p.stem}: OK " + json.dumps({k: v for k, v in figures[p.stem].items()
                                                if k != "captures"}))
        caps = work / "x_captures.json"
        caps.write_text(json.dumps({"targets_mm": params_of(progs[0].read_text())["targets_mm"],
                                    "captures": figures["x_linear"]["captures"]}))
        res = subprocess.run([str(VENV_PY), "-m", "cases.closed_loop", str(caps),
                              "--truth", str(REPO / "examples/vmc500/truth/truth.json"),
                              "--abbe", str(ABBE_CLI), "--out", str(work / "x_closed_loop.rtl")],
                             cwd=REPO / "host_tools", capture_output=True, text=True, timeout=300)
        check(res.returncode == 0, f"closed loop failed:\n{res.stdout}\n{res.stderr}")
        loop = json.loads(res.stdout)
        log(f"closed loop: {json.dumps(loop['summary'])}")
        for k in figures:
            figures[k].pop("captures", None)
        figures["closed_loop"] = loop["summary"]
        if args.json:
            args.json.parent.mkdir(parents=True, exist_ok=True)
            args.json.write_text(json.dumps(figures, indent=1))
        log("measurement programs in the LinuxCNC simulator: OK")
    finally:
        hal_clean()
        cleanup(work)


if __name__ == "__main__":
    main_wrapper(main)
