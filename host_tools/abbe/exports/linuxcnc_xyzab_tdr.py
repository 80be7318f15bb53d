"""``linuxcnc-xyzab-tdr``: a fitted dual-rotary-table chain as the HAL pins of LinuxCNC's
``xyzab_tdr_kins`` (the table-dual-rotary sample) and the rotary joints' HOME_OFFSET.

Source: LinuxCNC src/hal/components/xyzab_tdr_kins.comp (2.9), kinematicsInverse type 1:
``j = Ry(b)^T (Rx(a)^T (P - r - d - t z) + d) + r + t z`` with r = (x-rot-point,
y-rot-point, z-rot-point), d = (x-offset, 0, z-offset), t = tool-offset-z. In chain terms
(cases/five_axis_chains/table-dual-rotary-xyzab.toml) the workpiece sits on A, turned
about -X through the line (y, z) = (r_y, r_z + d_z), A sits on B, turned about -Y through
the line (x, z) = (r_x, r_z); x-offset runs along A's axis and moves nothing.

Mapping (um -> mm): B's line at its pivot + (EX0B, 0, EZ0B): x-rot-point, z-rot-point;
A's line at its pivot + (0, EY0A, EZ0A): y-rot-point, and z-offset = A's z minus
z-rot-point; x-offset keeps its nominal value (A's pivot x minus B's). The angular zeros
to the A and B joints (s E0, s = -1 for both). The tilts (EB0A, EC0A, EA0B, EC0B): the
residual.
"""

from __future__ import annotations

import numpy as np

from abbe.errors import AbbeInputError
from abbe.exports.chain_kins import (POSE_OPTIONS, ChainContext, ChainExport,
                                     home_offset_lines, location_reasons, not_held, require, um,
                                     zero_shift_deg)
from abbe.exports.target import Option, fmt

NAME = "linuxcnc-xyzab-tdr"
SUMMARY = ("LinuxCNC xyzab_tdr_kins (dual rotary table): rot-point and offsets (HAL setp), "
           "A/B HOME_OFFSET (INI)")
CHAIN = True
MM_DECIMALS = 6
DEG_DECIMALS = 9
HELD = ("EX0B", "EZ0B", "EY0A", "EZ0A", "EA0A", "EB0B")
PINS = ("x-rot-point", "y-rot-point", "z-rot-point", "x-offset", "z-offset")
OPTIONS = {
    "component": Option("str", "xyzab_tdr_kins", "HAL prefix of the kinematics' pins",
                        pattern=r"[A-Za-z_][A-Za-z0-9_-]{0,40}"),
    "a_joint": Option("int", 3, "joint number of A in the INI (sample: 3)", lo=0, hi=15),
    "b_joint": Option("int", 4, "joint number of B in the INI (sample: 4)", lo=0, hi=15),
    "a_home_offset_deg": Option("float", 0.0, "A joint's HOME_OFFSET today, deg",
                                lo=-36000.0, hi=36000.0),
    "b_home_offset_deg": Option("float", 0.0, "B joint's HOME_OFFSET today, deg",
                                lo=-36000.0, hi=36000.0),
    **POSE_OPTIONS,
}
SOURCES = ["LinuxCNC src/hal/components/xyzab_tdr_kins.comp (kinematicsInverse / Forward "
           "type 1; pins x/y/z-rot-point, x-offset, z-offset, tool-offset-z)",
           "LinuxCNC sample config sim/axis/vismach/5axis/table-dual-rotary/xyzab-tdr.ini "
           "(nets :x-offset, :z-offset, :x/y/z-rot-point; joints 3 = A, 4 = B) and its README",
           "LinuxCNC INI documentation: [JOINT_n] HOME_OFFSET"]


def module_inverse(pins: dict[str, float], work_mm: np.ndarray, a_deg: np.ndarray,
                   b_deg: np.ndarray) -> np.ndarray:
    """Joints (N, 3) mm of xyzab_tdr_kins type 1 (tool-offset-z 0), the source's formula."""
    P = np.asarray(work_mm, dtype=np.float64).reshape(-1, 3)
    sa, ca = np.sin(np.deg2rad(a_deg)), np.cos(np.deg2rad(a_deg))
    sb, cb = np.sin(np.deg2rad(b_deg)), np.cos(np.deg2rad(b_deg))
    rx, ry, rz = pins["x-rot-point"], pins["y-rot-point"], pins["z-rot-point"]
    dx, dz = pins["x-offset"], pins["z-offset"]
    qx, qy, qz = P[:, 0] - rx - dx, P[:, 1] - ry, P[:, 2] - rz - dz
    return np.column_stack([
        cb * qx + sa * sb * qy - ca * sb * qz + cb * dx - sb * dz + rx,
        ca * qy + sa * qz + ry,
        sb * qx - sa * cb * qy + ca * cb * qz + sb * dx + cb * dz + rz])


