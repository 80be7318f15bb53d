"""The machine file's ``[chain]``: a five-axis machine's kinematic chain (docs/formats.md,
"Kinematic chain (`[chain]`)").

::

    [chain]
    name = "5axiskins"                    # optional label
    order = ["X", "Y", "Z", "C", "B"]     # workpiece -> tool (ISO 10791-1 style)
    tool_length_mm = 0.0                  # optional: the linear axes' Abbe lever
    reference_mm = [0.0, 0.0, 0.0]        # optional: where squareness is taken about
    [chain.C]
    direction = "+Z"                      # A: "+X"/"-X", B: "+Y"/"-Y", C: "+Z"/"-Z"
    pivot_mm = [0.0, 0.0, 250.0]          # a point of the nominal line, all axes at zero
    travel_deg = [-360.0, 360.0]
    [chain.B]
    ...
    [chain.fit]                           # optional: what `abbe fit` identifies
    harmonics = 2                         # error motions up to H (0 = location errors only)
    folds = 4                             # held-out folds of `abbe diagnose`

Every problem is an :class:`abbe.errors.AbbeInputError` with file, line, field and
what was expected (exit 2 from the CLI).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from abbe.errors import AbbeInputError, check_number
from abbe.errors.numbers import show_value
from abbe.formats.five_axis import (BAR_LENGTH_RANGE_MM, HARMONICS_MAX, RADIUS_TOL_RANGE_MM,
                                    SPHERE_RADIUS_RANGE_MM, STYLUS_RADIUS_RANGE_MM)
from abbe.formats.structured import unknown_key
from abbe.model.chain import (LINEAR_AXES, ROTARY_MACHINE_AXIS, ChainAxis, KinematicChain,
                              chain_problem)

#: Ranges (docs/formats.md): pivots and reference within the coordinate range of the
#: trunnion file's rot-point (mm), angles as the five-axis files (deg).
PIVOT_RANGE_MM = (-2147.0, 2147.0)
ANGLE_RANGE_DEG = (-3600.0, 3600.0)
TOOL_LENGTH_RANGE_MM = (0.0, 1000.0)
_TOP_KEYS = ("name", "order", "tool_length_mm", "reference_mm")
_AXIS_KEYS = ("direction", "pivot_mm", "travel_deg")
_MACHINE_AXIS = {0: "X", 1: "Y", 2: "Z"}


def parse_chain(data: dict[str, Any], err: Callable[[str, str], AbbeInputError],
                line: Callable[[str], int | None], file: str) -> KinematicChain | None:
    """The ``[chain]`` section of a parsed machine file as a :class:`KinematicChain`, or
    None without one. ``err(field, message)`` builds a located error; ``line(field)``
    finds a key's line."""
    if "chain" not in data:
        return None
    sec = data["chain"]
    if not isinstance(sec, dict):
        raise err("chain", f"expected a table [chain], got {show_value(sec)}")

    def num(v: Any, f: str, lo: float, hi: float, unit: str) -> float:
        return check_number(v, file=file, line=line(f), field=f, lo=lo, hi=hi, unit=unit)

    order = sec.get("order")
    if order is None:
        raise err("chain", "missing required key 'order' (the axes from the workpiece to the "
                           "tool, e.g. [\"C\", \"A\", \"X\", \"Y\", \"Z\"])")
    if not isinstance(order, list) or not all(isinstance(n, str) for n in order):
        raise err("chain.order", f"expected an array of axis names, got {show_value(order)}")
    problem = chain_problem(order)
    if problem:
        raise err("chain.order", f"{problem}; got {show_value(order)}")
    rotary = [n for n in order if n in ROTARY_MACHINE_AXIS]
    allowed = (*_TOP_KEYS, *rotary, "fit")
    for k in sec:
        if k not in allowed:
            raise err(f"chain.{k}", unknown_key(k, allowed) + " (linear axes take no section: "
                      "they define the machine frame)" if k in LINEAR_AXES else
                      unknown_key(k, allowed))
    name = sec.get("name", "")
    if not isinstance(name, str) or "\0" in name:
        raise err("chain.name", f"expected a string, got {show_value(name)}")
    tool = num(sec.get("tool_length_mm", 0.0), "chain.tool_length_mm", *TOOL_LENGTH_RANGE_MM, "mm")
    ref = _vec3(sec.get("reference_mm", [0.0, 0.0, 0.0]), "chain.reference_mm", num, err)
    axes: list[ChainAxis] = []
    for n in order:
        if n in LINEAR_AXES:
            axes.append(ChainAxis(n, 1, (0.0, 0.0, 0.0), (0.0, 0.0)))
            continue
        f = f"chain.{n}"
        if n not in sec:
            raise err("chain", f"missing [chain.{n}] (direction, pivot_mm, travel_deg)")
        a = sec[n]
        if not isinstance(a, dict):
            raise err(f, f"expected a table [{f}], got {show_value(a)}")
        for k in a:
            if k not in _AXIS_KEYS:
                raise err(f"{f}.{k}", unknown_key(k, _AXIS_KEYS))
        for k in _AXIS_KEYS:
            if k not in a:
                raise err(f, f"missing required key {k!r}")
        own = _MACHINE_AXIS[ROTARY_MACHINE_AXIS[n]]
        d = a["direction"]
        if d not in (f"+{own}", f"-{own}"):
            raise err(f"{f}.direction", f"expected \"+{own}\" or \"-{own}\" ({n} turns about "
                      f"{own}), got {show_value(d)}")
        pivot = _vec3(a["pivot_mm"], f"{f}.pivot_mm", num, err)
        tr = a["travel_deg"]
        if not isinstance(tr, list) or len(tr) != 2:
            raise err(f"{f}.travel_deg", f"expected [min, max] in degrees, got {show_value(tr)}")
        lo, hi = (num(x, f"{f}.travel_deg", *ANGLE_RANGE_DEG, "deg") for x in tr)
        if not lo < hi:
            raise err(f"{f}.travel_deg", f"expected min < max, got [{lo}, {hi}] deg")
        axes.append(ChainAxis(n, 1 if d[0] == "+" else -1, pivot, (lo, hi)))
    return KinematicChain(name or "-".join(order), tuple(axes), tool, ref)


