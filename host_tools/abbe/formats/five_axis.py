"""Five-axis parts of the machine file and the five-axis measurement files.

Machine file sections (docs/formats.md, "Five-axis machine file"):

* ``[rotary]``: ``kinematics`` (``xyzac-trt`` / ``xyzbc-trt``), the LinuxCNC trt
  geometry (``x_rot_point_mm``, ``y_rot_point_mm``, ``z_rot_point_mm``;
  ``y_offset_mm``, ``z_offset_mm`` for A or ``x_offset_mm``, ``z_offset_mm`` for
  B; ``tool_length_mm``), ``[rotary.A|B|C] travel_deg``, and the plan's fit
  settings ``[rotary.fit]``;
* ``[probing.NAME]``: a touch-probe campaign on a calibration sphere (``datum_u_um``: the
  sphere is a datum, its centre known at ``sphere_mm`` to that standard uncertainty);
* ``[rtest.NAME]``: an R-test campaign;
* ``[indexer.C]`` (or A / B): a laser with a rotary indexer (ISO 230-2 of a rotary axis);
* ``[rotary_ballbar.NAME]``: a ballbar with a rotary axis turning under tool-centre-point
  control (ISO 10791-6 style set-ups), its two balls' nominal places.

Data files, strict CSV with fixed column names (units in the names):

* probing: ``position,t_s,<tilt>_deg,c_deg,x_mm,y_mm,z_mm`` - the machine
  positions where the probe triggered, several points per position;
* R-test: ``t_s,<tilt>_deg,c_deg,dx_um,dy_um,dz_um`` - the sphere centre's
  displacement (machine axes) under tool-centre-point control;
* indexer: ``run,direction,target_deg,deviation_urad`` (direction ``+``/``-``);
* rotary ballbar: ``t_s,<tilt>_deg,c_deg,radial_um`` - measured minus nominal bar length
  (the 3-axis ballbar CSV's ``radial_um``), whatever the bar's direction.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from abbe.errors import AbbeInputError, check_number
from abbe.errors.numbers import show_value
from abbe.formats.ballbar_csv import MAX_RADIAL_UM
from abbe.formats.delimited import DEFAULT_DIALECT, Column, Header, read_columns
from abbe.formats.limits import FIVE_AXIS_CSV_MAX_BYTES, FIVE_AXIS_CSV_MAX_ROWS
from abbe.formats.structured import unknown_key
from abbe.formats.text import read_text
from abbe.model.five_axis import KINEMATICS, TrunnionGeometry

#: Ranges of the five-axis numbers (docs/formats.md).
ANGLE_RANGE_DEG = (-3600.0, 3600.0)
SPHERE_RADIUS_RANGE_MM = (0.5, 100.0)
STYLUS_RADIUS_RANGE_MM = (0.0, 20.0)
RADIUS_TOL_RANGE_MM = (0.0001, 1.0)
TOOL_LENGTH_RANGE_MM = (0.0, 1000.0)
DISPLACEMENT_LIMIT_UM = 10_000.0
DEVIATION_LIMIT_URAD = 100_000.0
TIME_LIMIT_S = 1e7
HARMONICS_MAX = 8
#: A datum sphere's declared standard uncertainty (um): below 0.01 um no calibration of a
#: location on a table is; above 1 mm it is no datum.
DATUM_U_RANGE_UM = (0.01, 1000.0)
#: A rotary ballbar's nominal length (mm): the bars sold run from 50 to 600 mm; a tool and a
#: table ball closer than 10 mm or further than 1000 mm are not a ballbar set-up.
BAR_LENGTH_RANGE_MM = (10.0, 1000.0)

#: Class defaults of the Type B budget (docs/uncertainty.md, "Five-axis identification"):
#: an R-test's displacement sensors calibrated to 1 % of their sensitivity (k = 2); a
#: ballbar's length calibrated to 1 um (k = 2, the ISO 230-4 ballbar class default).
RTEST_CALIBRATION_U_PCT = 1.0
BALLBAR_CALIBRATION_U_UM = 1.0
CALIBRATION_U_PCT_RANGE = (0.0, 50.0)
CALIBRATION_U_UM_RANGE = (0.0, 100.0)

_OFFSETS = {"xyzac-trt": ("y_offset_mm", "z_offset_mm"), "xyzbc-trt": ("x_offset_mm", "z_offset_mm")}


@dataclass(frozen=True)
class ProbingPlan:
    """A touch-probe campaign: ``file`` (resolved), the calibration sphere's nominal
    centre in workpiece coordinates (mm), its radius and the probe's effective
    stylus radius (mm), the radius check tolerance (mm)."""

    name: str
    file: Path
    sphere_mm: tuple[float, float, float]
    sphere_radius_mm: float
    stylus_radius_mm: float
    radius_tolerance_mm: float
    line: int | None = None
    #: a datum: the sphere's centre is known at ``sphere_mm`` in the workpiece frame (a
    #: calibrated location on the table) to this standard uncertainty (um, k = 1); None: its
    #: place is a set-up unknown like any sphere's
    datum_u_um: float | None = None


@dataclass(frozen=True)
class RTestPlan:
    """An R-test campaign: ``file`` (resolved) and the sphere's nominal centre (mm)."""

    name: str
    file: Path
    sphere_mm: tuple[float, float, float]
    line: int | None = None
    #: U (k = 2) of the R-test sensors' sensitivity, % (None: the class default,
    #: RTEST_CALIBRATION_U_PCT)
    calibration_U_pct: float | None = None


