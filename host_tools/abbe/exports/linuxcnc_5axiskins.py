"""``linuxcnc-5axiskins``: a fitted head-head chain as the parameter of LinuxCNC's
``5axiskins`` (the bridgemill sample) and the rotary joints' HOME_OFFSET.

Source: LinuxCNC src/emc/kinematics/5axiskins.c (2.9): the tool tip is at
``J + L (sin B cos C, sin B sin C, 1 - cos B)`` with L = pivot-length (HAL pin
``5axiskins.pivot-length``, the distance from the controlled point up to where the B and
C lines meet): in chain terms C about +Z on the ram carrying B about -Y, both lines
through (0, 0, L) above the controlled point (cases/five_axis_chains/head-head-5axiskins.toml).

Mapping (um -> mm): the B line at (0, 0, L) + (EX0B, 0, EZ0B): pivot-length = L + EZ0B.
The angular zeros go to the joints: the axis turns by ``s t + E0`` (s the chain's
direction), so HOME_OFFSET grows by s E0 in degrees and the joint reads the true angle.
EX0C, EY0C, EX0B (the lines off the tool's axis) and the tilts have no parameter in
5axiskins: they are the residual.
"""

from __future__ import annotations

import numpy as np

from abbe.exports.chain_kins import (POSE_OPTIONS, ChainContext, ChainExport, home_offset_lines,
                                     location_reasons, not_held, require, um, zero_shift_deg,
                                     GEOMETRY_TOL_MM)
from abbe.exports.target import Option, fmt

NAME = "linuxcnc-5axiskins"
SUMMARY = "LinuxCNC 5axiskins (head-head): pivot-length (HAL setp), B/C HOME_OFFSET (INI)"
CHAIN = True
MM_DECIMALS = 6
DEG_DECIMALS = 9
HELD = ("EZ0B", "EB0B", "EC0C")
OPTIONS = {
    "component": Option("str", "5axiskins", "HAL prefix of the kinematics' pins",
                        pattern=r"[A-Za-z_][A-Za-z0-9_-]{0,40}"),
    "b_joint": Option("int", 3, "joint number of B in the INI (bridgemill: 3)", lo=0, hi=15),
    "c_joint": Option("int", 4, "joint number of C in the INI (bridgemill: 4)", lo=0, hi=15),
    "b_home_offset_deg": Option("float", 0.0, "B joint's HOME_OFFSET today, deg",
                                lo=-36000.0, hi=36000.0),
    "c_home_offset_deg": Option("float", 0.0, "C joint's HOME_OFFSET today, deg",
                                lo=-36000.0, hi=36000.0),
    **POSE_OPTIONS,
}
SOURCES = ["LinuxCNC src/emc/kinematics/5axiskins.c (kinematicsForward / Inverse: "
           "s2r(pivot-length, C, 180 - B); pin 5axiskins.pivot-length)",
           "LinuxCNC sample config sim/axis/vismach/5axis/bridgemill/5axis.ini and 5axisgui.hal "
           "(joints 3 = B, 4 = C; :pivot-len = gui pivot_len + motion.tooloffset.z)",
           "LinuxCNC INI documentation: [JOINT_n] HOME_OFFSET"]


def module_inverse(pivot_mm: float, work_mm: np.ndarray, b_deg: np.ndarray,
                   c_deg: np.ndarray) -> np.ndarray:
    """Joints (N, 3) mm of 5axiskins for tool-tip points (N, 3) at B, C (deg)."""
    b, c = np.deg2rad(b_deg), np.deg2rad(c_deg)
    h = pivot_mm * np.column_stack([np.sin(b) * np.cos(c), np.sin(b) * np.sin(c),
                                    1.0 - np.cos(b)])
    return np.asarray(work_mm, dtype=np.float64).reshape(-1, 3) - h


