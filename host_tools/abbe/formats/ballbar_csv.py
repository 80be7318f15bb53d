"""Ballbar CSV reader (``direction,angle_deg,radial_um,time_s``) and trace checks.

``radial_um`` = measured minus nominal length; a trace holds the CCW run, then
the CW run; samples with an angle outside [0, 360) are the feed-in / feed-out
arcs. :func:`read_ballbar_csv` validates everything it reads and raises
AbbeInputError naming file, line and column (docs/formats.md, "Ballbar CSV").
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from abbe.errors import AbbeInputError, parse_finite
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
    machine temperature (deg C) of each sample, or None.
    """

    direction: np.ndarray
    angle_deg: np.ndarray
    radial_um: np.ndarray
    time_s: np.ndarray
    file: str | None = None
    line_no: np.ndarray | None = None
    temp_c: np.ndarray | None = None

    def data_mask(self, direction: str | None = None) -> np.ndarray:
        """Samples inside [0, 360) (not feed arcs), optionally of one direction."""
        m = (self.angle_deg >= 0.0) & (self.angle_deg < 360.0)
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


def read_ballbar_csv(path: str | Path) -> BallbarTrace:
    """Read and validate a ballbar CSV (``direction,angle_deg,radial_um,time_s``).

    Raises AbbeInputError naming file, line and column for: a missing/unknown
    column or a column in other units (``radial_mm``, ``angle_rad`` ...), a bad
    cell, an unknown direction, CW rows before CCW rows or interleaved, a missing
    direction, angles not monotonic in the direction of travel, time going
    backwards, a radial value too large to be um, a gap in the data arc or a
    data arc that does not cover [0, 360).
    """
    path = Path(path)
    f = str(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise AbbeInputError(f"cannot read ballbar file: {exc.strerror}", file=f) from None
    except UnicodeDecodeError:
        raise AbbeInputError("not UTF-8 text", file=f) from None
    rows = [(no, r) for no, r in enumerate(csv.reader(io.StringIO(text)), start=1)
            if r and not (len(r) == 1 and not r[0].strip()) and not r[0].lstrip().startswith("#")]
    if not rows:
        raise AbbeInputError("empty file: expected header " + ",".join(COLUMNS), file=f, line=1)
    hno, header = rows[0]
    header = [h.strip() for h in header]
    for h in header:
        if h not in COLUMNS and h not in OPTIONAL_COLUMNS:
            hint = _unit_hint(h)
            if hint:
                raise AbbeInputError(f"column {h!r} is in other units: expected {hint!r} "
                                     "(angles deg, deviations um, time s)", file=f, line=hno, field=h)
            raise AbbeInputError(f"unknown column; expected {','.join(COLUMNS)}", file=f,
                                 line=hno, field=h)
    for c in COLUMNS:
        if c not in header:
            raise AbbeInputError(f"missing column {c!r}", file=f, line=hno, field=c)
        if header.count(c) > 1:
            raise AbbeInputError(f"duplicate column {c!r}", file=f, line=hno, field=c)
    for c in OPTIONAL_COLUMNS:
        if header.count(c) > 1:
            raise AbbeInputError(f"duplicate column {c!r}", file=f, line=hno, field=c)
    opt = tuple(c for c in OPTIONAL_COLUMNS if c in header)
    idx = {c: header.index(c) for c in COLUMNS + opt}
    dirs: list[str] = []
    vals: dict[str, list[float]] = {c: [] for c in COLUMNS[1:] + opt}
    nos: list[int] = []
    for no, r in rows[1:]:
        if len(r) != len(header):
            raise AbbeInputError(f"expected {len(header)} cells, got {len(r)}", file=f, line=no)
        d = r[idx["direction"]].strip().lower()
        if d not in DIRECTIONS:
            raise AbbeInputError(f"expected 'ccw' or 'cw', got {r[idx['direction']]!r}", file=f,
                                 line=no, field="direction")
        for c in COLUMNS[1:] + opt:
            vals[c].append(parse_finite(r[idx[c]].strip(), file=f, line=no, field=c))
        dirs.append(d)
        nos.append(no)
    tr = BallbarTrace(direction=np.array(dirs), angle_deg=np.array(vals["angle_deg"]),
                      radial_um=np.array(vals["radial_um"]), time_s=np.array(vals["time_s"]),
                      file=f, line_no=np.array(nos, dtype=np.int64),
                      temp_c=np.array(vals["temp_c"]) if "temp_c" in opt else None)
    _validate_trace(tr)
    return tr


def _validate_trace(tr: BallbarTrace) -> None:
    f = tr.file
    lines = tr.line_no if tr.line_no is not None else np.arange(1, tr.angle_deg.size + 1) + 1
    n = tr.direction.size
    if n == 0:
        raise AbbeInputError("no samples", file=f, line=1)
    # Order: all CCW, then all CW.
    is_cw = tr.direction == "cw"
    if not is_cw.any():
        raise AbbeInputError("no 'cw' samples: a ballbar test has a CCW run then a CW run",
                             file=f, line=int(lines[-1]), field="direction")
    if is_cw.all():
        raise AbbeInputError("no 'ccw' samples: a ballbar test has a CCW run then a CW run",
                             file=f, line=int(lines[0]), field="direction")
    first_cw = int(np.argmax(is_cw))
    back = np.nonzero(~is_cw[first_cw:])[0]
    if is_cw[0] or back.size:
        k = 0 if is_cw[0] else first_cw + int(back[0])
        raise AbbeInputError("the CCW run must come first, then the CW run (no interleaving)",
                             file=f, line=int(lines[k]), field="direction")
    bad = np.nonzero(np.abs(tr.radial_um) > MAX_RADIAL_UM)[0]
    if bad.size:
        k = int(bad[0])
        raise AbbeInputError(f"radial deviation {tr.radial_um[k]} is implausible in um "
                             f"(> {MAX_RADIAL_UM:g}): wrong units or wrong nominal radius",
                             file=f, line=int(lines[k]), field="radial_um")
    dt = np.diff(tr.time_s)
    bad = np.nonzero(dt <= 0)[0]
    if bad.size:
        k = int(bad[0]) + 1
        raise AbbeInputError("time_s must increase from sample to sample", file=f,
                             line=int(lines[k]), field="time_s")
    for d, sgn in (("ccw", 1.0), ("cw", -1.0)):
        sel = np.nonzero(tr.direction == d)[0]
        a = tr.angle_deg[sel]
        if a.size < 8:
            raise AbbeInputError(f"only {a.size} '{d}' samples", file=f,
                                 line=int(lines[sel[-1]]), field="angle_deg")
        step = np.diff(a) * sgn
        bad = np.nonzero(step <= 0)[0]
        if bad.size:
            k = int(sel[bad[0] + 1])
            raise AbbeInputError(f"angle_deg must {'increase' if sgn > 0 else 'decrease'} "
                                 f"along the {d.upper()} run (got {tr.angle_deg[k - 1]:g} then "
                                 f"{tr.angle_deg[k]:g})", file=f, line=int(lines[k]),
                                 field="angle_deg")
        if a.min() < -360.0 or a.max() >= 720.0:
            k = int(sel[np.argmax((a < -360.0) | (a >= 720.0))])
            raise AbbeInputError("angle out of range [-360, 720) deg (radians?)", file=f,
                                 line=int(lines[k]), field="angle_deg")
        dm = (a >= 0.0) & (a < 360.0)
        if dm.sum() < 8:
            raise AbbeInputError(f"the '{d}' run has no data arc in [0, 360) deg", file=f,
                                 line=int(lines[sel[-1]]), field="angle_deg")
        ad = a[dm]
        idx = sel[dm]
        med = float(np.median(np.abs(np.diff(ad))))
        tol = max(GAP_FACTOR * med, MIN_GAP_DEG)
        gaps = np.nonzero(np.abs(np.diff(ad)) > tol)[0]
        if gaps.size:
            k = int(idx[gaps[0] + 1])
            raise AbbeInputError(f"gap in the '{d}' data arc: {ad[gaps[0]]:g} -> "
                                 f"{ad[gaps[0] + 1]:g} deg (samples every {med:g} deg)",
                                 file=f, line=int(lines[k]), field="angle_deg")
        lo, hi = float(ad.min()), float(ad.max())
        if lo > tol or 360.0 - hi > tol:
            k = int(idx[0] if lo > tol else idx[-1])
            raise AbbeInputError(f"the '{d}' data arc covers [{lo:g}, {hi:g}] deg, not the "
                                 "full circle [0, 360)", file=f, line=int(lines[k]),
                                 field="angle_deg")


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