@dataclass(frozen=True)
class IndexerPlan:
    """A laser + rotary indexer measurement of ``axis`` (file resolved)."""

    axis: str
    file: Path
    line: int | None = None


@dataclass(frozen=True)
class RotaryBallbarPlan:
    """A ballbar with a rotary axis turning: ``file`` (resolved), the table ball's and the
    tool ball's nominal centres in workpiece coordinates (mm; the tool ball is held there
    under tool-centre-point control), the bar's nominal length (mm, their distance)."""

    name: str
    file: Path
    table_ball_mm: tuple[float, float, float]
    tool_ball_mm: tuple[float, float, float]
    line: int | None = None
    setup: str = ""  # sections sharing a set-up share the table ball and the tool cup
    #: U (k = 2) of the bar's length calibration, um (None: BALLBAR_CALIBRATION_U_UM)
    calibration_U_um: float | None = None

    @property
    def length_mm(self) -> float:
        return float(np.linalg.norm(np.subtract(self.tool_ball_mm, self.table_ball_mm)))


@dataclass(frozen=True)
class FitPlan:
    """What the five-axis fit identifies: error motion harmonics (0 = location only),
    the squareness of the linear axes, folds of the held-out judgement."""

    harmonics: int = 0
    squareness: bool = False
    folds: int = 4


@dataclass(frozen=True)
class FiveAxisSpec:
    """The five-axis sections of a machine file."""

    geometry: TrunnionGeometry
    probing: dict[str, ProbingPlan]
    rtest: dict[str, RTestPlan]
    indexer: dict[str, IndexerPlan]
    fit: FitPlan
    ballbar: dict[str, RotaryBallbarPlan] = field(default_factory=dict)


TOP_KEYS = ("rotary", "probing", "rtest", "indexer", "rotary_ballbar")

# ------------------------------------------------------------------ machine file


