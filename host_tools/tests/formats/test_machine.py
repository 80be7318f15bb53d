"""Machine file reader: valid files load; every bad key names file, line, field."""

from __future__ import annotations

from pathlib import Path

import pytest

from abbe.errors import AbbeInputError
from abbe.formats.machine import load_machine

GOOD = """\
[machine]
name = "vmc500"

[axes.X]
travel_mm = [0.0, 500.0]
backlash_takeup_mm = 2.0
[axes.Y]
travel_mm = [-400.0, 0.0]
[axes.Z]
travel_mm = [-300.0, 0.0]

[reference]
point_mm = [163.626, -212.772, -290.704]

[tool]
offset_mm = [0.0, 0.0, 100.0]

[laser.X]
file = "laser/x.csv"
start_mm = [0.0, -212.772, -290.704]
end_mm = [500.0, -212.772, -290.704]
map = { linear = "+dx", straight_h = "+dy", straight_v = "+dz", yaw = "-ez", pitch = "-ey", roll = "+ex" }

[ballbar.circle1]
file = "ballbar/circle1.csv"
plane = "XY"
center_mm = [343.507, -285.090, -286.430]
radius_mm = 100.0
feed_mm_min = 200.0

[fit]
folds = 4
"""


def write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "m.toml"
    p.write_text(text)
    return p


def test_good_file_loads(tmp_path: Path) -> None:
    m = load_machine(write(tmp_path, GOOD))
    assert m.name == "vmc500"
    assert m.axes["X"].travel_mm == (0.0, 500.0)
    assert m.axes["X"].backlash_takeup_mm == 2.0
    assert m.axes["Y"].backlash_takeup_mm == 1.0
    assert m.reference_mm == (163.626, -212.772, -290.704)
    assert m.tool_offset_mm == (0.0, 0.0, 100.0)
    line = m.laser["X"]
    assert line.file == (tmp_path / "laser/x.csv").resolve()
    assert line.map["yaw"].sign == -1 and line.map["yaw"].term == "ez"
    assert line.term_channel("dx").channel == "linear"
    assert line.line == 18
    bb = m.ballbar["circle1"]
    assert bb.plane == "XY" and bb.radius_mm == 100.0 and bb.feed_mm_min == 200.0
    assert bb.file.name == "circle1.csv"
    assert m.extra["fit"]["folds"] == 4 and m.extra["fit"]["max_harmonics"] == 8
    assert len(m.sha256) == 64


def test_minimal_file_defaults(tmp_path: Path) -> None:
    m = load_machine(write(tmp_path, '[axes.X]\ntravel_mm = [0, 10]\n[reference]\npoint_mm = [0, 0, 0]\n'))
    assert m.name == "m" and m.tool_offset_mm == (0.0, 0.0, 0.0) and not m.laser and not m.ballbar


