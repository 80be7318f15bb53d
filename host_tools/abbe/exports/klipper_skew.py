"""``klipper-skew``: a Klipper ``[skew_correction NAME]`` profile (xy, xz, yz skew).

Source: Klipper klippy/extras/skew_correction.py: a move to p goes to
``calc_skew(p)`` = (x - y xy - z (xz - xy yz), y - z yz, z); profiles are the
config sections ``[skew_correction NAME]`` with ``xy_skew``, ``xz_skew``,
``yz_skew`` (tangent factors, loaded by ``SKEW_PROFILE LOAD=NAME``; the plain
``[skew_correction]`` section must exist too).

Mapping: the model is fitted over the work volume by dX ~ b + k_xy y + k_xz z and
dY ~ b + k_yz z (:mod:`.linear`); the machine reaches p + E(p), so the skew is
xy = k_xy, yz = k_yz, xz = k_xz + xy yz, which makes calc_skew(p) - p = -E(p) for
that linear part. Klipper has no scale, no Z correction from X/Y, no backlash,
no tables.
"""

from __future__ import annotations

import re

import numpy as np

from abbe.exports.linear import model_matrix, remainder
from abbe.exports.target import Context, Export, Option, Unheld, not_held
from abbe.exports.terms import Item

NAME = "klipper-skew"
SUMMARY = "Klipper [skew_correction NAME] profile: xy_skew, xz_skew, yz_skew"
DIGITS = 12
OPTIONS = {"profile": Option("str", "abbe", "profile name (SKEW_PROFILE LOAD=NAME)")}
SOURCES = ["Klipper klippy/extras/skew_correction.py (calc_skew, SKEW_PROFILE, "
           "[skew_correction NAME] xy_skew / xz_skew / yz_skew)"]
MASK = np.array([[False, True, True], [False, False, True], [False, False, False]])


def skew(p: np.ndarray, xy: float, xz: float, yz: float) -> np.ndarray:
    """Klipper's calc_skew on points (N, 3) mm."""
    out = np.array(p, dtype=np.float64)
    out[:, 0] = p[:, 0] - p[:, 1] * xy - p[:, 2] * (xz - xy * yz)
    out[:, 1] = p[:, 1] - p[:, 2] * yz
    return out


def _cannot(item: Item) -> Unheld | None:
    if item.kind == "backlash":
        return Unheld("skew correction has no direction dependence")
    if item.kind == "thermal":
        return Unheld("no temperature input")
    return Unheld("only the parts of dX linear in y, z and of dY linear in z are held "
                  "(least squares over the work volume); shown: what is left",
                  remainder=remainder(MASK))


def build(ctx: Context) -> Export:
    name = ctx.options["profile"]
    if not re.fullmatch(r"[A-Za-z0-9_\-]+", name):
        from abbe.errors import AbbeInputError
        raise AbbeInputError("a profile name of letters, digits, '_' and '-'", field="--set profile")
    A = model_matrix(ctx, MASK) * 1e-3
    xy, yz = A[0, 1], A[1, 2]
    xz = A[0, 2] + xy * yz
    txt = {k: f"{v:.{DIGITS}g}" for k, v in (("xy_skew", xy), ("xz_skew", xz), ("yz_skew", yz))}
    q = {k: float(v) for k, v in txt.items()}
    cfg = [f"# abbe export klipper-skew: add to printer.cfg, load with SKEW_PROFILE LOAD={name}",
           "# (tangent factors fitted to the model over the work volume)",
           "[skew_correction]", "", f"[skew_correction {name}]"]
    cfg += [f"{k} = {v}" for k, v in txt.items()]

    def correction(pos: np.ndarray, state: np.ndarray) -> np.ndarray:
        return (skew(pos, q["xy_skew"], q["xz_skew"], q["yz_skew"]) - pos) * 1e3

    return Export(
        target=NAME, files={"skew_correction.cfg": ("\n".join(cfg) + "\n").encode()},
        correction=correction,
        expressed=[f"XY skew {xy * 1e6:.3f} urad, XZ {xz * 1e6:.3f} urad, YZ {yz * 1e6:.3f} urad "
                   "(squareness and the linear cross trends of the fitted terms)"],
        not_held=not_held(ctx, _cannot), direction="none",
        notes=["factors fitted over the work volume (21 x 21 x 21 points), about the machine "
               "origin (Klipper's toolhead coordinates)"],
        assumptions=["Klipper's toolhead coordinates are the model's machine coordinates (mm)"],
        sources=SOURCES)