def parse_five_axis(data: dict[str, Any], err: Callable[[str, str], AbbeInputError],
                    line: Callable[[str], int | None], file: str,
                    resolve: Callable[[str, str], Path]) -> FiveAxisSpec | None:
    """The five-axis sections of a parsed machine file, or None without ``[rotary]``.

    ``err(field, message)`` builds a located error, ``line(field)`` finds a key's
    line, ``resolve(rel, field)`` makes a data path absolute.
    """
    if "rotary" not in data:
        if "chain" in data:  # a [chain] machine: abbe.formats.chain reads its sections
            return None
        for k in ("probing", "rtest", "indexer", "rotary_ballbar"):
            if k in data:
                raise err(k, f"[{k}] needs a [rotary] section (the five-axis kinematics)")
        return None
    rot = _table(data["rotary"], err, "rotary")

    def num(v: Any, f: str, lo: float, hi: float, unit: str) -> float:
        return check_number(v, file=file, line=line(f), field=f, lo=lo, hi=hi, unit=unit)

    kind = rot.get("kinematics")
    if not isinstance(kind, str) or kind not in KINEMATICS:
        raise err("rotary.kinematics", f"expected one of {', '.join(KINEMATICS)}, got "
                  f"{show_value(kind)}" if kind is not None else "missing required key 'kinematics'")
    tilt, table = KINEMATICS[kind]
    allowed = ("kinematics", "x_rot_point_mm", "y_rot_point_mm", "z_rot_point_mm",
               "tool_length_mm", *_OFFSETS[kind], tilt, table, "fit")
    for k in rot:
        if k not in allowed:
            raise err(f"rotary.{k}", unknown_key(k, allowed) + f" (for {kind})")
    rp = tuple(num(rot.get(k, 0.0), f"rotary.{k}", -2147.0, 2147.0, "mm")
               for k in ("x_rot_point_mm", "y_rot_point_mm", "z_rot_point_mm"))
    a, b = (num(rot.get(k, 0.0), f"rotary.{k}", -2147.0, 2147.0, "mm") for k in _OFFSETS[kind])
    offset = (0.0, a, b) if kind == "xyzac-trt" else (a, 0.0, b)
    tool = num(rot.get("tool_length_mm", 0.0), "rotary.tool_length_mm", *TOOL_LENGTH_RANGE_MM, "mm")
    travel: dict[str, tuple[float, float]] = {}
    for ax in (tilt, table):
        f = f"rotary.{ax}"
        if ax not in rot:
            raise err("rotary", f"missing [rotary.{ax}] (travel_deg = [min, max])")
        sec = _table(rot[ax], err, f)
        for k in sec:
            if k != "travel_deg":
                raise err(f"{f}.{k}", unknown_key(k, ("travel_deg",)))
        v = sec.get("travel_deg")
        if not isinstance(v, list) or len(v) != 2:
            raise err(f"{f}.travel_deg", f"expected [min, max] in degrees, got {show_value(v)}")
        lo, hi = (num(x, f"{f}.travel_deg", *ANGLE_RANGE_DEG, "deg") for x in v)
        if not lo < hi:
            raise err(f"{f}.travel_deg", f"expected min < max, got [{lo}, {hi}] deg")
        travel[ax] = (lo, hi)
    geom = TrunnionGeometry(kind, rp, offset, tool, travel)  # type: ignore[arg-type]
    fit = _fit_plan(rot.get("fit", {}), err, line, file)

    probing: dict[str, ProbingPlan] = {}
    for name, sec in _table(data.get("probing", {}), err, "probing").items():
        f = f"probing.{name}"
        s = _keys(_table(sec, err, f), err, f, ("file", "sphere_mm", "sphere_radius_mm",
                                                "stylus_radius_mm", "radius_tolerance_mm",
                                                "datum_u_um"),
                  ("file", "sphere_mm", "sphere_radius_mm"))
        probing[name] = ProbingPlan(
            name, resolve(_str(s["file"], err, f"{f}.file"), f"{f}.file"),
            _vec3(s["sphere_mm"], num, err, f"{f}.sphere_mm"),
            num(s["sphere_radius_mm"], f"{f}.sphere_radius_mm", *SPHERE_RADIUS_RANGE_MM, "mm"),
            num(s.get("stylus_radius_mm", 0.0), f"{f}.stylus_radius_mm", *STYLUS_RADIUS_RANGE_MM, "mm"),
            num(s.get("radius_tolerance_mm", 0.02), f"{f}.radius_tolerance_mm",
                *RADIUS_TOL_RANGE_MM, "mm"), line(f),
            None if "datum_u_um" not in s
            else num(s["datum_u_um"], f"{f}.datum_u_um", *DATUM_U_RANGE_UM, "um"))
    rtest: dict[str, RTestPlan] = {}
    for name, sec in _table(data.get("rtest", {}), err, "rtest").items():
        f = f"rtest.{name}"
        s = _keys(_table(sec, err, f), err, f, ("file", "sphere_mm", "calibration_U_pct"),
                  ("file", "sphere_mm"))
        rtest[name] = RTestPlan(name, resolve(_str(s["file"], err, f"{f}.file"), f"{f}.file"),
                                _vec3(s["sphere_mm"], num, err, f"{f}.sphere_mm"), line(f),
                                None if "calibration_U_pct" not in s else
                                num(s["calibration_U_pct"], f"{f}.calibration_U_pct",
                                    *CALIBRATION_U_PCT_RANGE, "%"))
    indexer: dict[str, IndexerPlan] = {}
    for name, sec in _table(data.get("indexer", {}), err, "indexer").items():
        f = f"indexer.{name}"
        if name not in (tilt, table):
            raise err(f, f"an indexer section is named after a rotary axis ({tilt}, {table})")
        s = _keys(_table(sec, err, f), err, f, ("file",), ("file",))
        indexer[name] = IndexerPlan(name, resolve(_str(s["file"], err, f"{f}.file"), f"{f}.file"),
                                    line(f))
    ballbar: dict[str, RotaryBallbarPlan] = {}
    for name, sec in _table(data.get("rotary_ballbar", {}), err, "rotary_ballbar").items():
        f = f"rotary_ballbar.{name}"
        s = _keys(_table(sec, err, f), err, f, ("file", "table_ball_mm", "tool_ball_mm", "setup",
                                                "calibration_U_um"),
                  ("file", "table_ball_mm", "tool_ball_mm"))
        su = s.get("setup", "")
        if not isinstance(su, str) or not su.replace("_", "").replace("-", "").isalnum() \
                and su != "":
            raise err(f"{f}.setup", f"expected a set-up name (letters, digits, _ or -), got "
                      f"{show_value(su)}")
        bb = RotaryBallbarPlan(name, resolve(_str(s["file"], err, f"{f}.file"), f"{f}.file"),
                               _vec3(s["table_ball_mm"], num, err, f"{f}.table_ball_mm"),
                               _vec3(s["tool_ball_mm"], num, err, f"{f}.tool_ball_mm"), line(f),
                               su, None if "calibration_U_um" not in s else
                               num(s["calibration_U_um"], f"{f}.calibration_U_um",
                                   *CALIBRATION_U_UM_RANGE, "um"))
        same = [o for o in ballbar.values() if su and o.setup == su]
        if same and same[0].table_ball_mm != bb.table_ball_mm:
            raise err(f"{f}.table_ball_mm", f"set-up {su!r} shares one table ball: expected "
                      f"{list(same[0].table_ball_mm)} as [rotary_ballbar.{same[0].name}], got "
                      f"{list(bb.table_ball_mm)}")
        lo, hi = BAR_LENGTH_RANGE_MM
        if not lo <= bb.length_mm <= hi:
            raise err(f"{f}.tool_ball_mm", f"expected the balls {lo:g} to {hi:g} mm apart (the "
                      f"bar's length), got {bb.length_mm:.6g} mm")
        ballbar[name] = bb
    if not probing and not rtest and not indexer and not ballbar:
        raise err("rotary", "a five-axis machine file needs at least one [probing.NAME], "
                  "[rtest.NAME], [indexer.AXIS] or [rotary_ballbar.NAME] section")
    return FiveAxisSpec(geom, probing, rtest, indexer, fit, ballbar)


