"""``klipper-twist``: Klipper ``[axis_twist_compensation]`` z_compensations, from the model.

Source: Klipper klippy/extras/axis_twist_compensation.py. Calibration probes each of
``sample_count`` bed points b_i (nozzle points from calibrate_start_x to calibrate_end_x at
calibrate_y) twice: with the probe over b_i (the toolhead at b_i - probe offset) and with
the nozzle at b_i (a paper test); z_offset_i = probe's z - nozzle's z, and
``z_compensations[i] = mean(z_offset) - z_offset_i``. At run time every probe result
gets the compensation interpolated linearly at the toolhead's X (``test_x``) between
compensation_start_x and compensation_end_x.

What the model says of it: the probe is a second tool, offset from the nozzle by
(x_offset, y_offset) (Klipper's [probe] offsets); the carriage's angular errors move
it in Z differently from the nozzle (the Abbe terms of Eq. 3 with the tool offset plus
the probe's). With dZ the model's Z error of a tool (positive: the tool stands high),
the probe triggers at h(b) - dZ_probe(b - o) and the nozzle touches at
h(b) - dZ_nozzle(b), so z_offset = dZ_nozzle(b) - dZ_probe(b - o), which this target
writes in Klipper's form. It corrects the probe's readings (a bed mesh or Z tilt made
with the probe), not the motion: every motion error is named as not held, and the
table ``probe reading`` states what the probe's readings keep over the bed.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from abbe.errors.numbers import parse_number
from abbe.exports.target import Context, Export, Option, Unheld, not_held
from abbe.exports.terms import Item
from abbe.model.reference import spatial_error

NAME = "klipper-twist"
SUMMARY = "Klipper [axis_twist_compensation] z_compensations (probe vs nozzle along X)"
OPTIONS = {
    "probe_x_offset": Option("float", 0.0, "[probe] x_offset, mm", lo=-500.0, hi=500.0),
    "probe_y_offset": Option("float", 25.0, "[probe] y_offset, mm", lo=-500.0, hi=500.0),
    "sample_count": Option("int", 3, "points along X (Klipper's SAMPLE_COUNT)", lo=2, hi=100),
    "calibrate_y": Option("str", "middle", "the Y of the calibration line, mm, or 'middle' "
                          "(of the Y travel)", pattern=r"middle|[-+0-9.eE]{1,24}"),
    "z": Option("str", "reference", "the Z position at which the bed is probed, mm, or "
                "'reference' (the reference point's)", pattern=r"reference|[-+0-9.eE]{1,24}"),
}
SOURCES = ["Klipper klippy/extras/axis_twist_compensation.py (AXIS_TWIST_COMPENSATION_CALIBRATE, "
           "z_offset = probe z - nozzle z, z_compensations = mean - z_offset, interpolated at "
           "test_x)"]
DIGITS = 6  # mm, as Klipper's SAVE_CONFIG writes them


def _z_offsets(ctx: Context, x_mm: np.ndarray, y_mm: float, z_mm: float) -> np.ndarray:
    """z_offset (mm) at nozzle points (x, y, z): dZ_nozzle(b) - dZ_probe(b - o)."""
    t = ctx.table
    ox, oy = float(ctx.options["probe_x_offset"]), float(ctx.options["probe_y_offset"])
    probe = replace(t, tool_offset_mm=(t.tool_offset_mm[0] + ox, t.tool_offset_mm[1] + oy,
                                       t.tool_offset_mm[2]))
    b = np.column_stack([x_mm, np.full(x_mm.size, y_mm), np.full(x_mm.size, z_mm)])
    q = b - np.array([ox, oy, 0.0])
    return (spatial_error(t, b)[:, 2] - spatial_error(probe, q)[:, 2]) * 1e-3


def build(ctx: Context) -> Export:
    lo_x, hi_x = ctx.volume.travel_mm["X"]
    lo_y, hi_y = ctx.volume.travel_mm["Y"]
    y_opt, z_opt = ctx.options["calibrate_y"], ctx.options["z"]
    y = (lo_y + hi_y) / 2 if y_opt == "middle" else parse_number(
        y_opt, field="--set calibrate_y", lo=lo_y, hi=hi_y, unit="mm")
    lo_z, hi_z = ctx.volume.travel_mm["Z"]
    z = float(ctx.table.reference_mm[2]) if z_opt == "reference" else parse_number(
        z_opt, field="--set z", lo=lo_z, hi=hi_z, unit="mm")
    n = int(ctx.options["sample_count"])
    ox = float(ctx.options["probe_x_offset"])
    # nozzle points whose probe points lie in the travel too
    x0, x1 = max(lo_x, lo_x + ox), min(hi_x, hi_x + ox)
    xs = np.linspace(x0, x1, n)
    off = _z_offsets(ctx, xs, y, z)
    comp = np.round(off.mean() - off, DIGITS)
    vals = ", ".join(f"{v:.{DIGITS}f}" for v in comp)
    cfg = ["# abbe export klipper-twist: the probe's twist error along X from the model",
           f"# probe offset x {ox:g}, y {float(ctx.options['probe_y_offset']):g} mm; line y = {y:g}, "
           f"z = {z:g} mm", "[axis_twist_compensation]",
           f"calibrate_start_x: {x0:g}", f"calibrate_end_x: {x1:g}", f"calibrate_y: {y:g}",
           f"z_compensations: {vals}", f"compensation_start_x: {x0:g}",
           f"compensation_end_x: {x1:g}"]

    # what the probe's readings keep over the bed (the line's grid and a Y span)
    gx = np.linspace(x0, x1, 101)
    before, after = [], []
    for yy in np.linspace(lo_y, hi_y, 11):
        o = _z_offsets(ctx, gx, float(yy), z)
        o = o - o.mean()
        before.append(o)
        # Klipper adds comp(test_x); test_x = the toolhead's x when probing = b - ox
        after.append(o + np.interp(gx - ox, xs, comp - comp.mean()))
    before_um = np.abs(np.concatenate(before)) * 1e3
    after_um = np.abs(np.concatenate(after)) * 1e3
    on_line = np.abs(after[5]) * 1e3
    table = {"name": "probe reading (relative to its mean over the bed)",
             "before_max_um": round(float(before_um.max()), 4),
             "after_max_um": round(float(after_um.max()), 4),
             "on_the_line_after_max_um": round(float(on_line.max()), 4),
             "limit_is_cause": False}

    def correction(pos: np.ndarray, state: np.ndarray) -> np.ndarray:
        return np.zeros_like(np.asarray(pos, dtype=float))

    def cannot(item: Item) -> Unheld | None:
        return Unheld("axis twist compensation corrects the probe's readings, not the motion")

    return Export(
        target=NAME, files={"axis_twist_compensation.cfg": ("\n".join(cfg) + "\n").encode()},
        correction=correction,
        expressed=[f"probe vs nozzle along X at y = {y:g} mm: z_compensations over "
                   f"{n} points, {float(np.ptp(comp)) * 1e3:.3f} um range"],
        not_held=not_held(ctx, cannot), tables=[table], direction="none",
        notes=[f"the probe's readings over the bed keep {table['before_max_um']:.3f} um -> "
               f"{table['after_max_um']:.3f} um (max |error| about their mean; on the "
               f"calibration line {table['on_the_line_after_max_um']:.3f} um): what varies with "
               "y and between the points stays",
               "motion is not corrected by this target: the residual over the volume is the "
               "model's error"],
        assumptions=["the probe sits at the nozzle's height (its z offset is the trigger "
                     "point's, not a lever)", "Klipper's toolhead coordinates are the model's"],
        sources=SOURCES)