def _vec3(v: Any, f: str, num: Callable[..., float],
          err: Callable[[str, str], AbbeInputError]) -> tuple[float, float, float]:
    if not isinstance(v, list) or len(v) != 3:
        raise err(f, f"expected an array of 3 numbers (mm), got {show_value(v)}")
    x, y, z = (num(c, f, *PIVOT_RANGE_MM, "mm") for c in v)
    return (x, y, z)


def chain_toml(chain: KinematicChain) -> str:
    """The ``[chain]`` text of a chain (what :func:`parse_chain` reads back)."""
    lines = ["[chain]", f'name = "{chain.name}"',
             "order = [" + ", ".join(f'"{a.name}"' for a in chain.axes) + "]",
             f"tool_length_mm = {chain.tool_length_mm!r}",
             f"reference_mm = {[float(v) for v in chain.reference_mm]!r}"]
    for a in chain.axes:
        if not a.rotary:
            continue
        own = _MACHINE_AXIS[ROTARY_MACHINE_AXIS[a.name]]
        lines += [f"[chain.{a.name}]", f'direction = "{"+" if a.direction > 0 else "-"}{own}"',
                  f"pivot_mm = {[float(v) for v in a.pivot_mm]!r}",
                  f"travel_deg = {[float(v) for v in a.travel]!r}"]
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------- measurement sections


@dataclass(frozen=True)
class ChainProbing:
    """``[probing.N]`` of a ``[chain]`` machine: the probing CSV (resolved; angle columns
    the chain's rotary axes in alphabetical order), the sphere's nominal centre
    (workpiece coordinates, mm), its radius and the stylus radius (mm), the radius check
    tolerance (mm), the stylus tip relative to the controlled point at zero angles (mm)."""

    name: str
    file: Path
    sphere_mm: tuple[float, float, float]
    sphere_radius_mm: float
    stylus_radius_mm: float
    radius_tolerance_mm: float
    tip_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    line: int | None = None


@dataclass(frozen=True)
class ChainRTest:
    """``[rtest.N]`` of a ``[chain]`` machine: the R-test CSV (resolved), the sphere's
    nominal centre (mm), the nest relative to the controlled point at zero angles (mm)."""

    name: str
    file: Path
    sphere_mm: tuple[float, float, float]
    tip_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    line: int | None = None