def _fit_plan(v: Any, err: Callable[[str, str], AbbeInputError], line: Callable[[str], int | None],
              file: str) -> FitPlan:
    f = "rotary.fit"
    s = _keys(_table(v, err, f), err, f, ("harmonics", "squareness", "folds"), ())
    h = s.get("harmonics", 0)
    if isinstance(h, bool) or not isinstance(h, int) or not 0 <= h <= HARMONICS_MAX:
        raise err(f"{f}.harmonics", f"expected an integer in [0, {HARMONICS_MAX}], got {show_value(h)}")
    sq = s.get("squareness", False)
    if not isinstance(sq, bool):
        raise err(f"{f}.squareness", f"expected true or false, got {show_value(sq)}")
    folds = s.get("folds", 4)
    if isinstance(folds, bool) or not isinstance(folds, int) or not 2 <= folds <= 20:
        raise err(f"{f}.folds", f"expected an integer in [2, 20], got {show_value(folds)}")
    return FitPlan(h, sq, folds)


def _table(v: Any, err: Callable[[str, str], AbbeInputError], f: str) -> dict[str, Any]:
    if not isinstance(v, dict):
        raise err(f, f"expected a table [{f}], got {show_value(v)}")
    return v


def _keys(sec: dict[str, Any], err: Callable[[str, str], AbbeInputError], f: str,
          allowed: tuple[str, ...], required: tuple[str, ...]) -> dict[str, Any]:
    for k in sec:
        if k not in allowed:
            raise err(f"{f}.{k}", unknown_key(k, allowed))
    for k in required:
        if k not in sec:
            raise err(f, f"missing required key {k!r}")
    return sec


