"""Ballbar (ISO 230-4 circular test): traces, evaluation, prediction from a model, plot.

Conventions (notes.md §4, docs/formats.md "Ballbar and simulation"):

* planes follow G17/G18/G19 and the right-hand rule; the angle theta runs
  XY: from +X toward +Y, ZX: from +Z toward +X, YZ: from +Y toward +Z;
  CCW = increasing theta. The commanded point at theta is
  ``centre + R (cos theta e_a + sin theta e_b)`` with (a, b) = (X, Y), (Z, X), (Y, Z);
* ``radial_um`` = measured minus nominal length; for a small tool-to-workpiece
  error E (um) at the commanded point it is ``u_r(theta) . E``;
* a trace holds the CCW run, then the CW run; samples with an angle outside
  [0, 360) are the feed-in / feed-out arcs and are not evaluated.

Evaluation: a least-squares circle (geometric fit, scipy) per direction and
for both directions together; centre offset (um, in plane axes a, b), radius
deviation (um), circular deviation G = max - min of the radial residuals
(per direction and bidirectional), circular hysteresis H = max |CCW - CW|
residual at the same angle.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from abbe.errors import AbbeInputError, parse_finite

PLANES: tuple[str, ...] = ("XY", "YZ", "ZX")
#: plane -> indices (a, b) of the axes spanning it: theta from +a toward +b.
PLANE_AXES: dict[str, tuple[int, int]] = {"XY": (0, 1), "ZX": (2, 0), "YZ": (1, 2)}
DIRECTIONS: tuple[str, str] = ("ccw", "cw")
COLUMNS: tuple[str, ...] = ("direction", "angle_deg", "radial_um", "time_s")
#: A radial deviation larger than this (um) is not a ballbar reading in um.
MAX_RADIAL_UM = 2000.0
#: A step between data samples larger than this many median steps (and > 2 deg) is a gap.
GAP_FACTOR = 4.0
MIN_GAP_DEG = 2.0


# --------------------------------------------------------------------------- geometry


@dataclass(frozen=True)
class CircleTest:
    """One circular test: geometry plus the simulation settings.

    plane: "XY", "YZ" or "ZX"; center_mm (3,) machine coordinates; radius_mm;
    feed_mm_min. Simulation only: sample_deg (angular step of the recorded
    samples), feed_arc_deg (feed-in and feed-out arcs), pause_s (between the CCW
    and the CW run), setup_offset_um (3,) (centre ball off the commanded centre),
    file (relative CSV path).
    """

    name: str
    plane: str
    center_mm: tuple[float, float, float]
    radius_mm: float
    feed_mm_min: float
    sample_deg: float = 0.5
    feed_arc_deg: float = 45.0
    pause_s: float = 2.0
    setup_offset_um: tuple[float, float, float] = (0.0, 0.0, 0.0)
    file: str = ""

    @property
    def axes(self) -> tuple[int, int]:
        return PLANE_AXES[self.plane]

    @property
    def omega_deg_s(self) -> float:
        """Angular speed at the programmed feed, deg/s."""
        return math.degrees(self.feed_mm_min / 60.0 / self.radius_mm)


def from_machine(bt: Any) -> CircleTest:
    """CircleTest from an ``abbe.formats.machine.BallbarTest`` (or anything with the same fields)."""
    return CircleTest(name=bt.name, plane=bt.plane, center_mm=tuple(bt.center_mm),
                      radius_mm=float(bt.radius_mm), feed_mm_min=float(bt.feed_mm_min),
                      file=str(bt.file))


def radial_units(plane: str, angle_deg: np.ndarray) -> np.ndarray:
    """Unit vectors u_r (N, 3) from the centre to the commanded point."""
    th = np.radians(np.asarray(angle_deg, dtype=np.float64).reshape(-1))
    a, b = PLANE_AXES[plane]
    u = np.zeros((th.size, 3))
    u[:, a] = np.cos(th)
    u[:, b] = np.sin(th)
    return u


def tangent_units(plane: str, angle_deg: np.ndarray) -> np.ndarray:
    """Unit vectors (N, 3) along increasing theta (the CCW direction of travel)."""
    th = np.radians(np.asarray(angle_deg, dtype=np.float64).reshape(-1))
    a, b = PLANE_AXES[plane]
    u = np.zeros((th.size, 3))
    u[:, a] = -np.sin(th)
    u[:, b] = np.cos(th)
    return u


def circle_points(test: Any, angle_deg: np.ndarray) -> np.ndarray:
    """Commanded machine positions (N, 3) mm at the angles (deg)."""
    c = np.asarray(test.center_mm, dtype=np.float64)
    return c + float(test.radius_mm) * radial_units(test.plane, angle_deg)


def travel_direction(test: Any, angle_deg: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Per-axis direction of motion (N, 3) in {-1, 0, +1} along the commanded circle."""
    d = np.where(np.asarray(direction) == "cw", -1.0, 1.0)
    v = tangent_units(test.plane, angle_deg) * d[:, None]
    v[np.abs(v) < 1e-12] = 0.0
    return np.sign(v)


