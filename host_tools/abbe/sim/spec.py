"""The simulation spec (``abbe simulate SPEC.toml``): a virtual machine and its test campaign.

Documented in docs/formats.md, "Ballbar and simulation". Sections:

``[machine]`` name, description, seed, travel_mm {X, Y, Z}, reference_mm, tool_offset_mm;
``[errors.X|Y|Z]`` wave_period_mm and one inline table per term (dx dy dz ex ey ez)
with shape keys (abbe.sim.truth); ``[effects.*]`` squareness, backlash, cyclic, thermal,
servo, scale_change, tool_offset (each with ``enabled``, default true);
``[noise]``; ``[campaign]`` gap_s; ``[laser.X|Y|Z]`` one 6D laser line per axis;
``[ballbar.NAME]`` circular tests.

Every key is checked: unknown keys, wrong types and impossible magnitudes raise
AbbeInputError naming the file, the line and the dotted field.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from abbe.errors import AbbeInputError
from abbe.errors.numbers import show_value
from abbe.formats.limits import SPEC_FILE_MAX_BYTES
from abbe.formats.structured import load_toml, unknown_key
from abbe.formats.machine import (
    CHANNELS,
    DEFAULT_MAPS,
    KeyLocator,  # shared best-effort key -> line locator
)
from abbe.model.geometry import PLANES, CircleTest, check_test_in_travel
from abbe.model.table import ANGULAR_TERMS, AXES, LINEAR_TERMS, OWN_TERM, TERMS
from abbe.sim.truth import Effects, MachineTruth, build_axis, is_straightness

OWN_ROTATION = {"X": "ex", "Y": "ey", "Z": "ez"}
_MAP_RE = re.compile(r"^([+-])(dx|dy|dz|ex|ey|ez)$")

# Limits of "possible" magnitudes (beyond them the spec is refused).
#: Most targets of a simulated laser line (spacing_mm >= length / this).
SIM_MAX_TARGETS = 10_000
MAX_LINEAR_UM = 1000.0
MAX_ANGULAR_URAD = 2000.0
MAX_SLOPE_PER_M = 1000.0


@dataclass
class NoiseSpec:
    """Measurement noise (1 sigma): laser channels (um / urad), ballbar (um),
    positioning repeatability per visit of a laser target (um, per axis),
    temperature sensor (K)."""

    laser_linear_um: float = 0.0
    laser_straightness_um: float = 0.0
    laser_angle_urad: float = 0.0
    ballbar_um: float = 0.0
    repeatability_um: tuple[float, float, float] = (0.0, 0.0, 0.0)
    temp_sensor_k: float = 0.0


@dataclass
class LaserLinePlan:
    """One 6D laser line: along ``axis`` from start_mm to end_mm (machine coordinates),
    targets every spacing_mm (from the lower end; the upper end is always a target),
    ``runs`` bidirectional runs at feed_mm_min with dwell_s per target and overrun_mm
    beyond the end targets before each reversal; instrument map channel -> "+term";
    misalignment_urad = (h, v) tilt of the beam toward the straightness directions."""

    axis: str
    file: str
    start_mm: tuple[float, float, float]
    end_mm: tuple[float, float, float]
    spacing_mm: float = 10.0
    runs: int = 5
    feed_mm_min: float = 200.0
    dwell_s: float = 3.0
    overrun_mm: float = 2.0
    map: dict[str, str] = field(default_factory=dict)
    misalignment_urad: tuple[float, float] = (0.0, 0.0)

    @property
    def j(self) -> int:
        return AXES.index(self.axis)

    def targets_mm(self) -> np.ndarray:
        """Target positions on the line's axis, ascending (mm)."""
        lo, hi = sorted((self.start_mm[self.j], self.end_mm[self.j]))
        n = int(math.floor((hi - lo) / self.spacing_mm + 1e-9))
        t = lo + self.spacing_mm * np.arange(n + 1)
        if hi - t[-1] > 1e-6:
            t = np.append(t, hi)
        return t

    def parsed_map(self) -> dict[str, tuple[int, str]]:
        """channel -> (sign, term)."""
        out = {}
        for ch, s in self.map.items():
            m = _MAP_RE.match(s)
            assert m is not None
            out[ch] = (1 if m.group(1) == "+" else -1, m.group(2))
        return out