def _str(v: Any, err: Callable[[str, str], AbbeInputError], f: str) -> str:
    if not isinstance(v, str) or not v.strip() or "\0" in v:
        raise err(f, f"expected a file name, got {show_value(v)}")
    return v


def _vec3(v: Any, num: Callable[..., float], err: Callable[[str, str], AbbeInputError],
          f: str) -> tuple[float, float, float]:
    if not isinstance(v, list) or len(v) != 3:
        raise err(f, f"expected an array of 3 numbers (mm), got {show_value(v)}")
    x, y, z = (num(e, f, -2147.0, 2147.0, "mm") for e in v)
    return (x, y, z)


# ------------------------------------------------------------------ data files


@dataclass(frozen=True)
class ProbePoints:
    """Probe trigger points: position index, time s, angles (N, 2) deg (tilt, C),
    machine positions (N, 3) mm, the file's line of every row."""

    position: np.ndarray
    time_s: np.ndarray
    angles_deg: np.ndarray
    points_mm: np.ndarray
    line_no: np.ndarray
    file: str


@dataclass(frozen=True)
class RTestTrace:
    """R-test readings: time s, angles (N, 2) deg, sphere displacement (N, 3) um."""

    time_s: np.ndarray
    angles_deg: np.ndarray
    displacement_um: np.ndarray
    line_no: np.ndarray
    file: str


@dataclass(frozen=True)
class IndexerRuns:
    """Rotary positioning deviations: run, direction (+1/-1), target deg, deviation urad."""

    run: np.ndarray
    direction: np.ndarray
    target_deg: np.ndarray
    deviation_urad: np.ndarray
    line_no: np.ndarray
    file: str


def probe_columns(tilt: str, second: str = "C") -> tuple[str, ...]:
    """Probing CSV header; ``tilt``, ``second``: the angle columns' axes (a chain's two
    rotary axes in alphabetical order; the trunnions' tilt axis and C)."""
    return ("position", "t_s", f"{tilt.lower()}_deg", f"{second.lower()}_deg", "x_mm", "y_mm",
            "z_mm")


def rtest_columns(tilt: str, second: str = "C") -> tuple[str, ...]:
    """R-test CSV header (angle columns as :func:`probe_columns`)."""
    return ("t_s", f"{tilt.lower()}_deg", f"{second.lower()}_deg", "dx_um", "dy_um", "dz_um")


def rotary_ballbar_columns(tilt: str, second: str = "C") -> tuple[str, ...]:
    """Rotary ballbar CSV header (angle columns as :func:`probe_columns`: a ``[chain]``
    machine's two rotary axes in alphabetical order)."""
    return ("t_s", f"{tilt.lower()}_deg", f"{second.lower()}_deg", "radial_um")


INDEXER_COLUMNS = ("run", "direction", "target_deg", "deviation_urad")


def _read(path: Path, names: tuple[str, ...], cols: dict[str, Column], what: str
          ) -> tuple[dict[str, np.ndarray], np.ndarray, str]:
    f = str(path)
    tf = read_text(path, what=what, max_bytes=FIVE_AXIS_CSV_MAX_BYTES)

    def plan(header: Header) -> dict[str, Column]:
        if tuple(header.names) != names:
            raise AbbeInputError(f"expected the header {','.join(names)}, got "
                                 f"{','.join(header.names)}", file=f, line=header.line)
        return {n: Column(n, i, cols[n].kind, cols[n].lo, cols[n].hi, cols[n].unit,
                          choices=cols[n].choices, expected=cols[n].expected)
                for i, n in enumerate(names)}

    _h, vals, lines = read_columns(tf, DEFAULT_DIALECT, what=what,
                                   max_rows=FIVE_AXIS_CSV_MAX_ROWS, plan=plan)
    if lines.size == 0:
        raise AbbeInputError(f"the {what} holds no data rows", file=f)
    return vals, lines, f