def build(ctx: ChainContext) -> ChainExport:
    ch, o = ctx.chain, ctx.options
    mod = "xyzab_tdr_kins"
    require([a.name for a in ch.axes] == ["A", "B", "X", "Y", "Z"], ctx, mod,
            "expected the order A, B, X, Y, Z (the workpiece on A, A on B)")
    require(ch.axis("A").direction == -1 and ch.axis("B").direction == -1, ctx, mod,
            "expected A about -X and B about -Y (the module turns the workpiece by "
            "Ry(b)^T Rx(a)^T)")
    if o["a_joint"] == o["b_joint"]:
        raise AbbeInputError(f"A and B are both joint {o['a_joint']}", field="--set b_joint")
    pa, pb = ch.pivot("A"), ch.pivot("B")
    rz = pb[2] + um(ctx, "EZ0B")
    val = {"x-rot-point": pb[0] + um(ctx, "EX0B"), "y-rot-point": pa[1] + um(ctx, "EY0A"),
           "z-rot-point": rz, "x-offset": pa[0] - pb[0],
           "z-offset": pa[2] + um(ctx, "EZ0A") - rz}
    nominal = {"x-rot-point": pb[0], "y-rot-point": pa[1], "z-rot-point": pb[2],
               "x-offset": pa[0] - pb[0], "z-offset": pa[2] - pb[2]}
    # z-rot-point quantised first: z-offset is written so that A's z (their sum) is exact
    text = {"z-rot-point": fmt(float(val["z-rot-point"]), MM_DECIMALS)}
    val["z-offset"] = pa[2] + um(ctx, "EZ0A") - float(text["z-rot-point"])
    text.update({k: fmt(float(val[k]), MM_DECIMALS) for k in PINS if k != "z-rot-point"})
    pins = {k: float(text[k]) for k in PINS}
    frm = {"x-rot-point": "B pivot x + EX0B", "y-rot-point": "A pivot y + EY0A",
           "z-rot-point": "B pivot z + EZ0B", "x-offset": "nominal (along A's axis: no effect)",
           "z-offset": "A pivot z + EZ0A - z-rot-point"}
    shift = {a: float(fmt(zero_shift_deg(ctx, a), DEG_DECIMALS)) for a in ("A", "B")}
    comp = o["component"]
    hal = [f"# abbe export {NAME}: fitted dual-rotary-table chain {ch.name} (mm; "
           "xyzab_tdr_kins.comp)",
           f"# model: {ctx.model_source}; nominal from {ctx.machine_source}",
           "# the sample nets these pins to signals (:x-offset, :x-rot-point ...): set the "
           "signal instead, e.g. sets :z-offset VALUE; keep tool-offset-z netted to "
           "motion.tooloffset.z"]
    for k in PINS:
        hal.append(f"# {k}: nominal {fmt(float(nominal[k]), MM_DECIMALS)}, change "
                   f"{fmt((pins[k] - float(nominal[k])) * 1e3, 3)} um ({frm[k]})")
        hal.append(f"setp {comp}.{k} {text[k]}")
    ini = [f"# abbe export {NAME}: rotary zero offsets (deg); merge into the joints' sections",
           "# HOME_OFFSET = today's value + direction x E0 (the joint then reads the true angle)"]
    for a in ("A", "B"):
        e0 = ctx.errors.location.get(f"E{a}0{a}", 0.0)
        ini += home_offset_lines(o[f"{a.lower()}_joint"], a, o[f"{a.lower()}_home_offset_deg"],
                                 shift[a], f"E{a}0{a} = {fmt(e0, 3)} urad, direction "
                                 f"{ch.axis(a).direction:+d}", DEG_DECIMALS, "deg")

    def joints(work_mm: np.ndarray, angles_deg: np.ndarray):
        ang = np.asarray(angles_deg, dtype=np.float64).reshape(-1, 2)  # A, B
        q = module_inverse(pins, work_mm, ang[:, 0], ang[:, 1])
        return q, ang - np.array([shift["A"], shift["B"]])[None, :]

    expressed = [{"pin": f"{comp}.{k}", "value_mm": pins[k], "nominal_mm": float(nominal[k]),
                  "from": frm[k]} for k in PINS]
    expressed += [{"ini": f"[JOINT_{o[a.lower() + '_joint']}] HOME_OFFSET",
                   "value_deg": o[f"{a.lower()}_home_offset_deg"] + shift[a],
                   "from": f"today + direction x E{a}0{a}"} for a in ("A", "B")]
    unobs = [n for n in ctx.not_observable if n in HELD]
    notes = ["xyzab_tdr_kins holds both lines' positions and the angular zeros; the lines' "
             "tilts are the residual (this export writes no table of them for abbe's HAL component yet)"]
    if unobs:
        notes.append("written at their nominal value (not observable by the fit): "
                     + ", ".join(unobs))
    return ChainExport(
        target=NAME, files={"xyzab-tdr.hal": ("\n".join(hal) + "\n").encode(),
                            "xyzab-tdr.ini": ("\n".join(ini) + "\n").encode()},
        joints=joints, expressed=expressed, held=HELD,
        not_held=not_held(ctx, HELD, location_reasons(mod), mod), notes=notes,
        assumptions=["abbe's machine coordinates are the module's joints with tool-offset-z 0 "
                     "(LinuxCNC adds the tool length itself)",
                     "tool-centre-point mode (switchkins type 1, M428 in the sample)",
                     "the rotary joints home to a fixed switch or index: HOME_OFFSET moves the "
                     "angle scale, not the table"],
        sources=SOURCES)
