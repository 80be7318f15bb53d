"""``linuxcnc-trt``: the identified trunnion geometry as the HAL pins of LinuxCNC's
``xyzac-trt-kins`` / ``xyzbc-trt-kins`` and the rotary joints' HOME_OFFSET.

Source: LinuxCNC src/emc/kinematics/trtfuncs.c. The inverse kinematics of
``xyzac-trt`` puts the programmed point w at joints
``q = r + o + Rx(A) (Rz(C) (w - r) - o)`` with r = (x-rot-point, y-rot-point,
z-rot-point) and o = (0, y-offset, z-offset + tool-offset); ``xyzbc-trt`` the
same with Ry(B) and o = (x-offset, 0, z-offset + tool-offset). Right-handed
rotations by the joint angles: the geometry of :mod:`abbe.model.five_axis`.

Mapping (ISO 230-1 location errors, um -> mm): the C axis line is at
r + (EX0C, EY0C, 0), so x/y-rot-point move by EX0C, EY0C; the tilt axis line at
r + o + (0, EY0A, EZ0A) (B: (EX0B, 0, EZ0B)), so the offsets move by
EY0A - EY0C, EZ0A (B: EX0B - EX0C, EZ0B). The angular zeros (the table turns by
joint + E0) go to the joints: HOME_OFFSET (the joint position given to the home
point) grows by E0 in degrees, so the joint reads the true angle. The tilts of
the lines (EB0A, EC0A, EA0C, EB0C; for B: EA0B, EC0B), the error motions, the
squareness and the linear axes' errors are translations trt cannot hold.

``abbe-five.bin``: the table for abbe's HAL component in five-axis mode, which
corrects what trt cannot hold (docs/linuxcnc.md, "Five-axis machines"). It is the
model with what trt now holds moved into its geometry: the C centre and the tilt
offset are the written pins (the model moves each line rigidly about its nominal
pivot, so a line through the written point with the same tilts is the same line; the
tilt line's point slides along its own axis by the C centre's shift, EX0C for A, EY0C
for B, which its tilts turn into |shift| x |tilt|, 0.06 um for 400 um and 150 urad),
their translations and angular zeros are 0, and each error motion, a function of
the old joint angle t = joint - E0, is re-phased to the joint that now reads the
true angle. Everything else (tilts, error motions, squareness, the linear table) is
the model's. Loading the fitted model_five.bin into the component instead would
correct the held translations twice.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from abbe.formats.five_axis_blob import write_five_blob
from abbe.model.five_axis import FiveAxisErrors, TrunnionGeometry
from abbe.exports.five_axis import (
    POSE_OPTIONS,
    FiveContext,
    FiveExport,
    identified_lines,
    not_held,
    zero_offsets_deg,
)
from abbe.errors import AbbeInputError
from abbe.exports.target import Option, fmt

NAME = "linuxcnc-trt"
SUMMARY = ("LinuxCNC xyzac-trt-kins / xyzbc-trt-kins: rotation point and offsets (HAL setp), "
           "rotary zero offsets (INI HOME_OFFSET)")
FIVE_AXIS = True
MM_DECIMALS = 6   # 1 nm
DEG_DECIMALS = 9  # 1e-9 deg = 0.017 urad
OPTIONS = {
    "component": Option("str", "", "HAL name of the kinematics (default: xyzac-trt-kins or "
                        "xyzbc-trt-kins by the model)", pattern=r"[A-Za-z_][A-Za-z0-9_-]{0,40}|"),
    "tilt_joint": Option("int", 3, "joint number of the tilt axis (A or B) in the INI", lo=0, hi=15),
    "c_joint": Option("int", 4, "joint number of the C axis in the INI", lo=0, hi=15),
    "tilt_home_offset_deg": Option("float", 0.0, "the tilt joint's HOME_OFFSET today, deg",
                                   lo=-36000.0, hi=36000.0),
    "c_home_offset_deg": Option("float", 0.0, "the C joint's HOME_OFFSET today, deg",
                                lo=-36000.0, hi=36000.0),
    **POSE_OPTIONS,
}
SOURCES = ["LinuxCNC src/emc/kinematics/trtfuncs.c (xyzacKinematicsInverse, "
           "xyzbcKinematicsInverse; pins x/y/z-rot-point, x/y/z-offset, tool-offset)",
           "LinuxCNC sample config sim/axis/vismach/5axis/table-rotary-tilting/xyzac-trt.ini "
           "(setp xyzac-trt-kins.x-rot-point, joints 3 = A, 4 = C)",
           "LinuxCNC INI documentation: [JOINT_n] HOME_OFFSET, the joint position of the home "
           "point"]
#: What trt holds, per tilt axis: the location errors it maps.
HELD = {"A": ("EY0A", "EZ0A", "EA0A"), "B": ("EX0B", "EZ0B", "EB0B")}


def _cannot(tilt: str):
    held = set(HELD[tilt]) | {"EX0C", "EY0C", "EC0C"}

    def cannot(label: str, kind: str) -> str | None:
        if kind == "location":
            return None if label in held else ("a tilt of an axis line: trt-kins holds "
                                               "translations of the lines only")
        if kind == "error motion":
            return "angle-dependent: trt-kins has constant geometry"
        if kind == "squareness":
            return "linear-axis squareness: not part of trt-kins"
        return "linear-axis errors: not part of trt-kins (abbe's comp files or HAL component)"
    return cannot


def trt_inverse(kind: str, pins: dict[str, float], work_mm: np.ndarray,
                angles_deg: np.ndarray) -> np.ndarray:
    """Joint positions (N, 3) mm of trtfuncs.c's inverse kinematics (tool-offset 0)."""
    w = np.asarray(work_mm, dtype=np.float64).reshape(-1, 3)
    ang = np.deg2rad(np.asarray(angles_deg, dtype=np.float64).reshape(-1, 2))
    r = np.array([pins["x-rot-point"], pins["y-rot-point"], pins["z-rot-point"]])
    b, c = ang[:, 0], ang[:, 1]
    u = w - r
    ux = np.cos(c) * u[:, 0] - np.sin(c) * u[:, 1]
    uy = np.sin(c) * u[:, 0] + np.cos(c) * u[:, 1]
    uz = u[:, 2]
    if kind == "xyzac-trt":
        dy, dz = pins["y-offset"], pins["z-offset"]
        y = np.cos(b) * (uy - dy) - np.sin(b) * (uz - dz) + dy
        z = np.sin(b) * (uy - dy) + np.cos(b) * (uz - dz) + dz
        return np.column_stack([ux, y, z]) + r
    dx, dz = pins["x-offset"], pins["z-offset"]
    x = np.cos(b) * (ux - dx) + np.sin(b) * (uz - dz) + dx
    z = -np.sin(b) * (ux - dx) + np.cos(b) * (uz - dz) + dz
    return np.column_stack([x, uy, z]) + r