# --------------------------------------------------------------------------- traces


@dataclass
class BallbarTrace:
    """A ballbar trace: per sample direction ('ccw'/'cw'), angle_deg, radial_um, time_s.

    line_no: source line of each sample (None for simulated traces).
    """

    direction: np.ndarray
    angle_deg: np.ndarray
    radial_um: np.ndarray
    time_s: np.ndarray
    file: str | None = None
    line_no: np.ndarray | None = None

    def data_mask(self, direction: str | None = None) -> np.ndarray:
        """Samples inside [0, 360) (not feed arcs), optionally of one direction."""
        m = (self.angle_deg >= 0.0) & (self.angle_deg < 360.0)
        if direction is not None:
            m &= self.direction == direction
        return m

    def to_csv(self) -> str:
        """CSV text: header ``direction,angle_deg,radial_um,time_s``."""
        out = io.StringIO()
        out.write(",".join(COLUMNS) + "\n")
        for d, a, r, t in zip(self.direction, self.angle_deg, self.radial_um, self.time_s):
            out.write(f"{d},{a:.3f},{r:.4f},{t:.3f}\n")
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
        if h not in COLUMNS:
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
    idx = {c: header.index(c) for c in COLUMNS}
    dirs: list[str] = []
    vals = {c: [] for c in COLUMNS[1:]}
    nos: list[int] = []
    for no, r in rows[1:]:
        if len(r) != len(header):
            raise AbbeInputError(f"expected {len(header)} cells, got {len(r)}", file=f, line=no)
        d = r[idx["direction"]].strip().lower()
        if d not in DIRECTIONS:
            raise AbbeInputError(f"expected 'ccw' or 'cw', got {r[idx['direction']]!r}", file=f,
                                 line=no, field="direction")
        for c in COLUMNS[1:]:
            vals[c].append(parse_finite(r[idx[c]].strip(), file=f, line=no, field=c))
        dirs.append(d)
        nos.append(no)
    tr = BallbarTrace(direction=np.array(dirs), angle_deg=np.array(vals["angle_deg"]),
                      radial_um=np.array(vals["radial_um"]), time_s=np.array(vals["time_s"]),
                      file=f, line_no=np.array(nos, dtype=np.int64))
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


# --------------------------------------------------------------------------- evaluation


@dataclass
class CircleFit:
    """Least-squares circle: centre offset (um, plane axes a, b), radius deviation (um),
    residuals (um) of the fitted samples, circular deviation G = max - min (um)."""

    center_um: tuple[float, float]
    radius_dev_um: float
    residual_um: np.ndarray
    G_um: float


