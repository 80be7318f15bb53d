#!/usr/bin/env python3
"""abbe's correction on LinuxCNC's three other five-axis kinds, WITHOUT LinuxCNC: the
joint-level loop of kinds_sim.py's cases closed offline.

  .venv/bin/python port/linuxcnc/tests/kinds_abbe_offline.py

Per case of kinds_sim.py (bridgemill / 5axiskins, max5 / maxkins, xyzab-tdr): the
table is WRITTEN from the chain model (abbe.formats.chain_blob.write_chain_blob of the
case's nominal geometry as a KinematicChain and its injected ISO 230-1 location errors;
not fitted), loaded by the C library (abbe_five_model_load, format 1.4) and evaluated
by abbe_five_error_eval_f32 at the joints the module's inverse gives for each pose
(kinds_sim.nominal_ik, which LinuxCNC's joints match within 1e-13 mm); the joints
corrected by -E go through kinds_sim's INDEPENDENT forward kinematics of the true
machine, and the tool tip minus the programmed point is checked <= BOUND_UM.

kinds_abbe_sim.py (CI) runs the same check through the command line (`abbe table eval
--clib`, 306 poses) before its LinuxCNC runs, which use a FITTED table; chain_of and
errors_of here write its truth table.

What this is not: the HAL component inside LinuxCNC (external offsets, TCP on / off,
the frame of the offsets); the joint-level correction is the same in both modes, the
frame handling for these kinds is not built (docs/linuxcnc.md).

Conventions found on the way (checked here, they fail the run if wrong): the chains'
directions that reproduce the modules' inverse kinematics are 5axiskins C +Z, B -Y;
maxkins C -Z, B -Y; xyzab_tdr_kins A -X, B -Y (kinds_sim's reading of the module).
kinds_sim's angular zero of a workpiece-side axis is about the turned direction, the
chain's about the positive machine axis: it changes sign for a -1 axis there.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parents[2] / "host_tools"))

import kinds_sim as ks  # noqa: E402
from abbe.formats.chain_blob import write_chain_blob  # noqa: E402
from abbe.model.chain import ChainAxis, KinematicChain, nominal_joints  # noqa: E402
from abbe.model.clib import CFiveModel  # noqa: E402
from abbe.model.five_axis import FiveAxisErrors  # noqa: E402

BOUND_UM = 0.5
LIN = tuple(ChainAxis(n, 1, (0.0, 0.0, 0.0), (0.0, 0.0)) for n in "XYZ")


def chain_of(name: str) -> KinematicChain:
    L, M = ks.PIVOT_BRIDGE, ks.PIVOT_MAX5
    if name == "bridgemill":
        return KinematicChain("5axiskins", LIN + (ChainAxis("C", 1, (0.0, 0.0, L)), ChainAxis("B", -1, (0.0, 0.0, L))))
    if name == "max5":
        return KinematicChain("maxkins", (ChainAxis("C", -1, (0.0, 0.0, 0.0)),) + LIN
                              + (ChainAxis("B", -1, (0.0, 0.0, M)),))
    g = ks.CASES["xyzab-tdr"].geometry
    rp = g["rot_point"]
    return KinematicChain("xyzab-tdr", (ChainAxis("A", -1, (rp, rp, rp + g["z_offset"])),
                                        ChainAxis("B", -1, (rp, rp, rp))) + LIN)


def errors_of(case: ks.Case, ch: KinematicChain) -> FiveAxisErrors:
    e = FiveAxisErrors()
    for n, v in case.errors.items():
        ax = n[-1]
        flip = n[1] == ax and ax in ch.workpiece_side and ch.axis(ax).direction == -1
        e.location[n] = -v if flip else v
    return e


def run(name: str) -> tuple[float, float, float]:
    case, ch = ks.CASES[name], chain_of(name)
    model = CFiveModel(write_chain_blob(ch, errors_of(case, ch)))
    rng = np.random.default_rng(39)
    poses = list(case.poses) + [(tuple(rng.uniform(-60.0, 60.0, 3)), tuple(rng.uniform(-60.0, 60.0, 2)))
                                for _ in range(30)]
    joint_gap, before, after = 0.0, 0.0, 0.0
    for point, angles in poses:
        p, a = np.array(point), np.array(angles)
        want = ks.nominal_ik(case, p, a, module=True)
        q0 = np.array([want["X"], want["Y"], want["Z"]])
        joint_gap = max(joint_gap, float(np.abs(nominal_joints(ch, p[None], a[None])[0] - q0).max()))

        def miss(q: np.ndarray) -> float:
            j = {**dict(zip("XYZ", q)), **dict(zip(case.rot, a))}
            return float(np.linalg.norm(ks.tool_in_workpiece(case, j, case.errors) - p) / ks.UM)

        err, _, _ = model.error_f32(q0[None], a[None])
        before = max(before, miss(q0))
        after = max(after, miss(q0 - err[0] * 1e-3))
    return joint_gap, before, after


def main() -> int:
    fails = []
    for name in ks.CASES:
        gap, before, after = run(name)
        print(f"[kinds offline] {name}: chain vs module inverse {gap:.2e} mm; tool tip - programmed point "
              f"without abbe {before:.3f} um, with abbe (C f32, table written from the chain) {after:.4f} um")
        if gap > 1e-9:
            fails.append(f"{name}: the chain's nominal joints differ from the module's by {gap:.3g} mm")
        if after > BOUND_UM or before < 1.0:
            fails.append(f"{name}: {after:.4f} um with abbe (bound {BOUND_UM}), {before:.3f} um without")
    print("PASS" if not fails else "FAIL: " + "; ".join(fails))
    return 1 if fails else 0


if __name__ == "__main__":
    sys.exit(main())