def build(ctx: FiveContext) -> FiveExport:
    g, e, o = ctx.geometry, ctx.errors, ctx.options
    tilt = g.tilt
    if o["tilt_joint"] == o["c_joint"]:
        raise AbbeInputError(f"the tilt and the C axis are both joint {o['c_joint']}",
                             field="--set c_joint")
    loc = {k: float(v) for k, v in e.location.items()}
    rp, pt = identified_lines(ctx)
    off = pt - rp  # the component along the tilt axis is not used by trt
    names = ("y-offset", "z-offset") if tilt == "A" else ("x-offset", "z-offset")
    vals = (off["XYZ".index(names[0][0].upper())], off[2])
    comp = o["component"] or f"{g.kind}-kins"
    text = {"x-rot-point": fmt(rp[0], MM_DECIMALS), "y-rot-point": fmt(rp[1], MM_DECIMALS),
            "z-rot-point": fmt(rp[2], MM_DECIMALS),
            names[0]: fmt(vals[0], MM_DECIMALS), names[1]: fmt(vals[1], MM_DECIMALS)}
    pins = {k: float(v) for k, v in text.items()}
    zero_deg = zero_offsets_deg(ctx)
    home = {tilt: fmt(o["tilt_home_offset_deg"] + zero_deg[tilt], DEG_DECIMALS),
            "C": fmt(o["c_home_offset_deg"] + zero_deg["C"], DEG_DECIMALS)}
    shift = np.array([float(home[tilt]) - o["tilt_home_offset_deg"],
                      float(home["C"]) - o["c_home_offset_deg"]])

    nominal = {"x-rot-point": g.rot_point_mm[0], "y-rot-point": g.rot_point_mm[1],
               "z-rot-point": g.rot_point_mm[2],
               names[0]: g.offset_mm["XYZ".index(names[0][0].upper())],
               names[1]: g.offset_mm[2]}
    hal = [f"# abbe export linuxcnc-trt: identified geometry of {g.kind} (mm, machine "
           "coordinates; trtfuncs.c)",
           f"# model: {Path(ctx.model_source).name}; nominal from {Path(ctx.machine_source).name}",
           "# where a pin is linked to a signal (the sample config nets y-offset and z-offset "
           "to :y-offset, :z-offset), set the signal instead: sets :y-offset VALUE",
           "# keep tool-offset netted to motion.tooloffset.z"]
    for k, v in text.items():
        hal.append(f"# {k}: nominal {fmt(nominal[k], MM_DECIMALS)}, change "
                   f"{fmt((pins[k] - nominal[k]) * 1e3, 3)} um")
        hal.append(f"setp {comp}.{k} {v}")
    ini = [f"# abbe export linuxcnc-trt: rotary zero offsets of {g.kind} (deg); merge into the "
           "joints' sections of the machine's INI",
           f"# HOME_OFFSET = today's value + the identified zero offset (table turns by joint + "
           "E0; the joint then reads the true angle)"]
    for axis, joint, old in ((tilt, o["tilt_joint"], o["tilt_home_offset_deg"]),
                             ("C", o["c_joint"], o["c_home_offset_deg"])):
        ename = f"E{axis}0{axis}"
        ini += ["", f"[JOINT_{joint}]",
                f"# {axis}: {ename} = {fmt(loc.get(ename, 0.0), 3)} urad = "
                f"{fmt(zero_deg[axis], DEG_DECIMALS)} deg; HOME_OFFSET today {old:g}",
                f"HOME_OFFSET = {home[axis]}"]

    def joints(work_mm: np.ndarray, angles_deg: np.ndarray):
        ang = np.asarray(angles_deg, dtype=np.float64).reshape(-1, 2)
        return trt_inverse(g.kind, pins, work_mm, ang), ang - shift[None, :]

    expressed = [{"pin": f"{comp}.{k}", "value_mm": pins[k], "nominal_mm": float(nominal[k]),
                  "from": _from(k, tilt)} for k in text]
    expressed += [{"ini": f"[JOINT_{j}] HOME_OFFSET", "value_deg": float(home[a]),
                   "from": f"E{a}0{a}"}
                  for a, j in ((tilt, o["tilt_joint"]), ("C", o["c_joint"]))]
    unobs = [n for n in ctx.not_observable if n in set(HELD[tilt]) | {"EX0C", "EY0C", "EC0C"}]
    notes = ["trt-kins computes the tool tip from the joints with these values: the linear joints "
             "move so that the programmed point stays under the tool as the table turns "
             "(tool-centre-point control, M428 in the sample config)",
             "abbe-five.bin: the table for abbe's HAL component in five-axis mode, which corrects "
             "what is not held here (geometry = these pins, held items 0; docs/linuxcnc.md)"]
    if unobs:
        notes.append("written at their nominal value (not observable by the fit): "
                     + ", ".join(unobs))
    return FiveExport(
        target=NAME,
        files={"trt-kins.hal": ("\n".join(hal) + "\n").encode(),
               "trt-kins.ini": ("\n".join(ini) + "\n").encode(),
               "abbe-five.bin": component_table(ctx, pins, zero_deg)},
        joints=joints, expressed=expressed, not_held=not_held(ctx, _cannot(tilt)), notes=notes,
        assumptions=[
            "abbe's machine coordinates are the kinematics' joint coordinates with tool-offset 0 "
            "(LinuxCNC adds the tool length to z-offset itself)",
            f"joint {o['tilt_joint']} is {tilt} and joint {o['c_joint']} is C, with the "
            "HOME_OFFSET given (--set tilt_home_offset_deg=, c_home_offset_deg=); the joints' "
            "positive sense is the right-handed one of the model (A about +X, B about +Y, C about "
            "+Z of the table, as trtfuncs.c)",
            "the rotary joints home to a fixed switch or index: HOME_OFFSET moves the angle "
            "scale, not the table"],
        sources=SOURCES)