@dataclass
class SimSpec:
    """A parsed, validated simulation spec (units mm, um, urad, s, deg C)."""

    path: Path
    name: str
    description: str
    seed: int
    travel_mm: dict[str, tuple[float, float]]
    reference_mm: tuple[float, float, float]
    tool_offset_mm: tuple[float, float, float]
    shapes: dict[str, dict[str, dict[str, Any]]]
    wave_period_mm: dict[str, float | None]
    effects: Effects
    noise: NoiseSpec
    gap_s: float
    laser: dict[str, LaserLinePlan]
    ballbar: dict[str, CircleTest]

    def truth(self) -> MachineTruth:
        """The virtual machine's ground truth."""
        e = self.effects
        axes = {}
        for j, a in enumerate(AXES):
            axes[a] = build_axis(a, self.travel_mm[a], self.reference_mm[j], self.shapes[a],
                                 self.wave_period_mm[a], cyclic_um=e.cyclic_um[j],
                                 cyclic_period_mm=e.cyclic_period_mm[j],
                                 cyclic_phase_deg=e.cyclic_phase_deg[j])
        return MachineTruth(name=self.name, seed=self.seed, reference_mm=self.reference_mm,
                            tool_offset_mm=self.tool_offset_mm, axes=axes, effects=e)


# --------------------------------------------------------------------------- reader

_REQ = object()


def _finite(v: Any) -> bool:
    """A TOML number that is finite and fits a double (a 400-digit integer does not)."""
    if isinstance(v, float):
        return math.isfinite(v)
    return abs(v) <= 1e300


