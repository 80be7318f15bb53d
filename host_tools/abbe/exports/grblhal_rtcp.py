"""``grblhal-rtcp-ac``: the identified A/C trunnion geometry as the settings $640..$645
of grblHAL's experimental ``kinematics/rtcp_ac.c`` (xyzac only).

Source: grblHAL core kinematics/rtcp_ac.c (snapshot 868991815d29, marked
"EXPERIMENTAL AND UNTESTED"): settings ``Setting_Kinematics0..5`` = $640..$645,
"RTCP A offset X/Y/Z" (``a_vector``: machine zero to the A rotary centre) and
"RTCP C offset X/Y/Z" (``c_vector``: A centre to the C rotary centre), mm, range
[-1000, 1000], format ``#####0.000``, float32. ``rtcp_forward`` maps a point p of
the RTCP coordinate system (relative to the C centre) to the machine:
``q = a + Rx(A) (c + Rz(C) p)``; M852 sets p's origin from the G5x offset by
``rtcp_inverse`` with the same settings.

Mapping: a = the identified A line's point (y, z) with x = the C centre's x (the
file's defaults note x as "where C sits on top of A"); c = C centre - a, so
a + c is the identified C centre (EX0C, EY0C) and a the A line (EY0A, EZ0A).
rtcp_ac has no place for the angular zeros (EA0A, EC0C), the tilts, the error
motions and the linear axes' errors.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from abbe.errors import AbbeInputError
from abbe.exports.five_axis import (
    POSE_OPTIONS,
    FiveContext,
    FiveExport,
    identified_lines,
    not_held,
)
from abbe.exports.target import fmt

NAME = "grblhal-rtcp-ac"
SUMMARY = "grblHAL rtcp_ac (experimental): A and C rotary centres as settings $640..$645"
FIVE_AXIS = True
FIRST_SETTING = 640   # Setting_Kinematics0
DECIMALS = 3          # the settings' format #####0.000
LIMIT_MM = 1000.0     # the settings' range
OPTIONS = dict(POSE_OPTIONS)
SOURCES = ["grblHAL core kinematics/rtcp_ac.c (snapshot 868991815d29): rtcp_forward, "
           "rtcp_inverse, rtcp_settings[] ($640..$645 RTCP A offset X/Y/Z, RTCP C offset "
           "X/Y/Z, mm, -1000..1000, #####0.000), M852",
           "grblHAL core settings.h: Setting_Kinematics0 = 640"]
HELD = {"EX0C", "EY0C", "EY0A", "EZ0A"}
LABELS = ("RTCP A offset X", "RTCP A offset Y", "RTCP A offset Z",
          "RTCP C offset X", "RTCP C offset Y", "RTCP C offset Z")


def _cannot(label: str, kind: str) -> str | None:
    if kind == "location":
        if label in HELD:
            return None
        if label in ("EA0A", "EC0C"):
            return "an angular zero: rtcp_ac has no setting for it (the axis' home position)"
        return "a tilt of an axis line: rtcp_ac holds the two centres only"
    if kind == "error motion":
        return "angle-dependent: rtcp_ac has constant geometry"
    if kind == "squareness":
        return "linear-axis squareness: not part of rtcp_ac"
    return "linear-axis errors: not part of rtcp_ac"


def rtcp_forward(a: np.ndarray, c: np.ndarray, p: np.ndarray, angles_deg: np.ndarray) -> np.ndarray:
    """rtcp_ac.c's forward transform in float32 as the controller computes it: machine
    positions (N, 3) mm of RTCP points p (N, 3) at angles (N, 2) = (A, C) deg."""
    f = np.float32
    p = np.asarray(p, dtype=f).reshape(-1, 3)
    A = np.deg2rad(np.asarray(angles_deg, dtype=np.float64).reshape(-1, 2)).astype(f)
    ca, sa = np.cos(A[:, 0]), np.sin(A[:, 0])
    cc, sc = np.cos(A[:, 1]), np.sin(A[:, 1])
    a, c = np.asarray(a, dtype=f), np.asarray(c, dtype=f)
    u = p[:, 0] * sc + p[:, 1] * cc + c[1]
    v = p[:, 2] + c[2]
    x = a[0] + p[:, 0] * cc - p[:, 1] * sc + c[0]
    y = a[1] + u * ca - v * sa
    z = a[2] + u * sa + v * ca
    return np.column_stack([x, y, z]).astype(np.float64)


def build(ctx: FiveContext) -> FiveExport:
    g = ctx.geometry
    if g.kind != "xyzac-trt":
        raise AbbeInputError(f"grblHAL's rtcp_ac is an A/C table-table kinematics; the model is "
                             f"{g.kind}", file=ctx.model_source, field="rotary.kind")
    pc, pa = identified_lines(ctx)
    a = np.array([pc[0], pa[1], pa[2]])
    c = pc - a
    vals = list(a) + list(c)
    for k, (lab, v) in enumerate(zip(LABELS, vals)):
        if not abs(v) <= LIMIT_MM:
            raise AbbeInputError(f"${FIRST_SETTING + k} ({lab}) would be {v:.3f} mm, outside "
                                 f"the setting's range [-{LIMIT_MM:g}, {LIMIT_MM:g}] mm",
                                 file=ctx.machine_source, field="rotary")
    text = [fmt(v, DECIMALS) for v in vals]
    aq = np.array([float(t) for t in text[:3]])
    cq = np.array([float(t) for t in text[3:]])
    nom_c = np.asarray(g.rot_point_mm, dtype=np.float64)
    nom_a = np.array([nom_c[0], *np.asarray(g.pivot("A"))[1:]])
    nominal = list(nom_a) + list(nom_c - nom_a)
    lines = ["; abbe export grblhal-rtcp-ac: identified A/C centres for grblHAL's rtcp_ac "
             "(kinematics/rtcp_ac.c, experimental), mm",
             f"; model: {Path(ctx.model_source).name}; nominal from {ctx.machine_source}",
             "; send each line to the controller (or paste into a sender); then set the work "
             "offset and issue M852 as rtcp_ac requires"]
    for k, (lab, t) in enumerate(zip(LABELS, text)):
        lines.append(f"; {lab}: nominal {fmt(nominal[k], DECIMALS)}, change "
                     f"{fmt((float(t) - nominal[k]) * 1e3, 1)} um")
        lines.append(f"${FIRST_SETTING + k}={t}")

    def joints(work_mm: np.ndarray, angles_deg: np.ndarray):
        ang = np.asarray(angles_deg, dtype=np.float64).reshape(-1, 2)
        # M852 at the work offset: the RTCP origin is the written C centre a + c
        p = np.asarray(work_mm, dtype=np.float32) - (aq + cq).astype(np.float32)
        return rtcp_forward(aq, cq, p, ang), ang

    unobs = [n for n in ctx.not_observable if n in HELD]
    notes = ["rtcp_ac computes in float32: the residual includes it (the joints here are "
             "computed in float32 as rtcp_forward does)",
             "the settings' format has 3 decimals: 1 um steps"]
    if unobs:
        notes.append("written at their nominal value (not observable by the fit): "
                     + ", ".join(unobs))
    return FiveExport(
        target=NAME, files={"rtcp_ac.nc": ("\n".join(lines) + "\n").encode()},
        joints=joints,
        expressed=[{"setting": f"${FIRST_SETTING + k}", "name": lab, "value_mm": float(t),
                    "nominal_mm": float(nominal[k])}
                   for k, (lab, t) in enumerate(zip(LABELS, text))],
        not_held=not_held(ctx, _cannot), notes=notes,
        assumptions=[
            "rtcp_ac.c is marked experimental and untested upstream: confirm the settings' "
            "numbers ($640 = Setting_Kinematics0) and signs on the machine",
            "abbe's machine coordinates are grblHAL's machine coordinates, A about +X and C "
            "about +Z right-handed (as rtcp_forward); tool length 0 (rtcp_ac adds it to Z)",
            "the work offset's origin is related to the C centre by M852 with these settings "
            "(the RTCP origin is the written C centre)",
            "the angular zeros (EA0A, EC0C) stay in the axes' homing: not corrected"],
        sources=SOURCES)
