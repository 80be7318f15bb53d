"""Ballbar CSV reader (``direction,angle_deg,radial_um,time_s``) and trace checks.

``radial_um`` = measured minus nominal length; a trace holds the CCW run, then
the CW run; samples with an angle outside [0, 360) are the feed-in / feed-out
arcs. :func:`read_ballbar_csv` validates everything it reads and raises
AbbeInputError naming file, line and column (docs/formats.md, "Ballbar CSV").
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from abbe.errors import AbbeInputError
from abbe.formats.columns import BALLBAR_ROLES, Columns, plan_columns
from abbe.formats.delimited import DEFAULT_DIALECT, Column, Header, read_columns
from abbe.formats.limits import BALLBAR_CSV_MAX_BYTES, BALLBAR_CSV_MAX_ROWS
from abbe.formats.text import read_text
from abbe.model.geometry import DIRECTIONS

COLUMNS: tuple[str, ...] = ("direction", "angle_deg", "radial_um", "time_s")
#: Optional columns: the machine temperature (deg C) logged with each sample.
OPTIONAL_COLUMNS: tuple[str, ...] = ("temp_c",)

#: A radial deviation larger than this (um) is not a ballbar reading in um.
MAX_RADIAL_UM = 2000.0

#: A step between data samples larger than this many median steps (and > 2 deg) is a gap.
GAP_FACTOR = 4.0

MIN_GAP_DEG = 2.0


@dataclass
class BallbarTrace:
    """A ballbar trace: per sample direction ('ccw'/'cw'), angle_deg, radial_um, time_s.

    line_no: source line of each sample (None for simulated traces); temp_c: the
    machine temperature (deg C) of each sample, or None. data_from_deg: the data arc is
    [data_from_deg, data_from_deg + 360) deg of the commanded angle (0 for abbe's CSV and
    simulations; a Renishaw file's START_ANGLE, so abbe evaluates the samples Renishaw's
    software does); the rest are feed arcs.
    """

    direction: np.ndarray
    angle_deg: np.ndarray
    radial_um: np.ndarray
    time_s: np.ndarray
    file: str | None = None
    line_no: np.ndarray | None = None
    temp_c: np.ndarray | None = None
    data_from_deg: float = 0.0

    def data_mask(self, direction: str | None = None) -> np.ndarray:
        """Samples of the data arc (not feed arcs), optionally of one direction."""
        a0 = self.data_from_deg
        m = (self.angle_deg >= a0) & (self.angle_deg < a0 + 360.0)
        if direction is not None:
            m &= self.direction == direction
        return m

    def to_csv(self) -> str:
        """CSV text: header ``direction,angle_deg,radial_um,time_s`` (``,temp_c`` with a
        temperature)."""
        out = io.StringIO()
        out.write(",".join(COLUMNS + (OPTIONAL_COLUMNS if self.temp_c is not None else ())) + "\n")
        for i, (d, a, r, t) in enumerate(zip(self.direction, self.angle_deg, self.radial_um,
                                             self.time_s)):
            tail = "" if self.temp_c is None else f",{self.temp_c[i]:.3f}"
            out.write(f"{d},{a:.3f},{r:.4f},{t:.3f}{tail}\n")
        return out.getvalue()


def _unit_hint(name: str) -> str | None:
    stem = name.rsplit("_", 1)[0] if "_" in name else name
    for col in COLUMNS:
        if col != "direction" and col.rsplit("_", 1)[0] == stem and name != col:
            return col
    return None


def read_ballbar_csv(path: str | Path, columns: Columns | None = None) -> BallbarTrace:
    """Read and validate a ballbar CSV (``direction,angle_deg,radial_um,time_s``, or as
    ``columns`` declares: machine file ``[ballbar.N.columns]``).

    Raises AbbeInputError naming file, line and column for: a missing/unknown
    column or a column in other units (``radial_mm``, ``angle_rad`` ...), a bad
    cell, an unknown direction, CW rows before CCW rows or interleaved, a missing
    direction, angles not monotonic in the direction of travel, time going
    backwards, a radial value too large to be um, a gap in the data arc or a
    data arc that does not cover [0, 360). Wrapped angles (an export writing
    359.5 then 0) are unwrapped first (:func:`unwrap_angles`).
    """
    path = Path(path)
    f = str(path)
    dialect = columns.dialect if columns is not None else DEFAULT_DIALECT
    tf = read_text(path, what="ballbar CSV", max_bytes=BALLBAR_CSV_MAX_BYTES,
                   encoding=dialect.encoding)

    def plan(header: Header) -> dict[str, Column]:
        if columns is None:
            for h in header.names:
                if h not in COLUMNS:
                    hint = _unit_hint(h)
                    if hint:
                        raise AbbeInputError(f"column {h!r} is in other units: expected {hint!r} "
                                             "(angles deg, deviations um, time s)", file=f,
                                             line=header.line, field=h)
        return plan_columns(header, BALLBAR_ROLES, columns, file=f,
                            need=tuple(r for r, v in BALLBAR_ROLES.items() if v.required),
                            strict_names=True, default_dirs=DIRECTIONS)

    header, vals, lines = read_columns(tf, dialect, what="ballbar CSV",
                                       max_rows=BALLBAR_CSV_MAX_ROWS, plan=plan)
    dirs = np.array(DIRECTIONS)[vals["direction"]] if lines.size else np.array([], dtype="<U3")
    angle = unwrap_angles(vals["angle"], vals["direction"])
    names = {r: (columns.fields[r].column if columns is not None and r in columns.fields
                 else BALLBAR_ROLES[r].default) for r in BALLBAR_ROLES}
    tr = BallbarTrace(direction=dirs, angle_deg=angle, radial_um=vals["radial"],
                      time_s=vals["time"], file=f, line_no=lines, temp_c=vals.get("temp"))
    validate_trace(tr, names)
    return tr


def unwrap_angles(angle_deg: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Undo the wrapping of instrument exports, per run (direction 0 = CCW, 1 = CW).

    Along a run a step *against* the direction of travel of more than 180 deg is
    the angle passing 360/0 (``359.5`` then ``0`` in a CCW run, ``0`` then ``359.5``
    in a CW run): the rest of the run moves by 360 deg. Then the whole run moves
    by the multiple of 360 deg that puts most of its samples into [0, 360) (the
    data arc; the rest are feed arcs). A trace already in abbe's convention
    (e.g. -45 .. 405 deg) is returned unchanged.
    """
    a = np.asarray(angle_deg, dtype=np.float64).copy()
    d = np.asarray(direction)
    for code, sgn in ((0, 1.0), (1, -1.0)):
        sel = np.flatnonzero(d == code)
        if sel.size < 2:
            continue
        x = a[sel]
        step = np.diff(x) * sgn
        wraps = step < -180.0
        if wraps.any():
            x = x + sgn * 360.0 * np.concatenate([[0.0], np.cumsum(wraps)])
        counts = {k: int(np.count_nonzero((x + 360.0 * k >= 0.0) & (x + 360.0 * k < 360.0)))
                  for k in range(-3, 4)}
        best = max(counts.values())
        k = min((k for k, c in counts.items() if c == best), key=abs)
        a[sel] = x + 360.0 * k
    return a