def _angle(name: str) -> Column:
    return Column(name, 0, "number", *ANGLE_RANGE_DEG, "deg")


def _time() -> Column:
    return Column("t_s", 0, "number", 0.0, TIME_LIMIT_S, "s")


def read_probe_points(path: str | Path, tilt: str, second: str = "C") -> ProbePoints:
    """Read a probing CSV (strict header, finite numbers in range, time not decreasing,
    at least 4 points per position, positions' rows contiguous and at one angle pair)."""
    names = probe_columns(tilt, second)
    cols = {"position": Column("position", 0, "int", 0, 100_000), "t_s": _time(),
            names[2]: _angle(names[2]), names[3]: _angle(names[3]),
            **{n: Column(n, 0, "number", -2147.0, 2147.0, "mm") for n in names[4:]}}
    v, lines, f = _read(Path(path), names, cols, "probing CSV")
    pos = v["position"]
    ang = np.column_stack([v[names[2]], v[names[3]]])
    _monotone_time(v["t_s"], lines, f)
    starts = np.flatnonzero(np.r_[True, pos[1:] != pos[:-1]])
    if len(np.unique(pos)) != len(starts):
        i = next(i for i in starts[1:] if pos[i] in pos[:i])
        raise AbbeInputError(f"the rows of position {int(pos[i])} are not contiguous", file=f,
                             line=int(lines[i]), field="position")
    ends = np.r_[starts[1:], pos.size]
    for s, e in zip(starts, ends):
        if e - s < 4:
            raise AbbeInputError(f"position {int(pos[s])} has {e - s} points; a sphere fit needs "
                                 "at least 4", file=f, line=int(lines[s]), field="position")
        bad = np.flatnonzero(np.any(np.abs(ang[s:e] - ang[s]) > 1e-9, axis=1))
        if bad.size:
            raise AbbeInputError(f"the angles change inside position {int(pos[s])}", file=f,
                                 line=int(lines[s + bad[0]]), field=names[2])
    return ProbePoints(pos, v["t_s"], ang, np.column_stack([v[n] for n in names[4:]]), lines, f)


def read_rtest(path: str | Path, tilt: str, second: str = "C") -> RTestTrace:
    """Read an R-test CSV (strict header, finite numbers in range, time not decreasing)."""
    names = rtest_columns(tilt, second)
    cols = {"t_s": _time(), names[1]: _angle(names[1]), names[2]: _angle(names[2]),
            **{n: Column(n, 0, "number", -DISPLACEMENT_LIMIT_UM, DISPLACEMENT_LIMIT_UM, "um")
               for n in names[3:]}}
    v, lines, f = _read(Path(path), names, cols, "R-test CSV")
    _monotone_time(v["t_s"], lines, f)
    if lines.size < 3:
        raise AbbeInputError("an R-test needs at least 3 readings", file=f)
    return RTestTrace(v["t_s"], np.column_stack([v[names[1]], v[names[2]]]),
                      np.column_stack([v[n] for n in names[3:]]), lines, f)


@dataclass(frozen=True)
class RotaryBallbarTrace:
    """Rotary ballbar readings: time s, angles (N, 2) deg (tilt, C), measured minus nominal
    bar length (N,) um, the file's line of every row."""

    time_s: np.ndarray
    angles_deg: np.ndarray
    radial_um: np.ndarray
    line_no: np.ndarray
    file: str


def read_rotary_ballbar(path: str | Path, tilt: str, second: str = "C") -> RotaryBallbarTrace:
    """Read a rotary ballbar CSV (strict header, finite numbers in range, |radial_um| <=
    the 3-axis ballbar's limit, time not decreasing, at least 3 readings, a rotary axis
    that turns)."""
    names = rotary_ballbar_columns(tilt, second)
    cols = {"t_s": _time(), names[1]: _angle(names[1]), names[2]: _angle(names[2]),
            "radial_um": Column("radial_um", 0, "number", -MAX_RADIAL_UM, MAX_RADIAL_UM, "um")}
    v, lines, f = _read(Path(path), names, cols, "rotary ballbar CSV")
    _monotone_time(v["t_s"], lines, f)
    if lines.size < 3:
        raise AbbeInputError("a rotary ballbar test needs at least 3 readings", file=f)
    ang = np.column_stack([v[names[1]], v[names[2]]])
    if np.ptp(ang, axis=0).max() < 1.0:
        raise AbbeInputError("no rotary axis turns (by 1 deg or more) in this ballbar test",
                             file=f, field=names[1])
    return RotaryBallbarTrace(v["t_s"], ang, v["radial_um"], lines, f)


