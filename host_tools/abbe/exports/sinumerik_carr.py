"""``sinumerik-carr``: the identified trunnion geometry as a SINUMERIK toolholder data
set with orientation capability (``$TC_CARR``, the swivel data record of CYCLE800),
kinematic type P (only the part rotates), as a part program that assigns it.

Sources (docs/exports.md cites the pages): SINUMERIK function manual W1 "Tool offset",
toolholder with orientation capability (the $TC_CARR1..65 list: l1 = 1..3, l2 = 4..6,
v1 = 7..9, v2 = 10..12, l3 = 15..17, l4 = 18..20, axis identifiers 21/22, kinematic
type 23 T/P/M, offsets of the rotary axes 24/25: "the initial state of the rotary axis
is the position specified by the parameter"); SINUMERIK Operate commissioning manual,
swivelling / CYCLE800 (swivel table: l2 from the machine reference point to the pivot of
rotary axis 1, l3 from there to the pivot of rotary axis 2, l4 = -(l2 + l3) closing the
chain; rotary axis 2 is carried by rotary axis 1; the checklist's right-hand rule: an
axis that moves the workpiece changes the sign of its rotary axis vector).

The chain of type P, written out: a workpiece point w (the non-swivelled state) is at
machine position ``q = l2 + R(v1, a1) (l3 + R(v2, a2) (l4 + w))``, R(v, a) the
right-handed rotation of the part by a about v, a = axis position - offset (24/25).
With the model's lines (abbe.model.five_axis: each line a rigid motion of the nominal
about its pivot) this holds every location error: the points of the actual lines (the
trt mapping), their directions (v1, v2 carry the tilts EB0A, EC0A, EA0C, EB0C; for B
EA0B, EC0B) and the angular zeros (24/25 = -E0). Left: the error motions, squareness
and the linear axes.
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
    zero_offsets_deg,
)
from abbe.exports.target import Option, fmt
from abbe.model.five_axis import AXIS_DIRECTION, LOCATION_ERRORS

NAME = "sinumerik-carr"
SUMMARY = ("Siemens SINUMERIK toolholder data $TC_CARR (CYCLE800 swivel data record, "
           "type P): offset vectors l2..l4, rotary axis vectors v1, v2, angle offsets")
FIVE_AXIS = True
MM_DECIMALS = 6    # 1 nm
VEC_DECIMALS = 9   # 1e-9 of a unit vector: 1 nrad
DEG_DECIMALS = 9   # 1e-9 deg = 0.017 urad
#: abbe's bound on a toolholder number (MD18088 $MN_MM_NUM_TOOL_CARRIER sets the control's).
MAX_CARRIER = 99
OPTIONS = {
    "carrier": Option("int", 1, "number m of the toolholder data set $TC_CARRn[m] (at most "
                      "MD18088 MM_NUM_TOOL_CARRIER of the control)", lo=1, hi=MAX_CARRIER),
    "tilt_axis": Option("str", "", "channel axis name of rotary axis 1 (the tilt), "
                        "$TC_CARR21 (default A or B by the model)",
                        pattern=r"[A-Z][A-Z0-9_]{0,7}|"),
    "c_axis": Option("str", "C", "channel axis name of rotary axis 2 (the table), $TC_CARR22",
                     pattern=r"[A-Z][A-Z0-9_]{0,7}"),
    "program": Option("str", "ABBE_CARR", "part program name (file PROGRAM.MPF, header "
                      "%_N_PROGRAM_MPF)", pattern=r"[A-Z][A-Z0-9_]{0,23}"),
    **POSE_OPTIONS,
}
SOURCES = [
    "SINUMERIK 840D sl / 828D function manual W1 Tool offset, 'Toolholder with orientation "
    "capability' (09/2011, 6FC5397-0BP40-2BA0, pp. 1502-1503: $TC_CARR1..33 and 34..65; "
    "08/2005, 6FC5397-0BP10-0BA0, 2-85..2-86 and the example 4-3 with $TC_CARR23 = \"P\")",
    "SINUMERIK 840D sl function manual (rotary axis offset $TC_CARR24/25: 'the initial "
    "state of the associated rotary axis is the position specified by the parameter')",
    "SINUMERIK Operate commissioning manual, swivelling / CYCLE800 (10/2015, 6FC5397-3DP40-"
    "5BA3, p. 157: swivel table l2, l3, l4 = -(l2 + l3), rotary axis vectors; 03/2013, "
    "6FC5397-1DP40-3BA1, p. 502: offset vectors refer to the non-swivelled state; CYCLE800 "
    "checklist: right-hand rule, sign of the rotary axis vector of a workpiece axis)",
]
#: the $TC_CARR parameter numbers of each vector (x, y, z).
L1, L2, V1, V2, L3, L4 = (1, 2, 3), (4, 5, 6), (7, 8, 9), (10, 11, 12), (15, 16, 17), (18, 19, 20)


def _cannot(label: str, kind: str) -> str | None:
    if kind == "location":
        return None  # positions (l2, l3), directions (v1, v2), zeros ($TC_CARR24/25)
    if kind == "error motion":
        return "angle-dependent: a toolholder data set has constant geometry"
    if kind == "squareness":
        return "linear-axis squareness: not part of the toolholder data"
    return "linear-axis errors: not part of the toolholder data (LEC / CEC, abbe's own)"


def carr_machine_position(vec: dict[str, np.ndarray], work_mm: np.ndarray,
                          rot_deg: np.ndarray) -> np.ndarray:
    """Machine positions (N, 3) mm of workpiece points by the type P chain
    ``l2 + R(v1, a1) (l3 + R(v2, a2) (l4 + w))``; rot_deg (N, 2) = (a1, a2), the rotations
    (axis positions minus the offsets)."""
    w = np.asarray(work_mm, dtype=np.float64).reshape(-1, 3)
    r = np.asarray(rot_deg, dtype=np.float64).reshape(-1, 2)
    inner = np.einsum("nij,nj->ni", axis_rotation(vec["v2"], r[:, 1]), w + vec["l4"]) + vec["l3"]
    return np.einsum("nij,nj->ni", axis_rotation(vec["v1"], r[:, 0]), inner) + vec["l2"]


def build(ctx: FiveContext) -> FiveExport:
    g, o = ctx.geometry, ctx.options
    tilt = g.tilt
    tilt_name = o["tilt_axis"] or tilt
    if tilt_name == o["c_axis"]:
        raise AbbeInputError(f"rotary axis 1 and 2 are both named {tilt_name}",
                             field="--set c_axis")
    pc, pt = identified_lines(ctx)
    vecs = {"l1": np.zeros(3), "l2": pt, "v1": identified_direction(ctx, tilt),
            "v2": identified_direction(ctx, "C"), "l3": pc - pt, "l4": -pc}
    dec = {"l1": MM_DECIMALS, "l2": MM_DECIMALS, "l3": MM_DECIMALS, "l4": MM_DECIMALS,
           "v1": VEC_DECIMALS, "v2": VEC_DECIMALS}
    text = {k: [fmt(float(x), dec[k]) for x in v] for k, v in vecs.items()}
    # l4 closes the chain of the values as written, so that A = C = 0 is the identity
    l2q = np.array([float(t) for t in text["l2"]])
    l3q = np.array([float(t) for t in text["l3"]])
    text["l4"] = [fmt(float(x), MM_DECIMALS) for x in -(l2q + l3q)]
    written = {k: np.array([float(t) for t in v]) for k, v in text.items()}
    zero_deg = zero_offsets_deg(ctx)
    off_text = [fmt(-zero_deg[tilt], DEG_DECIMALS), fmt(-zero_deg["C"], DEG_DECIMALS)]
    off = np.array([float(t) for t in off_text])

    nom_c = np.asarray(g.rot_point_mm, dtype=np.float64)
    nom_t = np.asarray(g.pivot(tilt), dtype=np.float64)
    nominal = {"l1": np.zeros(3), "l2": nom_t, "l3": nom_c - nom_t, "l4": -nom_c,
               "v1": np.asarray(AXIS_DIRECTION[tilt]), "v2": np.asarray(AXIS_DIRECTION["C"])}
    m = o["carrier"]
    names = {"l1": "offset vector l1 (tool side, not used by type P)",
             "l2": f"offset vector l2: machine reference point to the {tilt} axis (rotary axis 1)",
             "v1": f"rotary axis vector v1 ({tilt})",
             "v2": "rotary axis vector v2 (C)",
             "l3": f"offset vector l3: {tilt} axis to the C axis (rotary axis 2)",
             "l4": "offset vector l4 = -(l2 + l3), closing the chain"}
    unit = {"l1": "mm", "l2": "mm", "l3": "mm", "l4": "mm", "v1": "", "v2": ""}
    lines = [f"%_N_{o['program']}_MPF",
             f"; abbe export sinumerik-carr: identified geometry of {g.kind} as toolholder data "
             f"set {m} (kinematic type P, swivel table; mm, deg)",
             f"; model: {Path(ctx.model_source).name}; nominal from {ctx.machine_source}",
             "; machine coordinates = the MCS with the machine reference point at its zero; "
             "run once (or merge into the data set's archive), then check CYCLE800 on the "
             "machine (docs/exports.md, sinumerik-carr)"]
    n = 0

    def put(par: int, value: str, comment: str) -> None:
        nonlocal n
        n += 10
        lines.append(f"N{n} $TC_CARR{par}[{m}]={value} ; {comment}")

    for key, pars in (("l1", L1), ("l2", L2), ("v1", V1), ("v2", V2), ("l3", L3), ("l4", L4)):
        for j, par in enumerate(pars):
            change = (written[key][j] - nominal[key][j])
            ch = (f"{fmt(change * 1e3, 3)} um" if unit[key] else f"{fmt(change * 1e6, 3)} urad")
            put(par, text[key][j], f"{'xyz'[j]} of {names[key]}; nominal "
                f"{fmt(float(nominal[key][j]), dec[key])}, change {ch}")
    put(21, tilt_name, f"rotary axis 1 = channel axis {tilt_name}")
    put(22, o["c_axis"], f"rotary axis 2 = channel axis {o['c_axis']}")
    put(23, '"P"', "kinematic type P: only the part rotates")
    for par, axis, t in ((24, tilt, off_text[0]), (25, "C", off_text[1])):
        put(par, t, f"offset of rotary axis {1 if par == 24 else 2} ({axis}), deg: -E{axis}0{axis} "
            f"({fmt(-ctx.errors.location.get(f'E{axis}0{axis}', 0.0), 3)} urad)")
    n += 10
    lines.append(f"N{n} M30")

    def joints(work_mm: np.ndarray, angles_deg: np.ndarray):
        ang = np.asarray(angles_deg, dtype=np.float64).reshape(-1, 2)
        # the control turns the part by (axis - offset) = the programmed angle
        return carr_machine_position(written, work_mm, ang), ang + off[None, :]

    expressed = []
    for key, pars in (("l2", L2), ("v1", V1), ("v2", V2), ("l3", L3), ("l4", L4)):
        expressed.append({"parameters": [f"$TC_CARR{p}[{m}]" for p in pars],
                          "name": names[key], "value": [float(x) for x in written[key]],
                          "nominal": [float(x) for x in nominal[key]],
                          "unit": unit[key] or "1 (unit vector)", "from": _from(key, tilt)})
    for par, axis, v in ((24, tilt, off[0]), (25, "C", off[1])):
        expressed.append({"parameters": [f"$TC_CARR{par}[{m}]"],
                          "name": f"offset of rotary axis {axis}", "value": float(v),
                          "nominal": 0.0, "unit": "deg", "from": f"-E{axis}0{axis}"})
    held = set(LOCATION_ERRORS[tilt]) | set(LOCATION_ERRORS["C"])
    notes = ["the control computes the tool tip from the axis positions with these values "
             "(CYCLE800 / TCARR frames): the linear axes move so that the programmed point "
             "stays under the tool as the table turns",
             "v1, v2 are written as unit vectors (9 decimals), so it does not matter whether "
             "the control normalises them",
             "$TC_CARR1..3 (l1) are written 0: type P has no tool-side rotary axis; the other "
             "fields of the data set (name $TC_CARR34, Hirth 26..29, limits 30..33, user and "
             "retraction fields 35..40, fine offsets 41..65) are not touched"]
    notes += unobservable_notes(ctx, held)
    return FiveExport(
        target=NAME,
        files={f"{o['program']}.MPF": ("\n".join(lines) + "\n").encode()},
        joints=joints, expressed=expressed, not_held=not_held(ctx, _cannot), notes=notes,
        assumptions=[
            "the control composes the data set as q = l2 + R(v1, a1) (l3 + R(v2, a2) (l4 + w)) "
            "(abbe's reading of the Siemens pages: no reachable page prints the formula)",
            "abbe's machine coordinates are the MCS, the machine reference point of l2 at "
            "its zero; tool length 0 (the control adds the active tool's length)",
            f"rotary axis 1 is the tilt ({tilt_name}) carrying rotary axis 2 ({o['c_axis']}); "
            "R(v, a) turns the part right-handed about v as the axis position grows: abbe's "
            "model (A about +X, B about +Y, C about +Z of the table, as trtfuncs.c); on a "
            "machine whose positive table rotation is the ISO 841 one for a workpiece axis "
            "(Siemens' checklist: the vector's sign changes) the model's angles and this data "
            "set's vectors both have the other sign: confirm one swivel on the machine",
            "$TC_CARR24/25 hold the position of the axis at the initial state (the part turns "
            "by axis position - offset); the data set has no fine offsets active "
            "(they add to l1..l4 and the offsets), or they are zeroed",
            "$TC_CARR21/22 name the channel axes, so the control takes their positions "
            "(not $TC_CARR13/14)"],
        sources=SOURCES)


def _from(key: str, tilt: str) -> str:
    n1, n2, t1, t2, _ = LOCATION_ERRORS[tilt]
    return {"l2": f"nominal {tilt} pivot + ({n1}, {n2})",
            "v1": f"nominal direction of {tilt} turned by {t1}, {t2}",
            "v2": "nominal direction of C turned by EA0C, EB0C",
            "l3": "C centre + (EX0C, EY0C) - l2",
            "l4": "-(l2 + l3) as written"}[key]
