#!/usr/bin/python3
"""A measurement campaign of kinds_sim.py's TRUE machines, for `abbe fit` (issue 39).

  python3 port/linuxcnc/tests/kinds_campaign.py --kind max5 --out DIR [--seed N]

Per sample (bridgemill / 5axiskins, max5 / maxkins, xyzab-tdr): a machine file with the
sample's nominal geometry as a `[chain]` (docs/formats.md "Kinematic chain"; the
directions and pivots that reproduce the modules' inverse kinematics, kinds_sim.py), and
the campaign files it names, written by the INDEPENDENT generator
host_tools/cases/chain_generator.py (which imports nothing of abbe) from the location
errors kinds_sim.py injects (its TRUE machine):

- probing S1: a 12.5 mm sphere (1.5 mm stylus) probed at the generator's grid of angle
  pairs, five touches per position (one from above, four at 30 deg elevation), each
  touch coordinate with PROBE_NOISE_UM of noise; S2 the same sphere 100 mm higher; with a
  tool-side rotary axis S3, a stylus 100 mm longer (what makes a head's line lengths
  observable);
- rtest R1: an R-test under tool-centre-point control on S1's sphere, RTEST_NOISE_UM of
  noise per reading;
- every sphere is placed off its nominal centre by a random set-up error (SETUP_UM per
  coordinate, the R-test's nest alike through its zeroing): the fit does not know them.

The truth is handed to the generator in its own convention (angular zeros about the
positive machine axis); kinds_sim.py writes a workpiece-side axis' zero about the turned
direction, so it changes sign for a -1 axis there. :func:`check_truth` proves the two
forward kinematics (the generator's and kinds_sim.py's, both written without abbe) put
the tool at the same workpiece point at random poses, so the campaign measures the very
machine the LinuxCNC test judges the tool tip on.

Imports nothing of abbe: runs with the system python3 (numpy, tomllib).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parents[2] / "host_tools"))

import kinds_sim as ks  # noqa: E402
from cases import chain_generator as gen  # noqa: E402

SPHERE_MM = {"bridgemill": (40.0, 20.0, -150.0), "max5": (50.0, 20.0, -100.0),
             "xyzab-tdr": (40.0, 20.0, 30.0)}
SPHERE_RADIUS_MM, STYLUS_RADIUS_MM = 12.5, 1.5
PROBE_NOISE_UM = 0.3        # per touch coordinate
RTEST_NOISE_UM = 0.3        # per reading coordinate
SETUP_UM = 50.0             # sphere (and R-test nest) placement, per coordinate
TRUTH_TOL_MM = 1e-9         # the two forward kinematics must agree to this

# the samples as chains: the directions and pivots of kinds_sim.py's modules (docs/linuxcnc.md)
_LIMITS = ('[axes.X]\ntravel_mm = [-500.0, 500.0]\n[axes.Y]\ntravel_mm = [-500.0, 500.0]\n'
           '[axes.Z]\ntravel_mm = [-600.0, 300.0]\n[reference]\npoint_mm = [0.0, 0.0, 0.0]\n')


def chain_toml(name: str) -> str:
    """The `[machine]`, `[axes]`, `[reference]` and `[chain]` of a sample (no campaign)."""
    if name == "bridgemill":
        L = ks.PIVOT_BRIDGE
        chain = (f'name = "5axiskins"\norder = ["X", "Y", "Z", "C", "B"]\n'
                 f'[chain.C]\ndirection = "+Z"\npivot_mm = [0.0, 0.0, {L!r}]\ntravel_deg = [-360.0, 360.0]\n'
                 f'[chain.B]\ndirection = "-Y"\npivot_mm = [0.0, 0.0, {L!r}]\ntravel_deg = [-120.0, 120.0]\n')
    elif name == "max5":
        M = ks.PIVOT_MAX5
        chain = (f'name = "maxkins"\norder = ["C", "X", "Y", "Z", "B"]\n'
                 f'[chain.C]\ndirection = "-Z"\npivot_mm = [0.0, 0.0, 0.0]\ntravel_deg = [-3600.0, 3600.0]\n'
                 f'[chain.B]\ndirection = "-Y"\npivot_mm = [0.0, 0.0, {M!r}]\ntravel_deg = [-90.0, 90.0]\n')
    else:
        g = ks.CASES["xyzab-tdr"].geometry
        rp, dz = g["rot_point"], g["z_offset"]
        chain = (f'name = "xyzab-tdr"\norder = ["A", "B", "X", "Y", "Z"]\n'
                 f'[chain.A]\ndirection = "-X"\npivot_mm = [{rp!r}, {rp!r}, {rp + dz!r}]\n'
                 f'travel_deg = [-3600.0, 3600.0]\n'
                 f'[chain.B]\ndirection = "-Y"\npivot_mm = [{rp!r}, {rp!r}, {rp!r}]\n'
                 f'travel_deg = [-180.0, 180.0]\n')
    return f'[machine]\nname = "LinuxCNC sample {name}"\n{_LIMITS}[chain]\n{chain}'


def true_location(case: ks.Case, gch: gen.GenChain) -> dict[str, float]:
    """kinds_sim's injected errors in the generator's convention (um, urad)."""
    work = {a.name: a for a in gch.work}
    out = {}
    for n, v in case.errors.items():
        ax = n[-1]
        flip = n[1] == ax and ax in work and work[ax].sign < 0
        out[n] = -v if flip else v
    return out


def generator_tip(gch: gen.GenChain, loc: dict[str, float], q: np.ndarray, pair: np.ndarray
                  ) -> np.ndarray:
    """The tool tip in workpiece coordinates (mm) by the generator's kinematics at machine
    position q (mm) and angle pair (deg, alphabetical)."""
    tip = q + gen._pt(gen.tool_matrix(gch, pair, loc), np.zeros(3))
    W = gen.work_matrix(gch, pair, loc)
    return W[:3, :3].T @ (tip - W[:3, 3])


def check_truth(case: ks.Case, gch: gen.GenChain, loc: dict[str, float], n: int = 40) -> float:
    """Max distance (mm) between the generator's and kinds_sim's tool tips at random poses
    with the injected errors; raises if above TRUTH_TOL_MM or if the errors move nothing."""
    rng = np.random.default_rng(7)
    worst, moved = 0.0, 0.0
    for _ in range(n):
        q = rng.uniform(-100.0, 100.0, 3)
        pair = rng.uniform(-80.0, 80.0, 2)
        joints = {"X": q[0], "Y": q[1], "Z": q[2], **dict(zip(gch.names, pair))}
        a = generator_tip(gch, loc, q, pair)
        b = ks.tool_in_workpiece(case, joints, case.errors)
        worst = max(worst, float(np.linalg.norm(a - b)))
        moved = max(moved, float(np.linalg.norm(b - ks.tool_in_workpiece(case, joints, {}))))
    if worst > TRUTH_TOL_MM or moved < 1e-3:
        raise AssertionError(f"{case.name}: the generator's true machine is not kinds_sim's: "
                             f"{worst:.3g} mm apart (errors move the tip {moved:.3g} mm)")
    return worst


def _vec(v: np.ndarray) -> str:
    """A TOML array of floats (repr of Python floats: numpy 2 would print np.float64(...))."""
    return "[" + ", ".join(repr(float(x)) for x in v) + "]"


def _touch_dirs() -> np.ndarray:
    e = np.radians(30.0)
    return np.array([[0.0, 0.0, 1.0]] + [[np.cos(e) * np.cos(u), np.cos(e) * np.sin(u), np.sin(e)]
                                         for u in np.arange(4) * np.pi / 2])


def write_campaign(name: str, out: Path, seed: int = 39) -> Path:
    """Write machine.toml and its campaign files into ``out``; returns the machine file."""
    case = ks.CASES[name]
    out.mkdir(parents=True, exist_ok=True)
    mf = out / "machine.toml"
    mf.write_text(chain_toml(name))
    gch = gen.read_chain(mf)
    loc = true_location(case, gch)
    check_truth(case, gch, loc)
    rng = np.random.default_rng(seed)
    angles = gen.grid(gch)
    a0, a1 = (n.lower() for n in gch.names)
    sphere = np.array(SPHERE_MM[name])
    plan = [("probe", "S1", sphere, np.zeros(3)), ("probe", "S2", sphere + [0.0, 0.0, 100.0], np.zeros(3)),
            ("rtest", "R1", sphere, np.zeros(3))]
    if gch.tool:
        plan.append(("probe", "S3", sphere, np.array([0.0, 0.0, -100.0])))
    toml = [mf.read_text()]
    reach = SPHERE_RADIUS_MM + STYLUS_RADIUS_MM
    for kind, sname, w, tip in plan:
        setup = rng.normal(0.0, SETUP_UM * 1e-3, 3)
        fname = f"{'probe' if kind == 'probe' else 'rtest'}_{sname}.csv"
        if kind == "probe":
            centres = gen.probe_centres(gch, loc, w, setup, tip, angles, 0.0, rng)
            rows = [f"position,t_s,{a0}_deg,{a1}_deg,x_mm,y_mm,z_mm"]
            t = 0.0
            for k, (pair, c) in enumerate(zip(angles, centres)):
                t += 20.0
                for d in _touch_dirs():
                    t += 4.0
                    q = c + reach * d + rng.normal(0.0, PROBE_NOISE_UM * 1e-3, 3)
                    rows.append(f"{k},{t:.1f},{pair[0]:.6f},{pair[1]:.6f},{q[0]:.7f},{q[1]:.7f},{q[2]:.7f}")
            toml += [f"[probing.{sname}]", f'file = "{fname}"',
                     f"sphere_mm = {_vec(w)}", f"sphere_radius_mm = {SPHERE_RADIUS_MM}",
                     f"stylus_radius_mm = {STYLUS_RADIUS_MM}", f"tip_mm = {_vec(tip)}"]
        else:
            r = gen.rtest_readings(gch, loc, w, setup, tip, angles, RTEST_NOISE_UM, rng)
            rows = [f"t_s,{a0}_deg,{a1}_deg,dx_um,dy_um,dz_um"]
            rows += [f"{5.0 * i:.1f},{p[0]:.6f},{p[1]:.6f},{v[0]:.4f},{v[1]:.4f},{v[2]:.4f}"
                     for i, (p, v) in enumerate(zip(angles, r))]
            toml += [f"[rtest.{sname}]", f'file = "{fname}"', f"sphere_mm = {_vec(w)}",
                     f"tip_mm = {_vec(tip)}"]
        (out / fname).write_text("\n".join(rows) + "\n")
    mf.write_text("\n".join(toml) + "\n")
    return mf


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--kind", choices=sorted(ks.CASES), required=True)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--seed", type=int, default=39)
    args = ap.parse_args()
    print(write_campaign(args.kind, args.out, args.seed))
    return 0


if __name__ == "__main__":
    sys.exit(main())
