"""``linuxcnc-maxkins``: a fitted head-table chain as the parameter of LinuxCNC's
``maxkins`` (the max5 sample), the linear joints' and the rotary joints' HOME_OFFSET.

Source: LinuxCNC src/emc/kinematics/maxkins.c (2.9, B in its unconventional sense):
``kinematicsInverse`` puts the programmed point P at joints ``Rz(-C) P - L (sin B, 0,
1 - cos B)`` with L = pivot-length (HAL pin ``maxkins.pivot-length``): in chain terms the
table C about -Z through x = y = 0, the head B about -Y through (0, 0, L) above the
controlled point (cases/five_axis_chains/head-table-maxkins.toml).

Mapping (um -> mm): the B line at (0, 0, L) + (EX0B, 0, EZ0B): pivot-length = L + EZ0B.
The C line at (EX0C, EY0C): maxkins turns about the joints' x = y = 0, so the X and Y
joints' HOME_OFFSET shrink by EX0C, EY0C (the machine coordinates then have their origin
on the C line; the head travels with the linear axes, so nothing else moves; the work
offsets are re-probed in the new coordinates). The angular zeros to the B and C joints
(s E0, s the chain's direction). EX0B and the tilts: the residual.
"""

from __future__ import annotations

import numpy as np

from abbe.errors import AbbeInputError
from abbe.exports.chain_kins import (POSE_OPTIONS, ChainContext, ChainExport, GEOMETRY_TOL_MM,
                                     home_offset_lines, location_reasons, not_held, require, um,
                                     zero_shift_deg)
from abbe.exports.target import Option, fmt

NAME = "linuxcnc-maxkins"
SUMMARY = ("LinuxCNC maxkins (head-table): pivot-length (HAL setp), X/Y/B/C HOME_OFFSET (INI)")
CHAIN = True
MM_DECIMALS = 6
DEG_DECIMALS = 9
HELD = ("EZ0B", "EX0C", "EY0C", "EB0B", "EC0C")
OPTIONS = {
    "component": Option("str", "maxkins", "HAL prefix of the kinematics' pins",
                        pattern=r"[A-Za-z_][A-Za-z0-9_-]{0,40}"),
    "x_joint": Option("int", 0, "joint number of X in the INI", lo=0, hi=15),
    "y_joint": Option("int", 1, "joint number of Y in the INI", lo=0, hi=15),
    "b_joint": Option("int", 4, "joint number of B in the INI (max5: 4)", lo=0, hi=15),
    "c_joint": Option("int", 5, "joint number of C in the INI (max5: 5)", lo=0, hi=15),
    "x_home_offset_mm": Option("float", 0.0, "X joint's HOME_OFFSET today, mm",
                               lo=-10000.0, hi=10000.0),
    "y_home_offset_mm": Option("float", 0.0, "Y joint's HOME_OFFSET today, mm",
                               lo=-10000.0, hi=10000.0),
    "b_home_offset_deg": Option("float", 0.0, "B joint's HOME_OFFSET today, deg",
                                lo=-36000.0, hi=36000.0),
    "c_home_offset_deg": Option("float", 0.0, "C joint's HOME_OFFSET today, deg",
                                lo=-36000.0, hi=36000.0),
    **POSE_OPTIONS,
}
SOURCES = ["LinuxCNC src/emc/kinematics/maxkins.c (kinematicsInverse: xyr, xytheta - C, "
           "joints[0] += L sin B with B unconventional, joints[2] -= L (1 - cos B); pin "
           "maxkins.pivot-length)",
           "LinuxCNC sample config sim/axis/vismach/5axis/max5/max5kins.ini, max5kins.hal "
           "(setp maxkins.pivot-length [MAX]B_PIVOT_LENGTH; joints 4 = B, 5 = C)",
           "LinuxCNC INI documentation: [JOINT_n] HOME_OFFSET"]


def module_inverse(pivot_mm: float, work_mm: np.ndarray, b_deg: np.ndarray,
                   c_deg: np.ndarray) -> np.ndarray:
    """Joints (N, 3) mm of maxkins' inverse for programmed points (N, 3) at B, C (deg)."""
    w = np.asarray(work_mm, dtype=np.float64).reshape(-1, 3)
    b, c = np.deg2rad(b_deg), np.deg2rad(c_deg)
    r = np.hypot(w[:, 0], w[:, 1])
    th = np.arctan2(w[:, 1], w[:, 0]) - c
    return np.column_stack([r * np.cos(th) - pivot_mm * np.sin(b), r * np.sin(th),
                            w[:, 2] - pivot_mm * (1.0 - np.cos(b))])


