"""Closed loop of a positioning program (port/linuxcnc/tests/program_sim.py, step 4):
the captures of a program run in LinuxCNC's simulator, with the virtual machine's errors
applied, written as a Renishaw .rtl file and read back by ``abbe iso230-2``, must give
the virtual machine's positioning error within the noise.

  python -m cases.closed_loop CAPTURES.json --truth truth.json --abbe .venv/bin/abbe
      --out x.rtl

CAPTURES.json: ``targets_mm`` (the program's targets, text) and ``captures``: per dwell
``target`` (index), ``dir`` (+1 / -1), ``run``, ``pos_mm`` (the recorded commanded
position). The laser reads the X line through the reference point: reading =
-(E_x(p, s) - E_x(p0, s0)) (docs/formats.md, "6D laser"), p0 the first capture, s the
approach's backlash state (+1 / -1), plus Gaussian noise (0.2 um, seeded); the deviation
written is (recorded position - target) + reading. The truth compared with: the same
machine at the exact targets without noise.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from abbe.sim.truth import load_truth
from abbe.sim.virtual_machine import VirtualMachine
from cases.renishaw import rtl_from_updown

NOISE_UM = 0.2


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("captures", type=Path)
    ap.add_argument("--truth", type=Path, required=True)
    ap.add_argument("--abbe", required=True)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--seed", type=int, default=5)
    a = ap.parse_args(argv)
    d = json.loads(a.captures.read_text())
    targets = np.array([float(v) for v in d["targets_mm"].split()])
    caps = d["captures"]
    vm = VirtualMachine(load_truth(a.truth))
    pos = np.array([c["pos_mm"] for c in caps])
    s = np.zeros((len(caps), 3))
    s[:, 0] = [c["dir"] for c in caps]
    ex = vm.tool_error_um(pos, s)[:, 0]
    rng = np.random.default_rng(a.seed)
    read = -(ex - ex[0]) + rng.normal(0.0, NOISE_UM, len(caps))
    runs = max(c["run"] for c in caps)
    up, down = np.zeros((runs, targets.size)), np.zeros((runs, targets.size))
    for c, v, p in zip(caps, read, pos):
        dev = (p[0] - targets[c["target"]]) * 1000.0 + v
        (up if c["dir"] > 0 else down)[c["run"] - 1, c["target"]] = dev
    a.out.write_text(rtl_from_updown(targets, up, down), newline="")
    res = subprocess.run([a.abbe, "iso230-2", str(a.out), "--json", "-"], capture_output=True,
                         text=True)
    if res.returncode != 0:
        print(res.stderr, file=sys.stderr)
        return 1
    got = json.loads(res.stdout)
    # the truth: the machine at the exact targets, no noise, laser zero at (target 1, +)
    p_t = np.zeros((targets.size, 3))
    p_t[:] = pos[0]
    p_t[:, 0] = targets
    e_up = vm.tool_error_um(p_t, np.tile([1.0, 0, 0], (targets.size, 1)))[:, 0]
    e_dn = vm.tool_error_um(p_t, np.tile([-1.0, 0, 0], (targets.size, 1)))[:, 0]
    t_up, t_dn = -(e_up - e_up[0]), -(e_dn - e_up[0])
    g_up = np.array([t["mean_up_um"] for t in got["targets"]])
    g_dn = np.array([t["mean_down_um"] for t in got["targets"]])
    bound = 4.0 * NOISE_UM / np.sqrt(runs)
    mid = 0.5 * (t_up + t_dn)
    truth = {"B_um": float(np.max(np.abs(t_up - t_dn))),
             "E_um": float(max(t_up.max(), t_dn.max()) - min(t_up.min(), t_dn.min())),
             "M_um": float(mid.max() - mid.min())}
    summary = {"runs": runs, "targets": int(targets.size), "noise_um": NOISE_UM,
               "bound_um": round(float(bound), 4),
               "max_mean_error_um": round(float(max(np.abs(g_up - t_up).max(),
                                                    np.abs(g_dn - t_dn).max())), 4),
               **{k: {"abbe": round(got[k], 4), "machine": round(v, 4)} for k, v in truth.items()}}
    ok = summary["max_mean_error_um"] <= bound and all(
        abs(got[k] - v) <= 2 * bound for k, v in truth.items())
    print(json.dumps({"ok": bool(ok), "summary": summary}))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