def read_indexer(path: str | Path) -> IndexerRuns:
    """Read an indexer CSV: runs >= 1, direction ``+`` / ``-``, at least 2 targets."""
    cols = {"run": Column("run", 0, "int", 1, 100),
            "direction": Column("direction", 0, "choice", choices={"+": 0, "-": 1},
                                expected="'+' or '-'"),
            "target_deg": _angle("target_deg"),
            "deviation_urad": Column("deviation_urad", 0, "number", -DEVIATION_LIMIT_URAD,
                                     DEVIATION_LIMIT_URAD, "urad")}
    v, lines, f = _read(Path(path), INDEXER_COLUMNS, cols, "indexer CSV")
    if np.unique(v["target_deg"]).size < 2:
        raise AbbeInputError("an indexer file needs at least 2 target angles", file=f)
    return IndexerRuns(v["run"], np.where(v["direction"] == 0, 1, -1), v["target_deg"],
                       v["deviation_urad"], lines, f)


def _monotone_time(t: np.ndarray, lines: np.ndarray, f: str) -> None:
    bad = np.flatnonzero(np.diff(t) < 0)
    if bad.size:
        raise AbbeInputError("time goes backwards", file=f, line=int(lines[bad[0] + 1]), field="t_s")


# ------------------------------------------------------------------ writers


def _fmt(v: float) -> str:
    if not np.isfinite(v):
        raise ValueError("refusing to write a non-finite number")
    return f"{v:.6f}".rstrip("0").rstrip(".") if v != 0 else "0"


def probe_csv(tilt: str, position: np.ndarray, time_s: np.ndarray, angles_deg: np.ndarray,
              points_mm: np.ndarray, second: str = "C") -> str:
    """The text of a probing CSV (:func:`read_probe_points` reads it)."""
    rows = [",".join(probe_columns(tilt, second))]
    for i in range(len(position)):
        rows.append(",".join([str(int(position[i])), _fmt(time_s[i]), _fmt(angles_deg[i, 0]),
                              _fmt(angles_deg[i, 1])] + [_fmt(x) for x in points_mm[i]]))
    return "\n".join(rows) + "\n"


def rtest_csv(tilt: str, time_s: np.ndarray, angles_deg: np.ndarray, disp_um: np.ndarray,
              second: str = "C") -> str:
    """The text of an R-test CSV (:func:`read_rtest` reads it)."""
    rows = [",".join(rtest_columns(tilt, second))]
    for i in range(len(time_s)):
        rows.append(",".join([_fmt(time_s[i]), _fmt(angles_deg[i, 0]), _fmt(angles_deg[i, 1])]
                             + [_fmt(x) for x in disp_um[i]]))
    return "\n".join(rows) + "\n"


def indexer_csv(run: np.ndarray, direction: np.ndarray, target_deg: np.ndarray,
                dev_urad: np.ndarray) -> str:
    """The text of an indexer CSV (:func:`read_indexer` reads it)."""
    rows = [",".join(INDEXER_COLUMNS)]
    for i in range(len(run)):
        rows.append(f"{int(run[i])},{'+' if direction[i] > 0 else '-'},{_fmt(target_deg[i])},"
                    f"{_fmt(dev_urad[i])}")
    return "\n".join(rows) + "\n"


def rotary_ballbar_csv(tilt: str, time_s: np.ndarray, angles_deg: np.ndarray,
                       radial_um: np.ndarray, second: str = "C") -> str:
    """The text of a rotary ballbar CSV (:func:`read_rotary_ballbar` reads it)."""
    rows = [",".join(rotary_ballbar_columns(tilt, second))]
    for i in range(len(time_s)):
        rows.append(",".join([_fmt(time_s[i]), _fmt(angles_deg[i, 0]), _fmt(angles_deg[i, 1]),
                              _fmt(radial_um[i])]))
    return "\n".join(rows) + "\n"
