"""``marlin``: Marlin ``M852`` skew factors and ``M425`` backlash, as G-code lines.

Sources (MarlinFirmware/Marlin): Marlin/src/gcode/calibrate/M852.cpp (``M852 I<xy>
J<xz> K<yz>``, each within SKEW_FACTOR_MIN..MAX, J and K only with
SKEW_CORRECTION_FOR_Z; read with ``value_linear_units``, hence G21 first); the
planner's skew (a port of which is Klipper's calc_skew): x' = x - y xy - z (xz -
xy yz), y' = y - z yz; Marlin/src/gcode/calibrate/M425.cpp (``M425 F<0..1>
S<smoothing mm> X<mm> Y<mm> Z<mm>``) and Marlin/src/feature/backlash.cpp: on a
reversal toward + the axis gets ``distance_mm`` extra steps, toward - they are
taken back (applied steps d after a + move, 0 after a - move), spread over
``smoothing_mm`` of path; a negative distance is never applied (the correction is
clamped to the direction of motion).

Mapping: skew as ``klipper-skew``; M425 distance d = -OWN_SIGN B (the reversal
of the model's positioning, mean over the travel): what lost motion needs. The
smoothing is the model's take-up (largest over the axes).
"""

from __future__ import annotations

import numpy as np

from abbe.errors import AbbeInputError
from abbe.exports.klipper_skew import MASK, skew
from abbe.exports.linear import model_matrix, remainder
from abbe.exports.target import Context, Export, Option, Unheld, fmt, not_held
from abbe.exports.terms import Item, has_reversal, reversal_um
from abbe.model.table import AXES, OWN_SIGN

NAME = "marlin"
SUMMARY = "Marlin M852 skew factors and M425 backlash (G-code)"
DIGITS = 9
BACKLASH_DECIMALS = 4  # mm
OPTIONS = {
    "skew_factor_max": Option("float", 1.0, "SKEW_FACTOR_MAX of the firmware (|factor| limit)",
                              lo=0.0, hi=10.0, lo_open=True),
    "skew_z": Option("int", 1, "1 if the firmware has SKEW_CORRECTION_FOR_Z (J, K)", lo=0, hi=1),
}
SOURCES = ["Marlin Marlin/src/gcode/calibrate/M852.cpp (M852 I J K, SKEW_FACTOR_MIN/MAX)",
           "Marlin Marlin/src/gcode/calibrate/M425.cpp (M425 F S X Y Z)",
           "Marlin Marlin/src/feature/backlash.cpp (applied steps d after a + move, 0 after a - "
           "move; smoothing; negative distance never applied)"]


def build(ctx: Context) -> Export:
    zskew = bool(ctx.options["skew_z"])
    mask = MASK.copy()
    if not zskew:
        mask[:, 2] = False
    A = model_matrix(ctx, mask) * 1e-3
    xy, yz = A[0, 1], A[1, 2]
    xz = A[0, 2] + xy * yz
    fmax = float(ctx.options["skew_factor_max"])
    for k, v in (("I (xy)", xy), ("J (xz)", xz), ("K (yz)", yz)):
        if abs(v) > fmax:
            raise AbbeInputError(f"skew factor {k} = {v:.6g} exceeds SKEW_FACTOR_MAX {fmax:g}",
                                 field="--set skew_factor_max")
    fac = {"I": f"{xy:.{DIGITS}f}", "J": f"{xz:.{DIGITS}f}", "K": f"{yz:.{DIGITS}f}"}
    q = {k: float(v) for k, v in fac.items()}
    lines = ["; abbe export marlin: skew (M852) and backlash (M425); M500 stores them",
             "G21 ; millimetres: M852 and M425 read linear units"]
    lines.append("M852 " + " ".join(f"{k}{v}" for k, v in fac.items() if zskew or k == "I"))
    dist: dict[str, float] = {}
    unheld_bl: dict[str, str] = {}
    for j, a in enumerate(AXES):
        if not has_reversal(ctx.table, a):
            continue
        lo, hi = ctx.volume.travel_mm[a]
        B = float(np.mean(reversal_um(ctx.table, a, np.linspace(lo, hi, 101))))
        d_mm = -OWN_SIGN[a] * B * 1e-3
        if float(fmt(d_mm, BACKLASH_DECIMALS)) <= 0.0:
            unheld_bl[a] = (f"the model's reversal needs a distance of {d_mm * 1e3:.3f} um: "
                            "Marlin applies only positive backlash distances")
            continue
        dist[a] = float(fmt(d_mm, BACKLASH_DECIMALS))
    takeup = max((float(ctx.table.axes[a].backlash_takeup_mm) for a in dist), default=0.0)
    if dist:
        lines.append("M425 F1.0 S" + fmt(takeup, 3) + " "
                     + " ".join(f"{a}{fmt(d, BACKLASH_DECIMALS)}" for a, d in dist.items()))
    dvec = np.array([dist.get(a, 0.0) for a in AXES])

    def correction(pos: np.ndarray, state: np.ndarray) -> np.ndarray:
        c = (skew(pos, q["I"], q["J"] if zskew else 0.0, q["K"] if zskew else 0.0) - pos) * 1e3
        return c + 0.5 * (1.0 + np.clip(state, -1, 1)) * dvec[None, :] * 1e3

    def cannot(item: Item) -> Unheld | None:
        if item.kind == "backlash":
            if item.axis in unheld_bl:
                return Unheld(unheld_bl[item.axis])
            return None
        if item.kind == "thermal":
            return Unheld("no temperature input")
        return Unheld("only the parts of dX linear in y, z and of dY linear in z are held "
                      "(least squares over the work volume); shown: what is left",
                      remainder=remainder(mask))

    exp = [f"skew XY {xy * 1e6:.3f} urad" + (f", XZ {xz * 1e6:.3f}, YZ {yz * 1e6:.3f} urad"
                                              if zskew else " (no Z skew in this firmware)")]
    exp += [f"{a} backlash {d * 1e3:.1f} um (constant: the mean reversal)" for a, d in dist.items()]
    return Export(
        target=NAME, files={"marlin.gcode": ("\n".join(lines) + "\n").encode()},
        correction=correction, expressed=exp, not_held=not_held(ctx, cannot),
        direction=("takeup", takeup) if dist else "none",
        notes=["skew fitted over the work volume (21 x 21 x 21 points) about the machine origin",
               "Marlin spreads the backlash over S mm of path (segment by segment); modelled "
               "as a linear take-up over S mm of the axis' own travel"],
        assumptions=["Marlin's native coordinates are the model's machine coordinates (mm)"],
        sources=SOURCES)
