"""``isg-kin91``: the identified trunnion geometry as the rotary axes of the ISG / Beckhoff
TwinCAT CNC universal kinematics (kinematic ID 91, TF5240), a channel parameter list
fragment.

Sources (docs/exports.md cites the pages): TF5240 "Programming or description of the
kinematic chain" (every component in the same coordinate system; per axis ``type`` 1
linear / 2 rotary, ``orientation`` a direction vector, ``point`` a point of a rotary
axis), "3. Example of an AC machine with cardanic table" (the axes in the sequence from
the workpiece to the machine origin and on to the tool tip, C, A, X, Y, Z; "the
orientation vector must be multiplied by -1 for every axis that is located on the
workpiece side"), the channel parameters P-CHAN-00291 (type), P-CHAN-00292 (orientation,
REAL64, not a zero vector), P-CHAN-00293 (point, REAL64 in 0.1 um), V3.00 syntax
``trafo[j].axis[k].…``.

So a rotary axis of the table is written as the line it turns about: ``point`` = a point
of the identified line (0.1 um), ``orientation`` = minus its identified direction (the
tilts EB0A, EC0A, EA0C, EB0C; for B EA0B, EC0B). The universal kinematics has no angle
offset of an axis: the angular zeros (EA0A / EB0B, EC0C) are not held (they belong to
the axes' own reference positions), nor are the error motions, squareness and the
linear axes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from abbe.errors import AbbeInputError
from abbe.exports.five_axis import (
    POSE_OPTIONS,
    FiveContext,
    FiveExport,
    axis_rotation,
    identified_direction,
    identified_lines,
    not_held,
    unobservable_notes,
)
from abbe.exports.target import Option, fmt
from abbe.model.five_axis import AXIS_DIRECTION, LOCATION_ERRORS

NAME = "isg-kin91"
SUMMARY = ("ISG / Beckhoff TwinCAT CNC universal kinematics (ID 91): the rotary axes' points "
           "and orientation vectors (channel parameter list)")
FIVE_AXIS = True
POINT_DECIMALS = 2  # in 0.1 um: 1 nm
VEC_DECIMALS = 9    # 1 nrad
OPTIONS = {
    "trafo": Option("int", 0, "transformation entry j of trafo[j] (P-CHAN-00262 id 91)",
                    lo=0, hi=9),
    "tilt_index": Option("int", 3, "axis index k of the tilt axis in trafo[j].axis[k]",
                         lo=0, hi=5),
    "c_index": Option("int", 4, "axis index k of the C axis in trafo[j].axis[k]", lo=0, hi=5),
    **POSE_OPTIONS,
}
SOURCES = [
    "Beckhoff TF5240 Universal Kinematics: 'Programming or description of the kinematic "
    "chain' (https://infosys.beckhoff.com/content/1033/tf5240_universal_kinematic/278674827.html)",
    "Beckhoff TF5240: '3. Example of an AC machine with cardanic table' (chain C, A, X, Y, Z; "
    "orientation x -1 on the workpiece side; "
    "https://infosys.beckhoff.com/content/1033/tf5240_universal_kinematic/278732555.html)",
    "Beckhoff TF5200 channel parameters P-CHAN-00291 axis type, P-CHAN-00292 axis orientation, "
    "P-CHAN-00293 interpolation point on the axis (REAL64, 0.1 um; "
    "https://infosys.beckhoff.com/content/1033/tf5200_channel_parameter/149266827.html)",
]


def _cannot(label: str, kind: str) -> str | None:
    if kind == "location":
        if label.startswith("E") and label[1] == label[-1]:  # EA0A, EB0B, EC0C
            return ("an angular zero: the universal kinematics has no angle offset (the "
                    "axis' reference position)")
        return None
    if kind == "error motion":
        return "angle-dependent: the universal kinematics has constant geometry"
    if kind == "squareness":
        return "linear-axis squareness: not written (linear axes left as configured)"
    return "linear-axis errors: not part of the kinematics (isg-csv / TF5280 holds them)"


def table_position(axes: dict[str, tuple[np.ndarray, np.ndarray]], work_mm: np.ndarray,
                   angles_deg: np.ndarray) -> np.ndarray:
    """Machine positions (N, 3) mm of workpiece points: each table axis turns the part by
    its angle about the line (point, direction) it was identified as; ``axes`` {"tilt",
    "c": (point mm, unit direction)}, angles (N, 2) = (tilt, C) deg."""
    w = np.asarray(work_mm, dtype=np.float64).reshape(-1, 3)
    ang = np.asarray(angles_deg, dtype=np.float64).reshape(-1, 2)
    pc, vc = axes["c"]
    pt, vt = axes["tilt"]
    inner = np.einsum("nij,nj->ni", axis_rotation(vc, ang[:, 1]), w - pc) + pc
    return np.einsum("nij,nj->ni", axis_rotation(vt, ang[:, 0]), inner - pt) + pt


def build(ctx: FiveContext) -> FiveExport:
    g, o = ctx.geometry, ctx.options
    tilt = g.tilt
    if o["tilt_index"] == o["c_index"]:
        raise AbbeInputError(f"the tilt and the C axis are both axis[{o['c_index']}]",
                             field="--set c_index")
    if min(o["tilt_index"], o["c_index"]) < 3:
        raise AbbeInputError("axis[0..2] are the linear axes X, Y, Z of a five-axis chain; "
                             "the rotary axes have indices 3..5", field="--set tilt_index")
    pc, pt = identified_lines(ctx)
    j = o["trafo"]
    written: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    lines = [f"# abbe export isg-kin91: identified rotary axes of {g.kind} for the universal "
             "kinematics (ID 91)",
             f"# model: {Path(ctx.model_source).name}; nominal from {ctx.machine_source}",
             "# merge into the channel parameter list beside the kinematics' other entries "
             f"(trafo[{j}].id 91, zero position and orientation, number_of_axes, chain, "
             "linear axes, programming mode: left as configured)",
             "# point: a point of the axis line, 0.1 um; orientation: minus the axis' direction "
             "(workpiece side, TF5240)"]
    for key, axis, k, p in (("tilt", tilt, o["tilt_index"], pt), ("c", "C", o["c_index"], pc)):
        v = identified_direction(ctx, axis)
        pt_text = [fmt(float(x) * 1e4, POINT_DECIMALS) for x in p]
        or_text = [fmt(-float(x), VEC_DECIMALS) for x in v]
        nom_p = np.asarray(g.pivot(axis), dtype=np.float64)
        nom_text = ", ".join(fmt(x * 1e4, POINT_DECIMALS) for x in nom_p)
        change = ", ".join(fmt((float(t) * 1e-4 - n) * 1e3, 3) for t, n in zip(pt_text, nom_p))
        lines.append(f"# {axis}: point nominal ({nom_text}), direction nominal "
                     f"{tuple(AXIS_DIRECTION[axis])}; point changes ({change}) um")
        base = f"trafo[{j}].axis[{k}]"
        lines.append(f"{base}.type 2")
        lines += [f"{base}.orientation[{i}] {t}" for i, t in enumerate(or_text)]
        lines += [f"{base}.point[{i}] {t}" for i, t in enumerate(pt_text)]
        written[key] = (np.array([float(t) for t in pt_text]) * 1e-4,
                        -np.array([float(t) for t in or_text]))

    def joints(work_mm: np.ndarray, angles_deg: np.ndarray):
        ang = np.asarray(angles_deg, dtype=np.float64).reshape(-1, 2)
        # RTCP: the programmed angles are the axis angles (TF5240 "incomplete")
        return table_position(written, work_mm, ang), ang

    expressed = [{"parameters": [f"trafo[{j}].axis[{k}].point[0..2]",
                                 f"trafo[{j}].axis[{k}].orientation[0..2]"],
                  "axis": axis, "point_mm": [float(x) for x in written[key][0]],
                  "direction": [float(x) for x in written[key][1]],
                  "from": f"nominal line moved by {', '.join(LOCATION_ERRORS[axis][:4])}"}
                 for key, axis, k in (("tilt", tilt, o["tilt_index"]), ("c", "C", o["c_index"]))]
    held = {n for a in (tilt, "C") for n in LOCATION_ERRORS[a][:4]}
    notes = ["with RTCP the control computes the tool tip from the axis angles with these lines: "
             "the linear axes move so that the programmed point stays under the tool",
             "orientations are written as unit vectors (9 decimals)"]
    notes += unobservable_notes(ctx, held)
    return FiveExport(
        target=NAME, files={"kin91_rotary.lis": ("\n".join(lines) + "\n").encode()},
        joints=joints, expressed=expressed, not_held=not_held(ctx, _cannot), notes=notes,
        assumptions=[
            "all components in one coordinate system (TF5240): abbe's machine coordinates with "
            "every axis at 0; the zero position of the tool is the tool tip there (tool length "
            "0), the linear axes are X, Y, Z along +x, +y, +z",
            f"the chain runs from the workpiece: C (axis[{o['c_index']}]), then {tilt} "
            f"(axis[{o['tilt_index']}]), then the linear axes; a workpiece-side axis turns the "
            "tool relative to the part right-handed about its orientation vector, which is why "
            "TF5240 negates it: the part turns right-handed about the direction as the angle "
            "grows (abbe's model, as trtfuncs.c) -- confirm one swivel on the machine",
            "RTCP (incomplete transformation): the programmed angles are the axis angles"],
        sources=SOURCES)