BAD = [
    # (replace old, new, expected line, expected field, message fragment)
    ("name = \"vmc500\"", "nmae = \"vmc500\"", 2, "machine.nmae", "unknown key"),
    ("[tool]", "[tools]", 15, "tools", "unknown section"),
    ("[axes.Z]", "[axes.W]", 9, "axes.W", "unknown axis"),
    ("travel_mm = [0.0, 500.0]", "travel_mm = [500.0, 0.0]", 5, "axes.X.travel_mm", "min < max"),
    ("travel_mm = [0.0, 500.0]", "travel_mm = [0.0, \"a\"]", 5, "axes.X.travel_mm", "number"),
    ("backlash_takeup_mm = 2.0", "backlash_takeup_mm = -2.0", 6, "axes.X.backlash_takeup_mm", "in (0, 100] mm"),
    ("point_mm = [163.626, -212.772, -290.704]", "point_mm = [163.626, -212.772]", 13,
     "reference.point_mm", "3 numbers"),
    ("yaw = \"-ez\"", "yawn = \"-ez\"", 22, "laser.X.map.yawn", "unknown instrument channel"),
    ("yaw = \"-ez\"", "yaw = \"-ew\"", 22, "laser.X.map.yaw", "term one of"),
    ("yaw = \"-ez\"", "yaw = \"ez\"", 22, "laser.X.map.yaw", "\"+term\""),
    ("yaw = \"-ez\"", "yaw = \"-dz\"", 22, "laser.X.map.yaw", "already mapped"),
    ("end_mm = [500.0, -212.772, -290.704]", "end_mm = [500.0, -200.0, -290.704]", 21,
     "laser.X.end_mm", "keep y constant"),
    ("end_mm = [500.0, -212.772, -290.704]", "end_mm = [0.0, -212.772, -290.704]", 21,
     "laser.X.end_mm", "must move"),
    ("end_mm = [500.0, -212.772, -290.704]", "end_mm = [600.0, -212.772, -290.704]", 21,
     "laser.X.end_mm", "outside the travel"),
    ("file = \"laser/x.csv\"", "fiel = \"laser/x.csv\"", 19, "laser.X.fiel", "unknown key"),
    ("[laser.X]", "[laser.Q]", 18, "laser.Q", "unknown axis"),
    ("plane = \"XY\"", "plane = \"XZ\"", 26, "ballbar.circle1.plane", "XY, YZ, ZX"),
    ("radius_mm = 100.0", "radius_mm = 0", 28, "ballbar.circle1.radius_mm", "in [1, 2000] mm"),
    ("feed_mm_min = 200.0", "feed_mm_min = true", 29, "ballbar.circle1.feed_mm_min", "number"),
    ("folds = 4", "folds = 1", 32, "fit.folds", "integer in"),
    # the declared tool offset's uncertainty (issue 36): positive, finite, at most 100 mm
    ("offset_mm = [0.0, 0.0, 100.0]", "offset_mm = [0.0, 0.0, 100.0]\noffset_sigma_mm = 0", 17,
     "tool.offset_sigma_mm", "in (0, 100] mm"),
    ("offset_mm = [0.0, 0.0, 100.0]", "offset_mm = [0.0, 0.0, 100.0]\noffset_sigma_mm = nan", 17,
     "tool.offset_sigma_mm", "finite"),
    ("offset_mm = [0.0, 0.0, 100.0]", "offset_mm = [0.0, 0.0, 100.0]\noffset_sigma_mm = \"0.01\"",
     17, "tool.offset_sigma_mm", "number"),
    ("offset_mm = [0.0, 0.0, 100.0]", "offset_mm = [0.0, 0.0, 100.0]\noffset_sigmas_mm = 0.01", 17,
     "tool.offset_sigmas_mm", "unknown key"),
]


def test_declared_tool_uncertainty(tmp_path: Path) -> None:
    m = load_machine(write(tmp_path, GOOD))
    assert m.tool_offset_sigma_mm is None          # not stated: diagnose's default applies
    m = load_machine(write(tmp_path, GOOD.replace("offset_mm = [0.0, 0.0, 100.0]",
                                                  "offset_mm = [0.0, 0.0, 100.0]\noffset_sigma_mm = 0.5")))
    assert m.tool_offset_sigma_mm == 0.5


@pytest.mark.parametrize("old,new,line,field,frag", BAD)
def test_bad_keys_name_file_line_field(tmp_path: Path, old: str, new: str, line: int, field: str,
                                       frag: str) -> None:
    assert old in GOOD
    p = write(tmp_path, GOOD.replace(old, new, 1))
    with pytest.raises(AbbeInputError) as ei:
        load_machine(p)
    e = ei.value
    assert e.file == str(p)
    assert e.line == line
    assert e.field == field
    assert frag in e.message


def test_missing_required_key(tmp_path: Path) -> None:
    p = write(tmp_path, GOOD.replace('file = "laser/x.csv"\n', "", 1))
    with pytest.raises(AbbeInputError) as ei:
        load_machine(p)
    assert ei.value.field == "laser.X" and ei.value.line == 18 and "'file'" in ei.value.message


def test_laser_without_axis_section(tmp_path: Path) -> None:
    text = GOOD.replace("[axes.X]\ntravel_mm = [0.0, 500.0]\nbacklash_takeup_mm = 2.0\n", "")
    p = write(tmp_path, text)
    with pytest.raises(AbbeInputError) as ei:
        load_machine(p)
    assert ei.value.field == "laser.X" and "no [axes.X]" in ei.value.message and ei.value.line == 15


def test_toml_syntax_error_has_line(tmp_path: Path) -> None:
    p = write(tmp_path, GOOD.replace("radius_mm = 100.0", "radius_mm = = 100.0"))
    with pytest.raises(AbbeInputError) as ei:
        load_machine(p)
    assert ei.value.file == str(p) and ei.value.line == 28 and "TOML" in ei.value.message


def test_missing_file_and_reference(tmp_path: Path) -> None:
    with pytest.raises(AbbeInputError) as ei:
        load_machine(tmp_path / "nope.toml")
    assert ei.value.file.endswith("nope.toml")
    p = write(tmp_path, "[axes.X]\ntravel_mm = [0, 10]\n")
    with pytest.raises(AbbeInputError) as ei:
        load_machine(p)
    assert ei.value.field == "reference"