class _Reader:
    """Typed access to TOML tables with file/line/field errors."""

    def __init__(self, path: Path, text: str) -> None:
        self.path = path
        self.loc = KeyLocator(text)

    def err(self, dotted: str, msg: str) -> AbbeInputError:
        return AbbeInputError(msg, file=str(self.path), line=self.loc.line(dotted), field=dotted)

    def table(self, d: Any, dotted: str, allowed: tuple[str, ...] | None) -> dict[str, Any]:
        if not isinstance(d, dict):
            raise self.err(dotted, f"expected a table, got {show_value(d)}")
        if allowed is not None:
            for k in d:
                if k not in allowed:
                    raise self.err(f"{dotted}.{k}" if dotted else k,
                                   unknown_key(k, allowed, "key" if dotted else "section"))
        return d

    def num(self, d: dict, key: str, dotted: str, default: Any = _REQ, lo: float | None = None,
            hi: float | None = None, lo_open: bool = False, unit: str = "") -> float:
        f = f"{dotted}.{key}"
        if key not in d:
            if default is _REQ:
                raise self.err(dotted, f"missing required key {key!r}")
            return default
        v = d[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not _finite(v):
            raise self.err(f, f"expected a finite number{' (' + unit + ')' if unit else ''}, got {show_value(v)}")
        x = float(v)
        self._range(f, x, lo, hi, lo_open, unit)
        return x

    def _range(self, f: str, x: float, lo: float | None, hi: float | None, lo_open: bool,
               unit: str) -> None:
        u = f" {unit}" if unit else ""
        if lo is not None and (x < lo or (lo_open and x <= lo)):
            raise self.err(f, f"impossible value {x:g}{u}: must be {'>' if lo_open else '>='} {lo:g}{u}")
        if hi is not None and x > hi:
            raise self.err(f, f"impossible value {x:g}{u}: must be <= {hi:g}{u}")

    def vec(self, d: dict, key: str, dotted: str, n: int, default: Any = _REQ,
            lo: float | None = None, hi: float | None = None, lo_open: bool = False,
            unit: str = "", absolute: bool = False) -> tuple[float, ...]:
        f = f"{dotted}.{key}"
        if key not in d:
            if default is _REQ:
                raise self.err(dotted, f"missing required key {key!r}")
            return tuple(default)
        v = d[key]
        if not isinstance(v, list) or len(v) != n or any(
                isinstance(x, bool) or not isinstance(x, (int, float)) or not _finite(x)
                for x in v):
            raise self.err(f, f"expected an array of {n} finite numbers{' (' + unit + ')' if unit else ''}, got {show_value(v)}")
        out = tuple(float(x) for x in v)
        for x in out:
            self._range(f, abs(x) if absolute else x, lo, hi, lo_open, unit)
        return out

    def int_(self, d: dict, key: str, dotted: str, default: Any, lo: int, hi: int) -> int:
        f = f"{dotted}.{key}"
        if key not in d:
            return default
        v = d[key]
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise self.err(f, f"expected an integer in [{lo}, {hi}], got {show_value(v)}")
        return int(v)

    def str_(self, d: dict, key: str, dotted: str, default: Any = _REQ,
             choices: tuple[str, ...] | None = None) -> str:
        f = f"{dotted}.{key}"
        if key not in d:
            if default is _REQ:
                raise self.err(dotted, f"missing required key {key!r}")
            return default
        v = d[key]
        if not isinstance(v, str):
            raise self.err(f, f"expected a string, got {show_value(v)}")
        if choices is not None and v not in choices:
            raise self.err(f, f"expected one of {', '.join(choices)}, got {show_value(v)}")
        return v

    def bool_(self, d: dict, key: str, dotted: str, default: bool) -> bool:
        if key not in d:
            return default
        v = d[key]
        if not isinstance(v, bool):
            raise self.err(f"{dotted}.{key}", f"expected true or false, got {show_value(v)}")
        return v


# --------------------------------------------------------------------------- sections

_TOP = ("machine", "errors", "effects", "noise", "campaign", "laser", "ballbar")
_EFFECTS = ("squareness", "backlash", "cyclic", "thermal", "servo", "scale_change", "tool_offset")


def _shape(r: _Reader, d: Any, f: str, axis: str, term: str) -> dict[str, Any]:
    linear = term in LINEAR_TERMS
    unit = "um" if linear else "urad"
    allowed = (f"slope_{unit}_per_m", f"bow_{unit}", f"cantilever_{unit}", f"wave_{unit}",
               "wave_phase_deg", "cantilever_end")
    d = r.table(d, f, allowed)
    out: dict[str, Any] = {}
    cap = MAX_LINEAR_UM if linear else MAX_ANGULAR_URAD
    k = f"slope_{unit}_per_m"
    if k in d:
        if is_straightness(axis, term):
            raise r.err(f"{f}.{k}", "a straightness slope is a squareness (or set-up "
                        "misalignment): use [effects.squareness]")
        out[k] = r.num(d, k, f, lo=-MAX_SLOPE_PER_M, hi=MAX_SLOPE_PER_M, unit=f"{unit}/m")
    for k in (f"bow_{unit}", f"cantilever_{unit}"):
        if k in d:
            out[k] = r.num(d, k, f, lo=-cap, hi=cap, unit=unit)
    if "cantilever_end" in d:
        out["cantilever_end"] = r.str_(d, "cantilever_end", f, choices=("min", "max"))
    k = f"wave_{unit}"
    if k in d:
        w = d[k]
        if not isinstance(w, list) or not 1 <= len(w) <= 8:
            raise r.err(f"{f}.{k}", f"expected a list of 1..8 harmonic amplitudes ({unit}), got {w!r}")
        out[k] = list(r.vec(d, k, f, len(w), lo=0.0, hi=cap, unit=unit))
        ph = r.vec(d, "wave_phase_deg", f, len(w), default=[0.0] * len(w), lo=-360.0, hi=360.0,
                   unit="deg")
        out["wave_phase_deg"] = list(ph)
    elif "wave_phase_deg" in d:
        raise r.err(f"{f}.wave_phase_deg", f"wave_phase_deg without wave_{unit}")
    return out


def _effects(r: _Reader, raw: Any) -> Effects:
    d = r.table(raw, "effects", _EFFECTS)
    e = Effects()
    kw: dict[str, Any] = {}

    def sec(name: str, keys: tuple[str, ...]) -> tuple[dict[str, Any], bool] | None:
        if name not in d:
            return None
        s = r.table(d[name], f"effects.{name}", ("enabled",) + keys)
        return s, r.bool_(s, "enabled", f"effects.{name}", True)

    got = sec("squareness", ("xy_urad", "xz_urad", "yz_urad"))
    if got:
        s, on = got
        f = "effects.squareness"
        v = tuple(r.num(s, k, f, 0.0, lo=-1000.0, hi=1000.0, unit="urad")
                  for k in ("xy_urad", "xz_urad", "yz_urad"))
        if on:
            kw["squareness_urad"] = v
    got = sec("backlash", ("lost_motion_um", "takeup_mm"))
    if got:
        s, on = got
        f = "effects.backlash"
        b = r.vec(s, "lost_motion_um", f, 3, lo=0.0, hi=500.0, unit="um")
        tk = r.vec(s, "takeup_mm", f, 3, (0.1, 0.1, 0.1), lo=0.001, hi=50.0, unit="mm")
        if on:
            kw["backlash_um"] = b
        kw["backlash_takeup_mm"] = tk
    got = sec("cyclic", ("amplitude_um", "period_mm", "phase_deg"))
    if got:
        s, on = got
        f = "effects.cyclic"
        a = r.vec(s, "amplitude_um", f, 3, lo=0.0, hi=50.0, unit="um")
        p = r.vec(s, "period_mm", f, 3, lo=0.1, hi=1000.0, unit="mm")
        ph = r.vec(s, "phase_deg", f, 3, (0.0, 0.0, 0.0), lo=-360.0, hi=360.0, unit="deg")
        if on:
            kw["cyclic_um"] = a
        kw["cyclic_period_mm"] = p
        kw["cyclic_phase_deg"] = ph
    got = sec("thermal", ("start_c", "rise_k", "time_constant_s", "expansion_ppm_per_k",
                          "offset_um_per_k"))
    if got:
        s, on = got
        f = "effects.thermal"
        kw["thermal_start_c"] = r.num(s, "start_c", f, 20.0, lo=-20.0, hi=60.0, unit="deg C")
        rise = r.num(s, "rise_k", f, lo=-30.0, hi=30.0, unit="K")
        kw["thermal_time_constant_s"] = r.num(s, "time_constant_s", f, 3600.0, lo=1.0, hi=1e6,
                                              unit="s")
        kw["thermal_expansion_ppm_per_k"] = r.vec(s, "expansion_ppm_per_k", f, 3, (0.0,) * 3,
                                                  hi=50.0, unit="ppm/K", absolute=True)
        kw["thermal_offset_um_per_k"] = r.vec(s, "offset_um_per_k", f, 3, (0.0,) * 3, hi=100.0,
                                              unit="um/K", absolute=True)
        if on:
            kw["thermal_rise_k"] = rise
    got = sec("servo", ("lag_ms",))
    if got:
        s, on = got
        v = r.vec(s, "lag_ms", "effects.servo", 3, lo=0.0, hi=1000.0, unit="ms")
        if on:
            kw["servo_lag_ms"] = v
    got = sec("scale_change", ("ppm", "from_time_s"))
    if got:
        s, on = got
        f = "effects.scale_change"
        v = r.vec(s, "ppm", f, 3, hi=1000.0, unit="ppm", absolute=True)
        kw["scale_change_from_s"] = r.num(s, "from_time_s", f, 0.0, lo=0.0, hi=1e7, unit="s")
        if on:
            kw["scale_change_ppm"] = v
    got = sec("tool_offset", ("offset_mm",))
    if got:
        s, on = got
        v = r.vec(s, "offset_mm", "effects.tool_offset", 3, hi=1000.0, unit="mm", absolute=True)
        if on:
            kw["tool_offset_mm"] = v
    for k, v in kw.items():
        setattr(e, k, v)
    return e


def _laser(r: _Reader, name: str, raw: Any, travel: dict[str, tuple[float, float]]) -> LaserLinePlan:
    f = f"laser.{name}"
    if name not in AXES:
        raise r.err(f, f"a laser line is named after its axis ({', '.join(AXES)})")
    d = r.table(raw, f, ("file", "start_mm", "end_mm", "spacing_mm", "runs", "feed_mm_min",
                         "dwell_s", "overrun_mm", "map", "misalignment_urad"))
    j = AXES.index(name)
    start = r.vec(d, "start_mm", f, 3, unit="mm")
    end = r.vec(d, "end_mm", f, 3, unit="mm")
    for k in range(3):
        if k != j and abs(start[k] - end[k]) > 1e-6:
            raise r.err(f"{f}.end_mm", f"a line along {name} keeps {AXES[k].lower()} constant "
                        f"(start {start[k]:g}, end {end[k]:g} mm)")
    length = abs(end[j] - start[j])
    if length < 1e-6:
        raise r.err(f"{f}.end_mm", "start and end coincide on the line's axis")
    for key, pt in (("start_mm", start), ("end_mm", end)):
        for k, ax in enumerate(AXES):
            lo, hi = travel[ax]
            if not lo - 1e-6 <= pt[k] <= hi + 1e-6:
                raise r.err(f"{f}.{key}", f"{ax.lower()} = {pt[k]:g} mm is outside the travel "
                            f"[{lo:g}, {hi:g}] mm")
    # at most SIM_MAX_TARGETS targets per line: memory and time stay bounded
    spacing = r.num(d, "spacing_mm", f, 10.0, lo=max(length / SIM_MAX_TARGETS, 1e-3), hi=length,
                    unit="mm")
    runs = r.int_(d, "runs", f, 5, 1, 20)
    feed = r.num(d, "feed_mm_min", f, 200.0, lo=1.0, hi=60000.0, unit="mm/min")
    dwell = r.num(d, "dwell_s", f, 3.0, lo=0.0, hi=600.0, unit="s")
    over = r.num(d, "overrun_mm", f, 2.0, lo=0.0, hi=50.0, unit="mm")
    mis = r.vec(d, "misalignment_urad", f, 2, (0.0, 0.0), hi=5000.0, unit="urad", absolute=True)
    mp = dict(DEFAULT_MAPS[name])
    if "map" in d:
        md = r.table(d["map"], f"{f}.map", CHANNELS)
        for ch in CHANNELS:
            if ch not in md:
                raise r.err(f"{f}.map", f"missing channel {ch!r} (all six are simulated)")
        mp = {}
        for ch in CHANNELS:
            v = md[ch]
            m = _MAP_RE.match(v) if isinstance(v, str) else None
            if not m:
                raise r.err(f"{f}.map.{ch}", f"expected \"+term\" or \"-term\" (term one of "
                            f"{', '.join(TERMS)}), got {show_value(v)}")
            mp[ch] = v
        terms = {ch: mp[ch][1:] for ch in CHANNELS}
        if terms["linear"] != OWN_TERM[name]:
            raise r.err(f"{f}.map.linear", f"the linear channel measures {OWN_TERM[name]} on a "
                        f"{name} line")
        if terms["roll"] != OWN_ROTATION[name]:
            raise r.err(f"{f}.map.roll", f"roll is the rotation about the line: "
                        f"{OWN_ROTATION[name]} on a {name} line")
        for ch in ("straight_h", "straight_v"):
            if terms[ch] not in LINEAR_TERMS or terms[ch] == OWN_TERM[name]:
                raise r.err(f"{f}.map.{ch}", "a straightness channel measures one of the two "
                            f"transverse linear terms of {name}")
        for ch in ("pitch", "yaw"):
            if terms[ch] not in ANGULAR_TERMS or terms[ch] == OWN_ROTATION[name]:
                raise r.err(f"{f}.map.{ch}", "pitch/yaw measure the two transverse rotations "
                            f"of {name}")
        if len(set(terms.values())) != 6:
            raise r.err(f"{f}.map", "every term must be mapped exactly once")
    fname = r.str_(d, "file", f, f"laser/{name.lower()}.csv")
    return LaserLinePlan(axis=name, file=fname, start_mm=start, end_mm=end,  # type: ignore[arg-type]
                         spacing_mm=spacing, runs=runs, feed_mm_min=feed, dwell_s=dwell,
                         overrun_mm=over, map=mp, misalignment_urad=mis)  # type: ignore[arg-type]


def _ballbar(r: _Reader, name: str, raw: Any, travel: dict[str, tuple[float, float]]) -> CircleTest:
    f = f"ballbar.{name}"
    if not re.match(r"^[A-Za-z0-9_\-]+$", name):
        raise r.err(f, "test names use letters, digits, '_' and '-' only")
    d = r.table(raw, f, ("file", "plane", "center_mm", "radius_mm", "feed_mm_min", "sample_deg",
                         "feed_arc_deg", "pause_s", "setup_offset_um"))
    t = CircleTest(
        name=name,
        plane=r.str_(d, "plane", f, choices=PLANES),
        center_mm=r.vec(d, "center_mm", f, 3, unit="mm"),  # type: ignore[arg-type]
        radius_mm=r.num(d, "radius_mm", f, lo=1.0, hi=2000.0, unit="mm"),
        feed_mm_min=r.num(d, "feed_mm_min", f, lo=1.0, hi=60000.0, unit="mm/min"),
        sample_deg=r.num(d, "sample_deg", f, 0.5, lo=0.01, hi=5.0, unit="deg"),
        feed_arc_deg=r.num(d, "feed_arc_deg", f, 45.0, lo=0.0, hi=180.0, unit="deg"),
        pause_s=r.num(d, "pause_s", f, 2.0, lo=0.0, hi=3600.0, unit="s"),
        setup_offset_um=r.vec(d, "setup_offset_um", f, 3, (0.0, 0.0, 0.0), hi=1000.0,  # type: ignore[arg-type]
                              unit="um", absolute=True),
        file=r.str_(d, "file", f, f"ballbar/{name}.csv"),
    )
    try:
        check_test_in_travel(t, travel, file=str(r.path))
    except AbbeInputError as exc:
        exc.line = r.loc.line(exc.field or f)
        raise AbbeInputError(exc.message, file=exc.file, line=exc.line, field=exc.field) from None
    return t


def load_spec(path: str | Path) -> SimSpec:
    """Read and validate a simulation spec (TOML). Raises AbbeInputError(file, line, field)."""
    path = Path(path)
    data, tf = load_toml(path, what="simulation spec", max_bytes=SPEC_FILE_MAX_BYTES)
    r = _Reader(path, tf.text)
    r.table(data, "", _TOP)
    if "machine" not in data:
        raise AbbeInputError("missing [machine] section", file=str(path), field="machine")
    md = r.table(data["machine"], "machine", ("name", "description", "seed", "travel_mm",
                                              "reference_mm", "tool_offset_mm"))
    name = r.str_(md, "name", "machine")
    if not re.match(r"^[A-Za-z0-9_.\-]+$", name):
        raise r.err("machine.name", "use letters, digits, '.', '_' and '-' only")
    desc = r.str_(md, "description", "machine", "")
    seed = r.int_(md, "seed", "machine", None, 0, 2**63 - 1)
    if seed is None:
        raise r.err("machine", "missing required key 'seed' (an integer >= 0)")
    if "travel_mm" not in md:
        raise r.err("machine", "missing required key 'travel_mm' ({ X = [min, max], ... })")
    td = r.table(md["travel_mm"], "machine.travel_mm", AXES)
    travel: dict[str, tuple[float, float]] = {}
    for a in AXES:
        lo, hi = r.vec(td, a, "machine.travel_mm", 2, lo=-2147.0, hi=2147.0, unit="mm")
        if not lo < hi:
            raise r.err(f"machine.travel_mm.{a}", f"expected [min, max] with min < max, got [{lo:g}, {hi:g}]")
        travel[a] = (lo, hi)
    ref = r.vec(md, "reference_mm", "machine", 3, unit="mm")
    for k, a in enumerate(AXES):
        lo, hi = travel[a]
        if not lo <= ref[k] <= hi:
            raise r.err("machine.reference_mm", f"{a.lower()} = {ref[k]:g} mm is outside the "
                        f"travel [{lo:g}, {hi:g}] mm")
    tool = r.vec(md, "tool_offset_mm", "machine", 3, (0.0, 0.0, 0.0), hi=1000.0, unit="mm",
                 absolute=True)

    shapes: dict[str, dict[str, dict[str, Any]]] = {a: {} for a in AXES}
    wave: dict[str, float | None] = {a: None for a in AXES}
    ed = r.table(data.get("errors", {}), "errors", AXES)
    for a in AXES:
        if a not in ed:
            continue
        f = f"errors.{a}"
        ad = r.table(ed[a], f, ("wave_period_mm",) + TERMS)
        lo, hi = travel[a]
        if "wave_period_mm" in ad:
            wave[a] = r.num(ad, "wave_period_mm", f, lo=1.0, hi=100.0 * (hi - lo),
                            unit="mm")
        for t in TERMS:
            if t in ad:
                shapes[a][t] = _shape(r, ad[t], f"{f}.{t}", a, t)

    effects = _effects(r, data.get("effects", {}))
    nd = r.table(data.get("noise", {}), "noise", ("laser_linear_um", "laser_straightness_um",
                                                  "laser_angle_urad", "ballbar_um",
                                                  "repeatability_um", "temp_sensor_k"))
    noise = NoiseSpec(
        laser_linear_um=r.num(nd, "laser_linear_um", "noise", 0.0, lo=0.0, hi=100.0, unit="um"),
        laser_straightness_um=r.num(nd, "laser_straightness_um", "noise", 0.0, lo=0.0, hi=100.0,
                                    unit="um"),
        laser_angle_urad=r.num(nd, "laser_angle_urad", "noise", 0.0, lo=0.0, hi=100.0, unit="urad"),
        ballbar_um=r.num(nd, "ballbar_um", "noise", 0.0, lo=0.0, hi=100.0, unit="um"),
        repeatability_um=r.vec(nd, "repeatability_um", "noise", 3, (0.0, 0.0, 0.0), lo=0.0,  # type: ignore[arg-type]
                               hi=100.0, unit="um"),
        temp_sensor_k=r.num(nd, "temp_sensor_k", "noise", 0.0, lo=0.0, hi=5.0, unit="K"),
    )
    cd = r.table(data.get("campaign", {}), "campaign", ("gap_s",))
    gap = r.num(cd, "gap_s", "campaign", 600.0, lo=0.0, hi=1e6, unit="s")

    laser = {n: _laser(r, n, v, travel)
             for n, v in r.table(data.get("laser", {}), "laser", None).items()}
    ballbar = {n: _ballbar(r, n, v, travel)
               for n, v in r.table(data.get("ballbar", {}), "ballbar", None).items()}
    files: dict[str, str] = {}
    for kind, items in (("laser", laser), ("ballbar", ballbar)):
        for n, it in items.items():
            fn = it.file
            if (fn.startswith("/") or ".." in Path(fn).parts or not fn.endswith(".csv")
                    or fn.startswith("truth/")):
                raise r.err(f"{kind}.{n}.file", "expected a relative path ending in .csv inside "
                            "the output directory (not under truth/)")
            if fn in files:
                raise r.err(f"{kind}.{n}.file", f"file {fn!r} is already used by {files[fn]}")
            files[fn] = f"{kind}.{n}"
    return SimSpec(path=path, name=name, description=desc, seed=seed, travel_mm=travel,
                   reference_mm=ref, tool_offset_mm=tool, shapes=shapes,  # type: ignore[arg-type]
                   wave_period_mm=wave, effects=effects, noise=noise, gap_s=gap, laser=laser,
                   ballbar=ballbar)