@dataclass(frozen=True)
class ChainBallbar:
    """``[rotary_ballbar.N]`` of a ``[chain]`` machine: the rotary ballbar CSV (resolved;
    angle columns the chain's rotary axes in alphabetical order), the table ball's and the
    tool ball's nominal centres (workpiece coordinates, mm; the tool ball is held there
    under tool-centre-point control), the tool ball relative to the controlled point at
    zero angles (mm: a tool-side rotary axis swings it with the spindle), the set-up the
    test shares with others (same table ball, same tool cup: one set of ball unknowns)."""

    name: str
    file: Path
    table_ball_mm: tuple[float, float, float]
    tool_ball_mm: tuple[float, float, float]
    tip_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    setup: str = ""
    line: int | None = None

    @property
    def length_mm(self) -> float:
        return float(sum((a - b) ** 2 for a, b in zip(self.tool_ball_mm,
                                                       self.table_ball_mm)) ** 0.5)


@dataclass(frozen=True)
class ChainPlans:
    """The measurement sections of a ``[chain]`` machine file and ``[chain.fit]``: the
    error motions' highest harmonic the fit identifies (0: location errors only) and the
    held-out folds of ``abbe diagnose``."""

    probing: dict[str, ChainProbing] = field(default_factory=dict)
    rtest: dict[str, ChainRTest] = field(default_factory=dict)
    harmonics: int = 0
    folds: int = 4
    ballbar: dict[str, ChainBallbar] = field(default_factory=dict)


_FIT_KEYS = ("harmonics", "folds")


def _chain_fit(data: dict[str, Any], err: Callable[[str, str], AbbeInputError]
               ) -> tuple[int, int]:
    """(harmonics, folds) of ``[chain.fit]`` (0, 4 without it)."""
    sec = data.get("chain", {}).get("fit")
    if sec is None:
        return 0, 4
    f = "chain.fit"
    if not isinstance(sec, dict):
        raise err(f, f"expected a table [chain.fit], got {show_value(sec)}")
    for k in sec:
        if k not in _FIT_KEYS:
            raise err(f"{f}.{k}", unknown_key(k, _FIT_KEYS))
    h = sec.get("harmonics", 0)
    if isinstance(h, bool) or not isinstance(h, int) or not 0 <= h <= HARMONICS_MAX:
        raise err(f"{f}.harmonics", f"expected an integer in [0, {HARMONICS_MAX}] (error "
                  f"motions up to that harmonic; 0 = location errors only), got {show_value(h)}")
    folds = sec.get("folds", 4)
    if isinstance(folds, bool) or not isinstance(folds, int) or not 2 <= folds <= 20:
        raise err(f"{f}.folds", f"expected an integer in [2, 20], got {show_value(folds)}")
    return h, folds


_PROBING_KEYS = ("file", "sphere_mm", "sphere_radius_mm", "stylus_radius_mm",
                 "radius_tolerance_mm", "tip_mm")
_RTEST_KEYS = ("file", "sphere_mm", "tip_mm")
_BALLBAR_KEYS = ("file", "table_ball_mm", "tool_ball_mm", "tip_mm", "setup")


