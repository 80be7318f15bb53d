"""The machine file's ``[thermal]`` section: the thermal record, its sensors and channels.

::

    [thermal]
    record = "data.xlsx"          # CSV or .xlsx, relative to the machine file
    sheet = "Sheet1"              # optional, .xlsx only
    identify_hours = [0.0, 24.0]  # identification (and selection) window, h
    validate_hours = [24.0, 46.0] # held-out window, h (must not overlap)
    cycle_hours = 8.0             # one speed step on + off: the cross-validation folds
    tool_z_mm = 100.0             # optional: the tool offset the tilts move the tip by
    note = "..."                  # optional: what the record's source does not document

    [thermal.sensors]             # every temperature: where it sits (free text)
    t1 = "spindle front bearing"

    [thermal.channels.ch1]        # every displacement channel (ISO 230-3 five-sensor nest)
    direction = "x"               # x | y | z: the displacement it reads, um
    nest_z_mm = 0.0               # its height on the test mandrel along the spindle axis, mm

Two channels of the same direction x or y at different heights form a pair: their
difference over the spacing is a tilt (about Y for x, about X for y, urad). Errors name
the machine file, the key's line and the dotted field.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from abbe.errors import AbbeInputError, check_number
from abbe.formats.structured import unknown_key

DIRECTIONS = ("x", "y", "z")
_KEYS = ("record", "sheet", "identify_hours", "validate_hours", "cycle_hours", "tool_z_mm",
         "note", "temperature_calibration_U_pct", "sensors", "channels")
_CHANNEL_KEYS = ("direction", "nest_z_mm", "calibration_U_pct")
#: Class defaults of the Type B budget (docs/uncertainty.md, "Thermal records"): a
#: non-contact displacement sensor's sensitivity known to 1 % (k = 2) after calibration
#: against a gauge, and a temperature sensor's sensitivity (its reading of a rise) to
#: 0.5 % (k = 2): a class A Pt100's tolerance changes by 0.002 K per K of rise (0.2 %),
#: doubled for the logger's channel.
DISPLACEMENT_CALIBRATION_U_PCT = 1.0
TEMPERATURE_CALIBRATION_U_PCT = 0.5


@dataclass(frozen=True)
class ChannelSpec:
    """One displacement channel: ``direction`` x / y / z, ``nest_z_mm`` its height, mm;
    ``calibration_U_pct`` the expanded uncertainty (k = 2) of its sensitivity, %, and
    whether the machine file declared it (else the class default)."""

    name: str
    direction: str
    nest_z_mm: float
    calibration_U_pct: float = DISPLACEMENT_CALIBRATION_U_PCT
    calibration_declared: bool = False


@dataclass(frozen=True)
class TiltPair:
    """A tilt from two channels of one direction: ``output`` "b" (about Y, from x) or "a"
    (about X, from y); ``lower`` / ``upper`` channel names; ``spacing_mm``."""

    output: str
    lower: str
    upper: str
    spacing_mm: float


@dataclass(frozen=True)
class ThermalSpec:
    """The parsed ``[thermal]`` section (module docs)."""

    record: Path
    sheet: str | None
    identify_hours: tuple[float, float]
    validate_hours: tuple[float, float]
    cycle_hours: float
    tool_z_mm: float
    note: str
    sensors: dict[str, str]
    channels: dict[str, ChannelSpec]
    temperature_calibration_U_pct: float = TEMPERATURE_CALIBRATION_U_PCT
    temperature_calibration_declared: bool = False

    def tilt_pairs(self) -> list[TiltPair]:
        """The x and y pairs (the two extreme heights of each direction)."""
        out = []
        for d, tilt in (("x", "b"), ("y", "a")):
            chans = sorted((c for c in self.channels.values() if c.direction == d),
                           key=lambda c: c.nest_z_mm)
            if len(chans) >= 2 and chans[-1].nest_z_mm > chans[0].nest_z_mm:
                out.append(TiltPair(tilt, chans[0].name, chans[-1].name,
                                    chans[-1].nest_z_mm - chans[0].nest_z_mm))
        return out


def parse_thermal(data: dict[str, Any], err: Callable[[str, str], AbbeInputError],
                  line: Callable[[str], int | None], file: str,
                  resolve: Callable[[str, str], Path]) -> ThermalSpec | None:
    """The ``[thermal]`` section of a parsed machine file, or None without one."""
    if "thermal" not in data:
        return None
    sec = data["thermal"]
    if not isinstance(sec, dict):
        raise err("thermal", "expected a table [thermal]")
    for k in sec:
        if k not in _KEYS:
            raise err(f"thermal.{k}", unknown_key(k, _KEYS))

    def num(f: str, v: Any, lo: float, hi: float, unit: str) -> float:
        return check_number(v, file=file, line=line(f), field=f, lo=lo, hi=hi, unit=unit)

    def text(f: str, v: Any) -> str:
        if not isinstance(v, str) or len(v) > 2000:
            raise err(f, f"expected a string (at most 2000 characters), got {type(v).__name__}")
        return v

    def window(key: str, default: tuple[float, float]) -> tuple[float, float]:
        f = f"thermal.{key}"
        v = sec.get(key, list(default))
        if not isinstance(v, list) or len(v) != 2:
            raise err(f, "expected [start, end] in hours")
        a, b = (num(f, x, 0.0, 1e5, "h") for x in v)
        if not a < b:
            raise err(f, f"expected start < end, got [{a:g}, {b:g}] h")
        return a, b

    if "record" not in sec:
        raise err("thermal", "missing required key 'record' (the thermal record file)")
    record = resolve(text("thermal.record", sec["record"]), "thermal.record")
    sheet = text("thermal.sheet", sec["sheet"]) if "sheet" in sec else None
    ident = window("identify_hours", (0.0, 24.0))
    valid = window("validate_hours", (24.0, 46.0))
    if valid[0] < ident[1] and ident[0] < valid[1]:
        raise err("thermal.validate_hours", f"the validation hours {valid} overlap the "
                                            f"identification hours {ident}: expected disjoint")
    cycle = num("thermal.cycle_hours", sec.get("cycle_hours", 8.0), 0.25, 1000.0, "h")
    tool_z = num("thermal.tool_z_mm", sec.get("tool_z_mm", 100.0), 0.0, 2000.0, "mm")
    note = text("thermal.note", sec.get("note", ""))
    sensors_raw = sec.get("sensors", {})
    if not isinstance(sensors_raw, dict):
        raise err("thermal.sensors", "expected a table [thermal.sensors] (NAME = \"where\")")
    sensors = {k: text(f"thermal.sensors.{k}", v) for k, v in sensors_raw.items()}
    chans_raw = sec.get("channels", {})
    if not isinstance(chans_raw, dict) or not chans_raw:
        raise err("thermal.channels", "expected [thermal.channels.NAME] sections "
                                      "(direction, nest_z_mm)")
    channels: dict[str, ChannelSpec] = {}
    for name, c in chans_raw.items():
        f = f"thermal.channels.{name}"
        if not isinstance(c, dict):
            raise err(f, "expected a table (direction, nest_z_mm)")
        for k in c:
            if k not in _CHANNEL_KEYS:
                raise err(f"{f}.{k}", unknown_key(k, _CHANNEL_KEYS))
        d = c.get("direction")
        if d not in DIRECTIONS:
            raise err(f"{f}.direction", f"expected one of {', '.join(DIRECTIONS)}, got {d!r}")
        z = num(f"{f}.nest_z_mm", c.get("nest_z_mm", 0.0), -2000.0, 2000.0, "mm")
        cal = num(f"{f}.calibration_U_pct", c.get("calibration_U_pct",
                                                   DISPLACEMENT_CALIBRATION_U_PCT), 0.0, 50.0, "%")
        channels[name] = ChannelSpec(name, d, z, cal, "calibration_U_pct" in c)
    t_cal = num("thermal.temperature_calibration_U_pct",
                sec.get("temperature_calibration_U_pct", TEMPERATURE_CALIBRATION_U_PCT),
                0.0, 50.0, "%")
    return ThermalSpec(record, sheet, ident, valid, cycle, tool_z, note, sensors, channels,
                       t_cal, "temperature_calibration_U_pct" in sec)


def check_against_record(spec: ThermalSpec, temp_names: tuple[str, ...],
                         channel_names: tuple[str, ...], machine_file: str,
                         line: Callable[[str], int | None]) -> None:
    """Every declared sensor and channel is in the record, every record column declared."""
    for kind, declared, present in (("sensors", spec.sensors, temp_names),
                                    ("channels", spec.channels, channel_names)):
        for n in declared:
            if n not in present:
                raise AbbeInputError(f"{n} is not in the record {spec.record.name} "
                                     f"(it has {', '.join(present)})", file=machine_file,
                                     line=line(f"thermal.{kind}.{n}"), field=f"thermal.{kind}.{n}")
        for n in present:
            if n not in declared:
                raise AbbeInputError(f"the record's {n} is not declared: add it to "
                                     f"[thermal.{kind}]", file=machine_file,
                                     line=line(f"thermal.{kind}"), field=f"thermal.{kind}")
