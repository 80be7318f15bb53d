"""``rrf-m556``: RepRapFirmware ``M556`` axis skew compensation, as a G-code line.

Sources (Duet3D/RepRapFirmware): ``Move::AxisTransform`` (src/Movement/Move.cpp;
Move3.cpp in 3.6): a move to p goes to x' = x + tanXY y + tanXZ z, y' = y + tanYZ z
(the default ``P0``: X carries the XY compensation), z unchanged; the inverse takes
them back in the opposite order. ``M556 S<length> X<dev> Y<dev> Z<dev>`` sets
tanXY = X / S, tanYZ = Y / S, tanXZ = Z / S (the G-code dictionary: "Axis
compensations - XY: 0.00700, YZ: -0.00200, ZX: 0.00600" for ``M556 S100 X0.7
Y-0.2 Z0.6``); ``S1`` makes X, Y, Z the tangents themselves.

Mapping: as ``klipper-skew``, the model's linear parts fitted over the work volume,
dX ~ b + k_xy y + k_xz z, dY ~ b + k_yz z (:mod:`.linear`); the machine reaches
p + E(p), so tanXY = -k_xy, tanXZ = -k_xz, tanYZ = -k_yz make AxisTransform(p) - p
= -E for that linear part, with no cross term (RRF's x' reads the untransformed y).
RepRapFirmware has no scale, no Z skew from X/Y, no table: the rest is named.
"""

from __future__ import annotations

import numpy as np

from abbe.exports.klipper_skew import MASK
from abbe.exports.linear import model_matrix, remainder
from abbe.exports.target import Context, Export, Option, Unheld, not_held
from abbe.exports.terms import Item

NAME = "rrf-m556"
SUMMARY = "RepRapFirmware M556 axis skew compensation (G-code)"
DIGITS = 6  # decimals of the deviations over S
OPTIONS = {"length": Option("float", 100.0, "S: the length the deviations are given over, mm",
                            lo=1.0, hi=10000.0)}
SOURCES = ["RepRapFirmware src/Movement/Move.cpp Move::AxisTransform / InverseAxisTransform "
           "(x += tanXY y + tanXZ z, y += tanYZ z)",
           "RepRapFirmware G-code dictionary, M556 (S, X, Y, Z, P; tanXY = X/S, tanYZ = Y/S, "
           "tanXZ = Z/S)"]


def transform(p: np.ndarray, xy: float, xz: float, yz: float) -> np.ndarray:
    """RepRapFirmware's AxisTransform on points (N, 3) mm."""
    out = np.array(p, dtype=np.float64)
    out[:, 0] = p[:, 0] + xy * p[:, 1] + xz * p[:, 2]
    out[:, 1] = p[:, 1] + yz * p[:, 2]
    return out


def _cannot(item: Item) -> Unheld | None:
    if item.kind == "backlash":
        return Unheld("M556 has no direction dependence")
    if item.kind == "thermal":
        return Unheld("no temperature input")
    return Unheld("only the parts of dX linear in y, z and of dY linear in z are held "
                  "(least squares over the work volume); shown: what is left",
                  remainder=remainder(MASK))


def build(ctx: Context) -> Export:
    length = float(ctx.options["length"])
    A = model_matrix(ctx, MASK) * 1e-3
    tan = {"XY": -A[0, 1], "XZ": -A[0, 2], "YZ": -A[1, 2]}
    dev = {"X": f"{tan['XY'] * length:.{DIGITS}f}", "Y": f"{tan['YZ'] * length:.{DIGITS}f}",
           "Z": f"{tan['XZ'] * length:.{DIGITS}f}"}
    q = {k: float(v) / length for k, v in dev.items()}
    lines = ["; abbe export rrf-m556: axis skew compensation (config.g, or M500 with config-override.g)",
             f"M556 S{length:g} X{dev['X']} Y{dev['Y']} Z{dev['Z']}"]

    def correction(pos: np.ndarray, state: np.ndarray) -> np.ndarray:
        return (transform(pos, q["X"], q["Z"], q["Y"]) - pos) * 1e3

    return Export(
        target=NAME, files={"rrf_m556.g": ("\n".join(lines) + "\n").encode()},
        correction=correction,
        expressed=[f"tanXY {tan['XY'] * 1e6:.3f} urad, tanXZ {tan['XZ'] * 1e6:.3f} urad, "
                   f"tanYZ {tan['YZ'] * 1e6:.3f} urad (squareness and the linear cross trends "
                   "of the fitted terms; deviations over S = "
                   f"{length:g} mm)"],
        not_held=not_held(ctx, _cannot), direction="none",
        notes=["tangents fitted over the work volume (21 x 21 x 21 points), about the machine "
               "origin; P0 (X carries the XY compensation, RepRapFirmware's default)"],
        assumptions=["RepRapFirmware's machine coordinates are the model's (mm); no bed "
                     "compensation active on the same effect"],
        sources=SOURCES)