def parse_chain_plans(data: dict[str, Any], err: Callable[[str, str], AbbeInputError],
                      line: Callable[[str], int | None], file: str,
                      resolve: Callable[[str, str], Path]) -> ChainPlans:
    """The ``[probing.N]``, ``[rtest.N]`` and ``[rotary_ballbar.N]`` sections of a
    ``[chain]`` machine file (``[indexer]`` is the trunnions' only, for now)."""
    def num(v: Any, f: str, lo: float, hi: float, unit: str) -> float:
        return check_number(v, file=file, line=line(f), field=f, lo=lo, hi=hi, unit=unit)

    if "indexer" in data:
        raise err("indexer", "[indexer] is read for a [rotary] trunnion only; a [chain] machine "
                             "takes [probing.NAME], [rtest.NAME] and [rotary_ballbar.NAME]")

    def sections(top: str, keys: tuple[str, ...], required: tuple[str, ...]
                 ) -> dict[str, tuple[str, dict[str, Any]]]:
        t = data.get(top, {})
        if not isinstance(t, dict):
            raise err(top, f"expected a table [{top}.NAME], got {show_value(t)}")
        out = {}
        for name, sec in t.items():
            f = f"{top}.{name}"
            if not isinstance(sec, dict):
                raise err(f, f"expected a table [{f}], got {show_value(sec)}")
            for k in sec:
                if k not in keys:
                    raise err(f"{f}.{k}", unknown_key(k, keys))
            for k in required:
                if k not in sec:
                    raise err(f, f"missing required key {k!r}")
            if not isinstance(sec["file"], str) or not sec["file"].strip():
                raise err(f"{f}.file", f"expected a file name, got {show_value(sec['file'])}")
            out[name] = (f, sec)
        return out

    probing = {}
    for name, (f, sec) in sections("probing", _PROBING_KEYS,
                                   ("file", "sphere_mm", "sphere_radius_mm")).items():
        probing[name] = ChainProbing(
            name, resolve(sec["file"], f"{f}.file"), _vec3(sec["sphere_mm"], f"{f}.sphere_mm", num, err),
            num(sec["sphere_radius_mm"], f"{f}.sphere_radius_mm", *SPHERE_RADIUS_RANGE_MM, "mm"),
            num(sec.get("stylus_radius_mm", 0.0), f"{f}.stylus_radius_mm",
                *STYLUS_RADIUS_RANGE_MM, "mm"),
            num(sec.get("radius_tolerance_mm", 0.02), f"{f}.radius_tolerance_mm",
                *RADIUS_TOL_RANGE_MM, "mm"),
            _vec3(sec.get("tip_mm", [0.0, 0.0, 0.0]), f"{f}.tip_mm", num, err), line(f))
    rtest = {}
    for name, (f, sec) in sections("rtest", _RTEST_KEYS, ("file", "sphere_mm")).items():
        rtest[name] = ChainRTest(name, resolve(sec["file"], f"{f}.file"),
                                 _vec3(sec["sphere_mm"], f"{f}.sphere_mm", num, err),
                                 _vec3(sec.get("tip_mm", [0.0, 0.0, 0.0]), f"{f}.tip_mm", num, err),
                                 line(f))
    ballbar: dict[str, ChainBallbar] = {}
    for name, (f, sec) in sections("rotary_ballbar", _BALLBAR_KEYS,
                                   ("file", "table_ball_mm", "tool_ball_mm")).items():
        su = sec.get("setup", "")
        if not isinstance(su, str) or (su != "" and not su.replace("_", "").replace(
                "-", "").isalnum()):
            raise err(f"{f}.setup", f"expected a set-up name (letters, digits, _ or -), got "
                      f"{show_value(su)}")
        bb = ChainBallbar(name, resolve(sec["file"], f"{f}.file"),
                          _vec3(sec["table_ball_mm"], f"{f}.table_ball_mm", num, err),
                          _vec3(sec["tool_ball_mm"], f"{f}.tool_ball_mm", num, err),
                          _vec3(sec.get("tip_mm", [0.0, 0.0, 0.0]), f"{f}.tip_mm", num, err),
                          su, line(f))
        lo, hi = BAR_LENGTH_RANGE_MM
        if not lo <= bb.length_mm <= hi:
            raise err(f"{f}.tool_ball_mm", f"expected the balls {lo:g} to {hi:g} mm apart (the "
                      f"bar's length), got {bb.length_mm:.6g} mm")
        same = [o for o in ballbar.values() if su and o.setup == su]
        if same and (same[0].table_ball_mm != bb.table_ball_mm or same[0].tip_mm != bb.tip_mm):
            raise err(f"{f}.table_ball_mm", f"set-up {su!r} shares one table ball and one tool "
                      f"cup: expected table_ball_mm {list(same[0].table_ball_mm)} and tip_mm "
                      f"{list(same[0].tip_mm)} as [rotary_ballbar.{same[0].name}], got "
                      f"{list(bb.table_ball_mm)} and {list(bb.tip_mm)}")
        ballbar[name] = bb
    harmonics, folds = _chain_fit(data, err)
    return ChainPlans(probing, rtest, harmonics, folds, ballbar)
