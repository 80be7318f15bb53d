"""``linuxcnc-matrixkins``: the 3x3 matrix of LinuxCNC's matrixkins kinematics.

Source: LinuxCNC src/hal/components/matrixkins.comp: ``kinematicsInverse``
computes joint = C * axis (X_joint = C_xx X + C_xy Y + C_xz Z, ...) with HAL
parameters ``matrixkins.C_xx`` .. ``C_zz`` (doubles, default identity);
``kinematicsForward`` applies the inverse matrix; ``[KINS] KINEMATICS =
matrixkins``. It corrects scale (diagonal) and squareness / skew (off-diagonal)
about the machine origin.

Mapping: the model's error is fitted over the work volume by E(p) ~ b + A p
(:mod:`.linear`, all nine entries free); commanding joints j reaches j + A j, so
C = (I + A)^-1 puts the tool on p. Everything not linear in the positions (the
fitted terms' curvature and waves, backlash, thermal) is not held.
"""

from __future__ import annotations

import numpy as np

from abbe.exports.linear import model_matrix, remainder
from abbe.exports.target import Context, Export, Option, Unheld, not_held
from abbe.exports.terms import Item

NAME = "linuxcnc-matrixkins"
SUMMARY = "LinuxCNC matrixkins C_xx..C_zz (scale and squareness, 3x3 about the origin)"
DIGITS = 15  # significant digits of each coefficient
KEYS = ("xx", "xy", "xz", "yx", "yy", "yz", "zx", "zy", "zz")
OPTIONS = {
    "component": Option("str", "matrixkins", "HAL component (instance) name",
                        pattern=r"[A-Za-z_][A-Za-z0-9_-]{0,40}"),
}
SOURCES = ["LinuxCNC src/hal/components/matrixkins.comp (joint = C * axis, C_xx..C_zz, "
           "inverse matrix in kinematicsForward)"]
MASK = np.ones((3, 3), dtype=bool)


def _cannot(item: Item) -> Unheld | None:
    if item.kind == "backlash":
        return Unheld("a kinematics matrix has no direction dependence")
    if item.kind == "thermal":
        return Unheld("no temperature input")
    return Unheld("only the part linear in the positions is held (least squares over the "
                  "work volume); shown: what is left", remainder=remainder(MASK))


def build(ctx: Context) -> Export:
    A = model_matrix(ctx, MASK) * 1e-3  # um/mm -> dimensionless
    C = np.linalg.inv(np.eye(3) + A)
    txt = [f"{v:.{DIGITS}g}" for v in C.reshape(-1)]
    Cq = np.array([float(v) for v in txt]).reshape(3, 3)
    comp = ctx.options["component"]
    hal = ["# abbe export linuxcnc-matrixkins: add to the HAL file; INI: [KINS] KINEMATICS = "
           "matrixkins", "# joint = C * axis (machine coordinates, mm)"]
    hal += [f"setp {comp}.C_{k} {t}" for k, t in zip(KEYS, txt)]
    ini = ["# abbe export linuxcnc-matrixkins", "[KINS]", "KINEMATICS = matrixkins",
           "JOINTS = 3"]

    def correction(pos: np.ndarray, state: np.ndarray) -> np.ndarray:
        return (pos @ (Cq - np.eye(3)).T) * 1e3

    scale = {a: round(float(A[i, i]) * 1e6, 3) for i, a in enumerate("XYZ")}
    return Export(
        target=NAME,
        files={"matrixkins.hal": ("\n".join(hal) + "\n").encode(),
               "matrixkins.ini": ("\n".join(ini) + "\n").encode()},
        correction=correction,
        expressed=["the part of the model linear in the positions: scale per axis "
                   f"{scale} ppm and the off-diagonal skew (squareness and linear trends)"],
        not_held=not_held(ctx, _cannot), direction="none",
        notes=["C = (I + A)^-1 with A the least-squares linear part of the model over the "
               "work volume (21 x 21 x 21 points)",
               "matrixkins applies C about the machine origin: the constant it shifts is the "
               "work offset's (constant_offset_um)"],
        assumptions=["axis and joint coordinates are the model's machine coordinates (mm)"],
        sources=SOURCES)