def component_table(ctx: FiveContext, pins: dict[str, float], zero_deg: dict[str, float]) -> bytes:
    """The five-axis table of what trt does not hold (module docstring): geometry from
    the written pins (mm), the held location errors 0, error motions re-phased by the
    angular zeros zero_deg (deg): a series in t = joint - E0 as a series in the joint."""
    g, e = ctx.geometry, ctx.errors
    tilt = g.tilt
    rp = (pins["x-rot-point"], pins["y-rot-point"], pins["z-rot-point"])
    off = [0.0, 0.0, pins["z-offset"]]
    off["XYZ".index("Y" if tilt == "A" else "X")] = pins["y-offset" if tilt == "A" else "x-offset"]
    geom = TrunnionGeometry(g.kind, rp, (off[0], off[1], off[2]), g.tool_length_mm,
                            dict(g.travel_deg))
    held = set(HELD[tilt]) | {"EX0C", "EY0C", "EC0C"}
    location = {k: float(v) for k, v in e.location.items() if k not in held}
    motions = {}
    for (axis, comp), coef in e.motions.items():
        c = np.asarray(coef, dtype=np.float64).reshape(-1, 2)  # rows k = 1..H: sin k t, cos k t
        k = np.arange(1, len(c) + 1)
        ph = np.deg2rad(zero_deg[axis]) * k  # sin k(j - E0) = sin kj cos kE0 - cos kj sin kE0
        s_new = c[:, 0] * np.cos(ph) + c[:, 1] * np.sin(ph)
        c_new = c[:, 1] * np.cos(ph) - c[:, 0] * np.sin(ph)
        motions[(axis, comp)] = np.column_stack([s_new, c_new]).reshape(-1)
    return write_five_blob(geom, FiveAxisErrors(location=location, motions=motions,
                                                squareness=e.squareness, linear=e.linear))


def _from(pin: str, tilt: str) -> str:
    return {"x-rot-point": "nominal + EX0C", "y-rot-point": "nominal + EY0C",
            "z-rot-point": "nominal (C has no Z location error)",
            "y-offset": "nominal + EY0A - EY0C", "x-offset": "nominal + EX0B - EX0C",
            "z-offset": f"nominal + EZ0{tilt}"}[pin]
