"""``linuxcnc-comp``: one LinuxCNC ``COMP_FILE`` per joint (screw compensation).

Format (LinuxCNC docs/src/config/ini-config.adoc, ``[JOINT_n] COMP_FILE`` /
``COMP_FILE_TYPE``; loader src/emc/motion/usrmotintf.cc ``usrmotLoadComp``;
table src/emc/motion/command.c; interpolation src/emc/motion/control.c
``compute_screw_comp``): one triplet ``nominal forward reverse`` per line, machine
units (mm here), nominal strictly ascending, at most 256 triplets per joint
(``EMCMOT_COMP_SIZE``, src/emc/motion/motion.h). The loader stops at the first
line that is not three numbers, so the file holds nothing else (no comment).

* type 0: forward / reverse = the actual position reached moving + / -; the
  loader stores the trims ``nominal - forward``, ``nominal - reverse``;
* type 1: forward / reverse are the trims themselves (``nominal - actual``).

The trim (float32 in ``emcmot_comp_entry_t``) is added to the joint's commanded
position, linearly interpolated between the nominals (float32 slopes) and held
beyond the first and last one; moving + uses the forward trim, moving - the
reverse one, at rest the last value is kept. ``BACKLASH`` is ignored when a
COMP_FILE is given, so the reversal goes into the two columns.

What it holds: each joint's own positioning error on the line through the
reference point, both directions (reversal from :func:`terms.reversal_um`),
plus the Abbe terms of the model's tool offset along that joint. Nothing
cross-axis. Joints 0, 1, 2 = X, Y, Z (trivkins; ``--set joints=``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from abbe.exports.grids import choose_grid
from abbe.exports.target import Context, Export, Option, Unheld, fmt, not_held
from abbe.exports.terms import Item, has_reversal, own_error
from abbe.model.table import AXES

NAME = "linuxcnc-comp"
SUMMARY = "LinuxCNC COMP_FILE per joint (nominal forward reverse), type 0 or 1"
EMCMOT_COMP_SIZE = 256
DECIMALS = 7  # mm: 0.1 nm
OPTIONS = {
    "type": Option("int", 1, "COMP_FILE_TYPE: 0 = actual positions, 1 = trims", lo=0, hi=1),
    "points": Option("int", EMCMOT_COMP_SIZE,
                     "triplets per joint (LinuxCNC holds at most 256, EMCMOT_COMP_SIZE)",
                     lo=2, hi=EMCMOT_COMP_SIZE),
    "joints": Option("axes", {"X": "0", "Y": "1", "Z": "2"}, "joint number of each axis",
                     item="int", lo=0, hi=15),
}
SOURCES = ["LinuxCNC docs/src/config/ini-config.adoc ([JOINT_n] COMP_FILE, COMP_FILE_TYPE)",
           "LinuxCNC src/emc/motion/motion.h (EMCMOT_COMP_SIZE 256, emcmot_comp_entry_t float trims)",
           "LinuxCNC src/emc/motion/usrmotintf.cc (usrmotLoadComp: type 0 trim = nominal - column)",
           "LinuxCNC src/emc/motion/control.c (compute_screw_comp: interpolation, held ends, "
           "direction by vel_cmd sign)",
           "LinuxCNC configs/sim/screwcompX.dat (sample file)"]


def apply_comp(nominal: np.ndarray, trim: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """The trim LinuxCNC applies at joint positions ``pos`` (mm): float32 trims and
    slopes as command.c stores them, linear between nominals, held outside."""
    t32 = np.asarray(trim, dtype=np.float32)
    t = t32.astype(np.float64)
    slope = np.zeros(t.size)
    slope[:-1] = ((t[1:] - t[:-1]) / np.diff(nominal)).astype(np.float32).astype(np.float64)
    p = np.asarray(pos, dtype=np.float64)
    i = np.clip(np.searchsorted(nominal, p, side="right") - 1, 0, nominal.size - 1)
    dpos = p - nominal[i]
    out = t[i] + slope[i] * dpos
    return np.where(p < nominal[0], t[0], out)


def _cannot(item: Item) -> Unheld | None:
    if item.kind == "term" and item.part == "single":
        others = "".join(a for a in AXES if a != item.axis)
        return Unheld("a COMP_FILE corrects a joint from its own position only", others)
    if item.kind == "term":
        return Unheld("products with other axes' positions need more than one input")
    if item.kind == "squareness":
        return Unheld("squareness is cross-axis (one joint's error from another's position)")
    if item.kind == "thermal":
        return Unheld("no temperature input")
    return None  # backlash: the forward / reverse columns


def build(ctx: Context) -> Export:
    typ = int(ctx.options["type"])
    limit = int(ctx.options["points"])
    joints = ctx.options["joints"]
    files: dict[str, bytes] = {}
    tabs: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    tables: list[dict[str, Any]] = []
    ini = ["# abbe export linuxcnc-comp: add to the machine's INI (units: mm).",
           "# LinuxCNC ignores [JOINT_n] BACKLASH when COMP_FILE is set: the reversal is in",
           "# the forward/reverse columns."]
    for a in AXES:
        lo, hi = ctx.volume.travel_mm[a]

        def trims_um(q: np.ndarray, a: str = a) -> np.ndarray:
            return -np.column_stack([own_error(ctx.table, a, q, +1.0),
                                     own_error(ctx.table, a, q, -1.0)])

        g = choose_grid(lo, hi, trims_um, limit)
        nom_txt = [fmt(v, DECIMALS) for v in g.knots]
        nom = np.array([float(v) for v in nom_txt])
        tr = trims_um(nom) * 1e-3  # mm
        lines, back = [], np.empty((nom.size, 2))
        for i, n in enumerate(nom):
            if typ == 0:
                cols = [fmt(n - tr[i, 0], DECIMALS), fmt(n - tr[i, 1], DECIMALS)]
                back[i] = [n - float(cols[0]), n - float(cols[1])]
            else:
                cols = [fmt(tr[i, 0], DECIMALS), fmt(tr[i, 1], DECIMALS)]
                back[i] = [float(cols[0]), float(cols[1])]
            lines.append(f"{nom_txt[i]} {cols[0]} {cols[1]}")
        if np.any(np.diff(nom) <= 0):
            raise ValueError("nominals must increase")  # cannot happen: a round grid
        name = f"{a}.comp"
        files[name] = ("\n".join(lines) + "\n").encode()
        tabs[a] = (nom, back[:, 0], back[:, 1])
        tables.append({"name": f"{name} (joint {joints[a]}, axis {a})", **g.describe()})
        ini += ["", f"[JOINT_{joints[a]}]", f"COMP_FILE = {name}", f"COMP_FILE_TYPE = {typ}"]
    files["linuxcnc.ini"] = ("\n".join(ini) + "\n").encode()

    def correction(pos: np.ndarray, state: np.ndarray) -> np.ndarray:
        out = np.zeros_like(pos, dtype=np.float64)
        for j, a in enumerate(AXES):
            nom, fwd, rev = tabs[a]
            f = apply_comp(nom, fwd, pos[:, j])
            r = apply_comp(nom, rev, pos[:, j])
            s = state[:, j]
            out[:, j] = np.where(s > 0, f, np.where(s < 0, r, 0.5 * (f + r))) * 1e3
        return out

    rev = [a for a in AXES if has_reversal(ctx.table, a)]
    return Export(
        target=NAME, files=files, correction=correction,
        expressed=[f"{a} positioning along its own line (own term"
                   + (", reversal in the forward/reverse columns" if a in rev else "")
                   + ", tool-offset Abbe terms along the joint)" for a in AXES],
        not_held=not_held(ctx, _cannot), tables=tables, direction="sign",
        notes=[f"COMP_FILE_TYPE {typ}; joint positions in mm (machine units must be mm); "
               "the joint's machine coordinates must be the model's"],
        assumptions=["trivkins: joint n position = axis position (joints "
                     + ", ".join(f"{a}={joints[a]}" for a in AXES) + ")"],
        sources=SOURCES)