def build(ctx: ChainContext) -> ChainExport:
    ch, o = ctx.chain, ctx.options
    mod = "5axiskins"
    require([a.name for a in ch.axes] == ["X", "Y", "Z", "C", "B"], ctx, mod,
            "expected the order X, Y, Z, C, B (C on the ram carrying B)")
    require(ch.axis("C").direction == 1 and ch.axis("B").direction == -1, ctx, mod,
            "expected C about +Z and B about -Y (5axiskins' tip L (sin B cos C, ...))")
    pc, pb = ch.pivot("C"), ch.pivot("B")
    require(abs(pc[0]) <= GEOMETRY_TOL_MM and abs(pc[1]) <= GEOMETRY_TOL_MM
            and abs(pb[0]) <= GEOMETRY_TOL_MM and pb[2] > 0.0, ctx, mod,
            "expected both lines through (0, 0, L), L > 0 above the controlled point")
    if o["b_joint"] == o["c_joint"]:
        from abbe.errors import AbbeInputError
        raise AbbeInputError(f"B and C are both joint {o['b_joint']}", field="--set c_joint")
    L = float(pb[2])
    text = fmt(L + um(ctx, "EZ0B"), MM_DECIMALS)
    pivot = float(text)
    shift = {a: float(fmt(zero_shift_deg(ctx, a), DEG_DECIMALS)) for a in ("B", "C")}
    comp = o["component"]
    hal = [f"# abbe export {NAME}: fitted head-head chain {ch.name} (mm; 5axiskins.c)",
           f"# model: {ctx.model_source}; nominal from {ctx.machine_source}",
           "# the bridgemill sample drives this pin from sum2 pivotsum (5axisgui pivot_len + "
           "motion.tooloffset.z): there set the GUI's pivot_len (or pivotsum.in0's source) to "
           "this value instead",
           f"# pivot-length: nominal {fmt(L, MM_DECIMALS)}, change "
           f"{fmt((pivot - L) * 1e3, 3)} um (EZ0B)",
           f"setp {comp}.pivot-length {text}"]
    ini = [f"# abbe export {NAME}: rotary zero offsets (deg); merge into the joints' sections",
           "# HOME_OFFSET = today's value + direction x E0 (the joint then reads the true angle)"]
    for a, j in (("B", o["b_joint"]), ("C", o["c_joint"])):
        e0 = ctx.errors.location.get(f"E{a}0{a}", 0.0)
        ini += home_offset_lines(j, a, o[f"{a.lower()}_home_offset_deg"], shift[a],
                                 f"E{a}0{a} = {fmt(e0, 3)} urad, direction "
                                 f"{ch.axis(a).direction:+d}", DEG_DECIMALS, "deg")

    def joints(work_mm: np.ndarray, angles_deg: np.ndarray):
        ang = np.asarray(angles_deg, dtype=np.float64).reshape(-1, 2)  # B, C
        q = module_inverse(pivot, work_mm, ang[:, 0], ang[:, 1])
        return q, ang - np.array([shift["B"], shift["C"]])[None, :]

    expressed = [{"pin": f"{comp}.pivot-length", "value_mm": pivot, "nominal_mm": L,
                  "from": "nominal + EZ0B"}]
    expressed += [{"ini": f"[JOINT_{o[a.lower() + '_joint']}] HOME_OFFSET",
                   "value_deg": o[f"{a.lower()}_home_offset_deg"] + shift[a],
                   "from": f"today + direction x E{a}0{a}"} for a in ("B", "C")]
    unobs = [n for n in ctx.not_observable if n in HELD]
    notes = ["5axiskins holds where B's line crosses the tool axis (pivot-length) and the "
             "angular zeros; the lines' offsets across the tool axis and their tilts are the "
             "residual (this export writes no table of them for abbe's HAL component yet)"]
    if unobs:
        notes.append("written at their nominal value (not observable by the fit): "
                     + ", ".join(unobs))
    return ChainExport(
        target=NAME, files={"5axiskins.hal": ("\n".join(hal) + "\n").encode(),
                            "5axiskins.ini": ("\n".join(ini) + "\n").encode()},
        joints=joints, expressed=expressed, held=HELD,
        not_held=not_held(ctx, HELD, location_reasons(mod), mod), notes=notes,
        assumptions=["abbe's machine coordinates are 5axiskins' joints with the tool the "
                     "controller programs (pivot-length includes its length)",
                     "the rotary joints home to a fixed switch or index: HOME_OFFSET moves the "
                     "angle scale, not the head"],
        sources=SOURCES)