def validate_trace(tr: BallbarTrace, names: dict[str, str] | None = None) -> None:
    """Every check of a ballbar trace (docs/formats.md, "Ballbar CSV"), whatever file it came
    from; ``names``: the file's names of the direction / angle / radial / time fields."""
    f = tr.file
    col = {"direction": "direction", "angle": "angle_deg", "radial": "radial_um", "time": "time_s"}
    col.update(names or {})
    lines = tr.line_no if tr.line_no is not None else np.arange(1, tr.angle_deg.size + 1) + 1
    n = tr.direction.size
    if n == 0:
        raise AbbeInputError("no samples", file=f, line=1)
    # Order: all CCW, then all CW.
    is_cw = tr.direction == "cw"
    if not is_cw.any():
        raise AbbeInputError("no 'cw' samples: a ballbar test has a CCW run then a CW run",
                             file=f, line=int(lines[-1]), field=col["direction"])
    if is_cw.all():
        raise AbbeInputError("no 'ccw' samples: a ballbar test has a CCW run then a CW run",
                             file=f, line=int(lines[0]), field=col["direction"])
    first_cw = int(np.argmax(is_cw))
    back = np.nonzero(~is_cw[first_cw:])[0]
    if is_cw[0] or back.size:
        k = 0 if is_cw[0] else first_cw + int(back[0])
        raise AbbeInputError("the CCW run must come first, then the CW run (no interleaving)",
                             file=f, line=int(lines[k]), field=col["direction"])
    bad = np.nonzero(np.abs(tr.radial_um) > MAX_RADIAL_UM)[0]
    if bad.size:
        k = int(bad[0])
        raise AbbeInputError(f"radial deviation {tr.radial_um[k]} is implausible in um "
                             f"(> {MAX_RADIAL_UM:g}): wrong units or wrong nominal radius",
                             file=f, line=int(lines[k]), field=col["radial"])
    dt = np.diff(tr.time_s)
    bad = np.nonzero(dt <= 0)[0]
    if bad.size:
        k = int(bad[0]) + 1
        raise AbbeInputError("time_s must increase from sample to sample", file=f,
                             line=int(lines[k]), field=col["time"])
    for d, sgn in (("ccw", 1.0), ("cw", -1.0)):
        sel = np.nonzero(tr.direction == d)[0]
        a = tr.angle_deg[sel]
        if a.size < 8:
            raise AbbeInputError(f"only {a.size} '{d}' samples", file=f,
                                 line=int(lines[sel[-1]]), field=col["angle"])
        step = np.diff(a) * sgn
        bad = np.nonzero(step <= 0)[0]
        if bad.size:
            k = int(sel[bad[0] + 1])
            raise AbbeInputError(f"angle_deg must {'increase' if sgn > 0 else 'decrease'} "
                                 f"along the {d.upper()} run (got {tr.angle_deg[k - 1]:g} then "
                                 f"{tr.angle_deg[k]:g})", file=f, line=int(lines[k]),
                                 field=col["angle"])
        if a.min() < -360.0 or a.max() >= 720.0:
            k = int(sel[np.argmax((a < -360.0) | (a >= 720.0))])
            raise AbbeInputError("angle out of range [-360, 720) deg (radians?)", file=f,
                                 line=int(lines[k]), field=col["angle"])
        a0 = tr.data_from_deg
        dm = (a >= a0) & (a < a0 + 360.0)
        if dm.sum() < 8:
            raise AbbeInputError(f"the '{d}' run has no data arc in [{a0:g}, {a0 + 360:g}) deg",
                                 file=f, line=int(lines[sel[-1]]), field=col["angle"])
        ad = a[dm]
        idx = sel[dm]
        med = float(np.median(np.abs(np.diff(ad))))
        tol = max(GAP_FACTOR * med, MIN_GAP_DEG)
        gaps = np.nonzero(np.abs(np.diff(ad)) > tol)[0]
        if gaps.size:
            k = int(idx[gaps[0] + 1])
            raise AbbeInputError(f"gap in the '{d}' data arc: {ad[gaps[0]]:g} -> "
                                 f"{ad[gaps[0] + 1]:g} deg (samples every {med:g} deg)",
                                 file=f, line=int(lines[k]), field=col["angle"])
        lo, hi = float(ad.min()), float(ad.max())
        if lo - a0 > tol or a0 + 360.0 - hi > tol:
            k = int(idx[0] if lo - a0 > tol else idx[-1])
            raise AbbeInputError(f"the '{d}' data arc covers [{lo:g}, {hi:g}] deg, not the "
                                 f"full circle [{a0:g}, {a0 + 360:g})", file=f,
                                 line=int(lines[k]), field=col["angle"])


def check_trace_timing(trace: BallbarTrace, test: Any, machine_file: str | None = None) -> None:
    """The data arc must take about 2 pi R / F: otherwise radius or feed is inconsistent."""
    expect = 2.0 * math.pi * test.radius_mm / (test.feed_mm_min / 60.0)
    for d in DIRECTIONS:
        m = trace.data_mask(d)
        a = trace.angle_deg[m]
        t = trace.time_s[m]
        span = abs(a[-1] - a[0])
        if span <= 0:
            continue
        took = abs(t[-1] - t[0]) * 360.0 / span
        if not 0.8 <= took / expect <= 1.25:
            k = np.nonzero(m)[0][-1]
            line = int(trace.line_no[k]) if trace.line_no is not None else None
            raise AbbeInputError(
                f"the {d.upper()} run takes {took:.1f} s per revolution but R = "
                f"{test.radius_mm:g} mm at F = {test.feed_mm_min:g} mm/min needs {expect:.1f} s: "
                f"radius_mm or feed_mm_min of the test in {machine_file or 'the machine file'} "
                "does not match this trace", file=trace.file, line=line, field="time_s")
