#!/usr/bin/python3
"""The measurement programs of `abbe program` run in LinuxCNC's simulator (docs/programs.md,
"Checked in LinuxCNC"): wrap the run in `flock /tmp/abbe-linuxcnc.lock`.

  /usr/bin/python3 port/linuxcnc/tests/program_sim.py [--json FIGURES.json]

1. `abbe program` writes, for examples/vmc500/machine.toml (the ballbar feed raised to
   6000 mm/min to keep the run short): ISO 230-2 positioning of X (linear sequence) and
   of Y (pendulum sequence), and the XY ballbar circle, LinuxCNC dialect.
2. The simulator (port/linuxcnc/config without the abbe component) runs them;
   program_drive.py records the commanded path every ~2 ms.
3. Checks, from the recorded path and what the program text says (its comments: targets,
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
import re
import shutil
import subprocess
import tomllib
from pathlib import Path

import numpy as np

from lcnc_common import (ABBE_CLI, REPO, TestFailure, as_user, check, cleanup, cli, give,
                         hal_clean, log, main_wrapper, work_dir)

HERE = Path(__file__).resolve().parent
CONFIG = HERE.parent / "config"
MACHINE = REPO / "examples" / "vmc500" / "machine.toml"
VENV_PY = REPO / ".venv" / "bin" / "python"
#: Positions of a stationary trajectory are exactly equal; a capture dwell lasts at
#: least half the programmed dwell (anything shorter is a stop at an overrun point).
STILL_MM = 1e-9

def bracket(t: np.ndarray, a: int, b: int) -> tuple[float, float]:
    """A still interval's duration between the polled samples: at least t[b] - t[a], at most
    from the sample before to the sample after (a late poll only widens the bracket)."""
    return float(t[b] - t[a]), float(t[min(b + 1, len(t) - 1)] - t[max(a - 1, 0)])


def dwell_ok(lo: float, hi: float, want: float) -> bool:
    """The stated dwell lies inside the bracket, or at most 0.3 s (the planner's start) below
    its lower end."""
    return hi >= want - 1e-3 and lo <= want + 0.3

PROGRAMS = {
    "x_linear": ["--test", "positioning", "--axis", "X", "--feed", "12000", "--dwell-s", "0.3"],
    "y_pendulum": ["--test", "positioning", "--axis", "Y", "--sequence", "pendulum",
                   "--feed", "3000", "--dwell-s", "0.2"],
    "ballbar_xy": ["--test", "ballbar", "--plane", "XY", "--pause-s", "1"],
}


def params_of(text: str) -> dict[str, str]:
    """``(key = value)`` header comments and the ``(targets mm: ...)`` lines of a program."""
    p = dict(re.findall(r"^\((\w+) = ([^)]*)\)$", text, flags=re.M))
    t = re.findall(r"^\(targets mm: ([^)]*)\)$", text, flags=re.M)
    if t:
        p["targets_mm"] = " ".join(t)
    return p


def segments(t: np.ndarray, pos: np.ndarray) -> list[tuple[int, int]]:
    """Runs of samples [i, j] with the commanded position unchanged."""
    still = np.all(np.abs(np.diff(pos, axis=0)) <= STILL_MM, axis=1)
    out, i = [], None
    for k, s in enumerate(still):
        if s and i is None:
            i = k
        elif not s and i is not None:
            out.append((i, k))
            i = None
    if i is not None:
        out.append((i, len(t) - 1))
    return out


def in_travel(pos: np.ndarray, travel: dict) -> None:
    for j, a in enumerate("XYZ"):
        lo, hi = travel[a]
        check(pos[:, j].min() >= lo - 1e-6 and pos[:, j].max() <= hi + 1e-6,
              f"the path leaves the {a} travel [{lo}, {hi}]: {pos[:, j].min():.4f} .. "
              f"{pos[:, j].max():.4f}")


def check_positioning(rec: dict, prm: dict, travel: dict, line_mm: list[float]) -> dict:
    t, pos = np.array(rec["t_s"]), np.array(rec["pos_mm"])
    in_travel(pos, travel)
    j = "XYZ".index(prm["axis"])
    targets = np.array([float(v) for v in prm["targets_mm"].split()])
    runs, dwell = int(prm["runs"]), float(prm["dwell_s"])
    T = targets.size
    if prm["sequence"] == "linear":
        want = [(i, d, r) for r in range(1, runs + 1)
                for d, idx in ((+1, range(T)), (-1, range(T - 1, -1, -1))) for i in idx]
    else:
        want = [(i, d, r) for i in range(T) for r in range(1, runs + 1) for d in (+1, -1)]
    others = [k for k in range(3) if k != j]
    caps = []
    for a, b in segments(t, pos):
        dur = t[b] - t[a]
        on_line = all(abs(pos[a, k] - line_mm[k]) < 1e-6 for k in others)
        if dur >= 0.5 * dwell and on_line:
            caps.append((a, b, dur))
    check(len(caps) == len(want), f"{rec['program']}: {len(caps)} dwells on the line, the "
          f"program states {len(want)} captures")
    out, durs = [], []
    for (a, b, dur), (i, d, r) in zip(caps, want):
        x = pos[a, j]
        check(abs(x - targets[i]) < 1e-6, f"{rec['program']}: capture {len(out) + 1} at "
              f"{x:.4f} mm, expected target {i + 1} = {targets[i]:.4f} mm (run {r}, {d:+d})")
        prev = pos[:a + 1, j]
        moved = np.flatnonzero(np.abs(prev - x) > 1e-6)
        check(moved.size > 0, f"{rec['program']}: no approach before capture {len(out) + 1}")
        side = np.sign(x - prev[moved[-1]])
        check(side == d, f"{rec['program']}: target {i + 1} run {r} approached from the "
              f"{'+' if side < 0 else '-'} side, expected a {'+' if d > 0 else '-'} approach")
        lo_s, hi_s = bracket(t, a, b)
        check(dwell_ok(lo_s, hi_s, dwell), f"{rec['program']}: dwell of {lo_s:.3f}..{hi_s:.3f} s "
              f"at target {i + 1}, programmed {dwell} s")
        durs.append(dur)
        out.append({"target": i, "dir": d, "run": r, "pos_mm": pos[a].tolist(),
                    "dwell_s": round(float(dur), 4)})
    return {"captures": out, "n": len(out), "dwell_s": {"min": round(min(durs), 4),
                                                       "max": round(max(durs), 4)},
            "seconds": round(rec["seconds"], 2)}


def check_ballbar(rec: dict, prm: dict, travel: dict) -> dict:
    t, pos = np.array(rec["t_s"]), np.array(rec["pos_mm"])
    in_travel(pos, travel)
    c = np.array([float(v) for v in prm["center_mm"].split()])
    R, arc, pause = float(prm["radius_mm"]), float(prm["feed_arc_deg"]), float(prm["pause_s"])
    feed = float(prm["feed_mm_min"])
    check(len(rec["stops"]) == 1, f"ballbar: {len(rec['stops'])} programmed stops, expected 1")
    k0 = int(np.searchsorted(t, rec["stops"][0][0]))  # at the start point, the ballbar fitted
    d = pos[k0:, :2] - c[:2]
    r = np.hypot(d[:, 0], d[:, 1])
    check(np.all(np.abs(pos[k0:, 2] - c[2]) < 1e-6), "ballbar: Z moves during the circle")
    check(np.max(np.abs(r - R)) < 0.01, f"ballbar: the path leaves the radius by "
          f"{np.max(np.abs(r - R)) * 1000:.1f} um")
    th = np.degrees(np.unwrap(np.arctan2(d[:, 1], d[:, 0])))
    th += 360.0 * np.round((-arc - th[0]) / 360.0)  # the start is the feed-in arc's start
    top = int(np.argmax(th))
    ccw, cw = th[:top + 1], th[top:]
    check(abs(ccw[0] + arc) < 0.01, f"ballbar: the CCW run starts at {ccw[0]:.2f} deg, "
          f"expected {-arc}")
    check(abs(ccw[-1] - (360 + arc)) < 0.01 and abs(cw[-1] + arc) < 0.01,
          f"ballbar: CCW ends at {ccw[-1]:.2f}, CW at {cw[-1]:.2f} deg; expected "
          f"{360 + arc} and {-arc}")
    check(np.all(np.diff(ccw) >= -1e-9) and np.all(np.diff(cw) <= 1e-9),
          "ballbar: the angle turns back inside a run")
    # the pause at the top, and the feed on the data arc
    seg = [(a, b) for a, b in segments(t[k0:], pos[k0:]) if a <= top <= b]
    check(len(seg) == 1, "ballbar: no pause between the runs")
    lo_s, hi_s = bracket(t, k0 + seg[0][0], k0 + seg[0][1])
    paused = lo_s
    check(dwell_ok(lo_s, hi_s, pause), f"ballbar: pause {lo_s:.3f}..{hi_s:.3f} s between the "
          f"runs, programmed {pause} s")
    tt = t[k0:]
    m = (ccw >= 0) & (ccw <= 360)
    rate = np.diff(ccw[m]) / np.diff(tt[:top + 1][m])
    want = np.degrees(feed / 60.0 / R)
    med = float(np.median(rate[np.isfinite(rate)]))
    check(abs(med / want - 1) < 0.05, f"ballbar: {med:.2f} deg/s on the data arc, the feed "
          f"gives {want:.2f}")
    return {"ccw_deg": [round(float(ccw[0]), 3), round(float(ccw[-1]), 3)],
            "cw_deg": [round(float(cw[0]), 3), round(float(cw[-1]), 3)],
            "radius_dev_max_um": round(float(np.max(np.abs(r - R)) * 1000), 4),
            "pause_s": round(float(paused), 3), "deg_per_s": round(med, 3),
            "seconds": round(rec["seconds"], 2)}


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