def fit_circle(angle_deg: np.ndarray, radial_um: np.ndarray, radius_mm: float) -> CircleFit:
    """Least-squares circle of a ballbar trace.

    Model: the machine's path is the commanded circle shifted by the centre
    offset c (um, plane axes a, b: the path centre relative to the centre ball) and
    the bar reads ``|c + R u(theta)| - R + rho``, rho the radius deviation (um).
    Minimises sum (dR_i - model_i)^2 over (c, rho) with scipy least_squares, started
    from the linearised solution ``dR ~ c . u + rho`` (to which it reduces for small
    c). Exact for a pure set-up offset of any size.
    """
    th = np.radians(np.asarray(angle_deg, dtype=np.float64))
    dr = np.asarray(radial_um, dtype=np.float64)
    A = np.stack([np.cos(th), np.sin(th), np.ones_like(th)], axis=1)
    lin, *_ = np.linalg.lstsq(A, dr, rcond=None)
    R_um = radius_mm * 1000.0
    ux, uy = np.cos(th), np.sin(th)

    def res(p: np.ndarray) -> np.ndarray:
        return dr - (np.hypot(p[0] + R_um * ux, p[1] + R_um * uy) - R_um + p[2])

    sol = least_squares(res, lin, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    r = res(sol.x)
    return CircleFit(center_um=(float(sol.x[0]), float(sol.x[1])), radius_dev_um=float(sol.x[2]),
                     residual_um=r, G_um=float(r.max() - r.min()))


@dataclass
class BallbarResult:
    """ISO 230-4 evaluation of one trace (um; centre in the plane axes a, b)."""

    name: str
    plane: str
    radius_mm: float
    feed_mm_min: float
    per_direction: dict[str, CircleFit]
    both: CircleFit
    H_um: float
    n_samples: dict[str, int]
    angles: dict[str, np.ndarray] = field(default_factory=dict)
    residual_both: dict[str, np.ndarray] = field(default_factory=dict)

    def axis_names(self) -> tuple[str, str]:
        a, b = PLANE_AXES[self.plane]
        return ("XYZ"[a], "XYZ"[b])

    def to_json(self) -> dict[str, Any]:
        """JSON-ready summary (um)."""
        na, nb = self.axis_names()

        def fit(cf: CircleFit) -> dict[str, Any]:
            return {f"center_{na.lower()}_um": round(cf.center_um[0], 4),
                    f"center_{nb.lower()}_um": round(cf.center_um[1], 4),
                    "radius_dev_um": round(cf.radius_dev_um, 4), "G_um": round(cf.G_um, 4)}

        return {"name": self.name, "plane": self.plane, "radius_mm": self.radius_mm,
                "feed_mm_min": self.feed_mm_min,
                "ccw": fit(self.per_direction["ccw"]), "cw": fit(self.per_direction["cw"]),
                "bidirectional": fit(self.both), "H_um": round(self.H_um, 4),
                "samples": self.n_samples}

    def format_text(self) -> str:
        na, nb = self.axis_names()
        lines = [f"ballbar {self.name}: plane {self.plane}, R = {self.radius_mm:g} mm, "
                 f"F = {self.feed_mm_min:g} mm/min (ISO 230-4, LSC; feed arcs excluded)"]
        for key, cf in (("CCW", self.per_direction["ccw"]), ("CW", self.per_direction["cw"]),
                        ("both", self.both)):
            lines.append(f"  {key:5s} G = {cf.G_um:8.3f} um   centre {na}/{nb} = "
                         f"{cf.center_um[0]:8.3f} / {cf.center_um[1]:8.3f} um   "
                         f"radius dev = {cf.radius_dev_um:8.3f} um")
        lines.append(f"  circular hysteresis H = {self.H_um:.3f} um")
        return "\n".join(lines)


def _periodic_interp(x_new: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    order = np.argsort(x)
    return np.interp(x_new, x[order], y[order], period=360.0)


def evaluate_ballbar(trace: BallbarTrace, test: Any) -> BallbarResult:
    """ISO 230-4 evaluation of a trace of ``test`` (needs name, plane, radius_mm, feed_mm_min).

    Only data samples (0 <= angle < 360) are used. Per direction: its own LS
    circle, G. Bidirectional: one LS circle through both runs, G over both. H:
    max |residual_ccw(theta) - residual_cw(theta)| about the common circle, the
    CW residuals interpolated (periodically) at the CCW angles.
    """
    per: dict[str, CircleFit] = {}
    n: dict[str, int] = {}
    for d in DIRECTIONS:
        m = trace.data_mask(d)
        per[d] = fit_circle(trace.angle_deg[m], trace.radial_um[m], test.radius_mm)
        n[d] = int(m.sum())
    m = trace.data_mask()
    both = fit_circle(trace.angle_deg[m], trace.radial_um[m], test.radius_mm)
    dirs = trace.direction[m]
    ang = trace.angle_deg[m]
    res = {d: both.residual_um[dirs == d] for d in DIRECTIONS}
    angs = {d: ang[dirs == d] for d in DIRECTIONS}
    cw_at_ccw = _periodic_interp(angs["ccw"], angs["cw"], res["cw"])
    H = float(np.max(np.abs(res["ccw"] - cw_at_ccw)))
    return BallbarResult(name=test.name, plane=test.plane, radius_mm=float(test.radius_mm),
                         feed_mm_min=float(test.feed_mm_min), per_direction=per, both=both,
                         H_um=H, n_samples=n, angles=angs, residual_both=res)


def check_test_in_travel(test: Any, travel_mm: dict[str, tuple[float, float]],
                         file: str | None = None, line: int | None = None) -> None:
    """The circle (and its centre) must lie inside the machine travel (mm)."""
    a, b = PLANE_AXES[test.plane]
    for k, ax in enumerate("XYZ"):
        if ax not in travel_mm:
            continue
        lo, hi = travel_mm[ax]
        c = float(test.center_mm[k])
        r = float(test.radius_mm) if k in (a, b) else 0.0
        if c - r < lo - 1e-6 or c + r > hi + 1e-6:
            fld = "radius_mm" if lo <= c <= hi else "center_mm"
            raise AbbeInputError(
                f"circle {ax.lower()} = {c:g} +/- {r:g} mm leaves the travel [{lo:g}, {hi:g}] mm "
                f"of axis {ax}", file=file, line=line, field=f"ballbar.{test.name}.{fld}")


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


# --------------------------------------------------------------------------- prediction


def model_error_um(model: Any, pos_mm: np.ndarray, dir_state: np.ndarray | None = None,
                   temp_c: np.ndarray | None = None) -> np.ndarray:
    """Spatial error (N, 3) um of a model at positions (N, 3) mm.

    ``model``: an ``abbe.formats.blob.Table`` (float64 reference, ``abbe.model.reference``), an
    ``abbe.model.clib.CModel`` (C library ``error_f32``), or a callable
    ``f(pos_mm, dir_state, temp_c) -> (N, 3) um``.
    """
    from abbe.formats.blob import Table

    if isinstance(model, Table):
        from abbe.model.reference import spatial_error
        return spatial_error(model, pos_mm, dir_state, temp_c)
    if hasattr(model, "error_f32"):
        err, _flags = model.error_f32(pos_mm, dir_state, temp_c)
        return np.asarray(err, dtype=np.float64)
    if callable(model):
        return np.asarray(model(pos_mm, dir_state, temp_c), dtype=np.float64).reshape(-1, 3)
    raise TypeError(f"cannot evaluate a model of type {type(model).__name__}")


def direction_states(test: Any, angle_deg: np.ndarray, direction: np.ndarray,
                     takeup_mm: tuple[float, float, float] | None = None) -> np.ndarray:
    """Backlash direction state (N, 3) along the commanded samples, in their order.

    Without take-up (None or 0): the direction of motion (0 at a reversal point).
    With take-up: the state ramps by 2 dp / take-up along the path (as the library's
    compensator does), starting from the direction of the first motion of each axis.
    """
    from abbe.sim.virtual_machine import backlash_state

    ang = np.asarray(angle_deg, dtype=np.float64).reshape(-1)
    inst = travel_direction(test, ang, np.asarray(direction).reshape(-1))
    if takeup_mm is None:
        return inst
    pos = circle_points(test, ang)
    out = inst.copy()
    for j in range(3):
        if not takeup_mm[j] or takeup_mm[j] <= 0:
            continue
        nz = np.nonzero(inst[:, j])[0]
        s0 = float(inst[nz[0], j]) if nz.size else 1.0
        out[:, j] = backlash_state(pos[:, j], float(takeup_mm[j]), s0)
    return out


def predict_ballbar(model: Any, test: Any, angle_deg: np.ndarray | None = None,
                    direction: np.ndarray | None = None, temp_c: np.ndarray | None = None,
                    backlash: bool = True,
                    takeup_mm: tuple[float, float, float] | None = None) -> np.ndarray:
    """Predicted ballbar radial deviation (um) per sample: ``u_r . E_model`` at the
    commanded points.

    ``angle_deg``/``direction``: the samples in the order run (e.g. a measured
    trace's, feed arcs included); default one CCW revolution at 1 deg. Backlash
    direction state: :func:`direction_states` with the take-up ``takeup_mm`` (default:
    the Table's ``backlash_takeup_mm``; instantaneous for other models), off if
    ``backlash`` is False. ``temp_c`` (N, 3) axis temperatures or None (no thermal).
    Dynamic effects (servo lag) are not predicted.
    """
    from abbe.formats.blob import AXES, Table

    if angle_deg is None:
        angle_deg = np.arange(0.0, 360.0, 1.0)
    ang = np.asarray(angle_deg, dtype=np.float64).reshape(-1)
    dirs = (np.full(ang.size, "ccw") if direction is None
            else np.asarray(direction).reshape(-1))
    pos = circle_points(test, ang)
    ds = None
    if backlash:
        if takeup_mm is None and isinstance(model, Table):
            takeup_mm = tuple(float(model.axes[a].backlash_takeup_mm) for a in AXES)
        ds = direction_states(test, ang, dirs, takeup_mm)
    err = model_error_um(model, pos, ds, temp_c)
    return np.einsum("ni,ni->n", radial_units(test.plane, ang), err)


def predict_trace(model: Any, trace: BallbarTrace, test: Any, **kw: Any) -> np.ndarray:
    """:func:`predict_ballbar` at the samples of ``trace``."""
    return predict_ballbar(model, test, trace.angle_deg, trace.direction, **kw)


# --------------------------------------------------------------------------- plot


def _nice(x: float) -> float:
    if x <= 0:
        return 1.0
    e = 10 ** math.floor(math.log10(x))
    for m in (1.0, 2.0, 5.0, 10.0):
        if x <= m * e:
            return m * e
    return 10.0 * e


def plot_polar(result: BallbarResult, path: str | Path, title: str | None = None) -> None:
    """Polar plot as ballbar software draws it: both runs' radial residuals about the
    bidirectional LS circle (centre and radius removed), magnified around a nominal
    circle (the bold circle = 0 um; scale in um on the radial axis). Writes a PNG."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    res_all = np.concatenate([result.residual_both[d] for d in DIRECTIONS])
    half = _nice(max(float(np.max(np.abs(res_all))), 1e-3) * 1.1)
    fig = plt.figure(figsize=(6.4, 6.4), dpi=100)
    ax = fig.add_subplot(projection="polar")
    ax.set_rorigin(-3.0 * half)
    ax.set_rlim(-half, half)
    th = np.radians(np.linspace(0.0, 360.0, 721))
    ax.plot(th, np.zeros_like(th), color="black", lw=1.6, label="nominal")
    colors = {"ccw": "tab:blue", "cw": "tab:red"}
    for d in DIRECTIONS:
        a = result.angles[d]
        r = result.residual_both[d]
        o = np.argsort(a)
        a2 = np.append(a[o], a[o][0] + 360.0)
        r2 = np.append(r[o], r[o][0])
        ax.plot(np.radians(a2), r2, color=colors[d], lw=1.0,
                label=f"{d.upper()}  G = {result.per_direction[d].G_um:.2f} um")
    na, nb = result.axis_names()
    ax.set_thetagrids(range(0, 360, 45),
                      [f"+{na}", "", f"+{nb}", "", f"-{na}", "", f"-{nb}", ""])
    ax.set_rticks([-half, -half / 2, 0.0, half / 2, half])
    ax.set_rlabel_position(22.5)
    ax.tick_params(axis="y", labelsize=7)
    c = result.both
    info = (f"G (both) = {c.G_um:.2f} um   H = {result.H_um:.2f} um\n"
            f"centre {na}/{nb} = {c.center_um[0]:.2f} / {c.center_um[1]:.2f} um   "
            f"radius dev = {c.radius_dev_um:.2f} um\n"
            f"scale: {half / 2:g} um per ring; LS circle removed")
    fig.text(0.98, 0.02, info, ha="right", va="bottom", fontsize=8, family="monospace")
    ax.set_title(title or f"ballbar {result.name}: {result.plane}, R {result.radius_mm:g} mm, "
                 f"F {result.feed_mm_min:g} mm/min", fontsize=10, pad=22)
    ax.legend(loc="lower left", bbox_to_anchor=(-0.14, -0.16), fontsize=8, frameon=False)
    fig.subplots_adjust(bottom=0.16)
    fig.savefig(str(path), format="png", metadata={"Software": None})
    plt.close(fig)