def build(ctx: ChainContext) -> ChainExport:
    ch, o = ctx.chain, ctx.options
    mod = "maxkins"
    require([a.name for a in ch.axes] == ["C", "X", "Y", "Z", "B"], ctx, mod,
            "expected the order C, X, Y, Z, B (table C, head B)")
    require(ch.axis("C").direction == -1 and ch.axis("B").direction == -1, ctx, mod,
            "expected C about -Z and B about -Y (maxkins turns P by -C; B unconventional)")
    pc, pb = ch.pivot("C"), ch.pivot("B")
    require(abs(pc[0]) <= GEOMETRY_TOL_MM and abs(pc[1]) <= GEOMETRY_TOL_MM, ctx, mod,
            "expected the C line through x = y = 0")
    require(abs(pb[0]) <= GEOMETRY_TOL_MM, ctx, mod,
            "expected the B line through x = 0 above the controlled point")
    joints_used = [o["x_joint"], o["y_joint"], o["b_joint"], o["c_joint"]]
    if len(set(joints_used)) != 4:
        raise AbbeInputError(f"the joints X, Y, B, C must differ, got {joints_used}",
                             field="--set")
    L = float(pb[2])
    text = fmt(L + um(ctx, "EZ0B"), MM_DECIMALS)
    pivot = float(text)
    lin = {"X": float(fmt(-um(ctx, "EX0C"), MM_DECIMALS)),
           "Y": float(fmt(-um(ctx, "EY0C"), MM_DECIMALS))}
    shift = {a: float(fmt(zero_shift_deg(ctx, a), DEG_DECIMALS)) for a in ("B", "C")}
    comp = o["component"]
    hal = [f"# abbe export {NAME}: fitted head-table chain {ch.name} (mm; maxkins.c)",
           f"# model: {ctx.model_source}; nominal from {ctx.machine_source}",
           "# the max5 sample sets this from [MAX]B_PIVOT_LENGTH: set that INI value instead",
           f"# pivot-length: nominal {fmt(L, MM_DECIMALS)}, change "
           f"{fmt((pivot - L) * 1e3, 3)} um (EZ0B)",
           f"setp {comp}.pivot-length {text}"]
    ini = [f"# abbe export {NAME}: joint home offsets; merge into the joints' sections",
           "# X, Y: HOME_OFFSET = today's value - the C line's offset (EX0C, EY0C): the machine "
           "coordinates then have their origin on the C line, where maxkins turns",
           "# B, C: HOME_OFFSET = today's value + direction x E0 (the joint reads the true angle)"]
    for a, n in (("X", "EX0C"), ("Y", "EY0C")):
        ini += home_offset_lines(o[f"{a.lower()}_joint"], a, o[f"{a.lower()}_home_offset_mm"],
                                 lin[a], f"{n} = {fmt(ctx.errors.location.get(n, 0.0), 3)} um",
                                 MM_DECIMALS, "mm")
    for a in ("B", "C"):
        e0 = ctx.errors.location.get(f"E{a}0{a}", 0.0)
        ini += home_offset_lines(o[f"{a.lower()}_joint"], a, o[f"{a.lower()}_home_offset_deg"],
                                 shift[a], f"E{a}0{a} = {fmt(e0, 3)} urad, direction "
                                 f"{ch.axis(a).direction:+d}", DEG_DECIMALS, "deg")
    e = np.array([-lin["X"], -lin["Y"], 0.0])  # the C line in abbe's (old) coordinates

    def joints(work_mm: np.ndarray, angles_deg: np.ndarray):
        ang = np.asarray(angles_deg, dtype=np.float64).reshape(-1, 2)  # B, C
        w = np.asarray(work_mm, dtype=np.float64).reshape(-1, 3)
        # the programmed point in the new coordinates is w - e; the joints read e less
        q = module_inverse(pivot, w - e, ang[:, 0], ang[:, 1]) + e
        return q, ang - np.array([shift["B"], shift["C"]])[None, :]

    expressed = [{"pin": f"{comp}.pivot-length", "value_mm": pivot, "nominal_mm": L,
                  "from": "nominal + EZ0B"}]
    expressed += [{"ini": f"[JOINT_{o[a.lower() + '_joint']}] HOME_OFFSET",
                   "value_mm": o[f"{a.lower()}_home_offset_mm"] + lin[a],
                   "from": f"today - E{a}0C"} for a in ("X", "Y")]
    expressed += [{"ini": f"[JOINT_{o[a.lower() + '_joint']}] HOME_OFFSET",
                   "value_deg": o[f"{a.lower()}_home_offset_deg"] + shift[a],
                   "from": f"today + direction x E{a}0{a}"} for a in ("B", "C")]
    unobs = [n for n in ctx.not_observable if n in HELD]
    notes = ["maxkins holds the head's pivot height (pivot-length), the table's centre (as "
             "the X/Y home offsets) and the angular zeros; EX0B and the tilts are the residual "
             "(this export writes no table of them for abbe's HAL component yet)",
             "after the X/Y HOME_OFFSET change re-probe the work offsets (G54...): machine "
             "coordinates move by the C line's offset"]
    if unobs:
        notes.append("written at their nominal value (not observable by the fit): "
                     + ", ".join(unobs))
    return ChainExport(
        target=NAME, files={"maxkins.hal": ("\n".join(hal) + "\n").encode(),
                            "maxkins.ini": ("\n".join(ini) + "\n").encode()},
        joints=joints, expressed=expressed, held=HELD,
        not_held=not_held(ctx, HELD, location_reasons(mod), mod), notes=notes,
        assumptions=["abbe's machine coordinates are maxkins' joints with the tool the "
                     "controller programs (tool length 0 in abbe's chain)",
                     "maxkins 2.9's inverse (what tool-centre-point motion runs); its forward "
                     "differs from it when B and C are both turned (a display matter)",
                     "the joints home to fixed switches: HOME_OFFSET moves the scale, not the "
                     "machine"],
        sources=SOURCES)
