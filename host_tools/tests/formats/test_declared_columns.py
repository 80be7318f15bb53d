"""Declared instrument files: fixtures in several dialects read to the same values.

fixtures/dialects/reference.csv holds the readings in abbe's own format; every other
file there holds the same readings as some instrument writes them (semicolon +
decimal comma + preamble + units row + BOM + CRLF + nm + arcsec + a flipped sign; tab
+ mm/m + ms + other direction words; quoted names with commas + a latin-1 units row
with the micro sign; whitespace + CR-only + mm + mrad + '%' comments) and is
declared in a machine file's [laser.X.columns]. The ballbar export has wrapped
angles, mm and ms, semicolons and a decimal comma.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from abbe.errors import AbbeInputError
from abbe.formats.ballbar_csv import read_ballbar_csv
from abbe.formats.laser_csv import read_laser_csv
from abbe.formats.machine import load_machine

FIX = Path(__file__).parent / "fixtures" / "dialects"

MACHINE = """
[axes.X]
travel_mm = [0.0, 500.0]
[axes.Y]
travel_mm = [-400.0, 0.0]
[axes.Z]
travel_mm = [-300.0, 0.0]
[reference]
point_mm = [100.0, -200.0, -100.0]
[laser.X]
file = "{file}"
start_mm = [0.0, -200.0, -100.0]
end_mm = [200.0, -200.0, -100.0]
map = {{ linear = "+dx", pitch = "-ey", yaw = "-ez", roll = "+ex" }}
[laser.X.columns]
{columns}
"""

DIALECTS = {
    "semicolon_comma_nm_arcsec.csv": """
delimiter = ";"
decimal = ","
skip_lines = 3
units_row = true
run = "Run"
direction = "Direction"
direction_values = ["fwd", "bwd"]
target = "Target"
linear = { column = "Error", sign = -1 }
pitch = "Pitch"
yaw = "Yaw"
roll = "Roll"
time = "Time"
""",
    "tab_mm_per_m_ms.txt": """
delimiter = "tab"
run = "Run #"
direction = "Dir"
direction_values = ["UP", "down"]
target = "Target (mm)"
linear = { column = "Pos. error", unit = "um" }
pitch = { column = "Pitch", unit = "mm/m" }
yaw = { column = "Yaw", unit = "mm/m" }
roll = { column = "Roll", unit = "mm/m" }
time = { column = "t", unit = "ms" }
""",
    "quoted_latin1_units_row.csv": """
encoding = "latin-1"
units_row = true
run = "Run"
direction = "Direction"
target = "Position, mm"
linear = "Linear, \\u00b5m"
pitch = "Pitch, \\u00b5rad"
yaw = "Yaw, \\u00b5rad"
roll = "Roll, \\u00b5rad"
""",
    "whitespace_cr_mm_mrad.txt": """
delimiter = "whitespace"
comment = "%"
direction = "dir"
target = "pos"
linear = { column = "lin", unit = "mm" }
pitch = { column = "pitch", unit = "mrad" }
yaw = { column = "yaw", unit = "mrad" }
roll = { column = "roll", unit = "mrad" }
""",
}


def _machine(tmp_path: Path, file: str, columns: str) -> Path:
    shutil.copyfile(FIX / file, tmp_path / file)
    m = tmp_path / "machine.toml"
    m.write_text(MACHINE.format(file=file, columns=columns), encoding="utf-8")
    return m


@pytest.fixture(scope="module")
def reference():
    return read_laser_csv(FIX / "reference.csv", channels=("linear", "pitch", "yaw", "roll"))


@pytest.mark.parametrize("file", sorted(DIALECTS))
def test_dialect_reads_the_reference_values(tmp_path, reference, file):
    m = load_machine(_machine(tmp_path, file, DIALECTS[file]))
    line = m.laser["X"]
    got = read_laser_csv(line.file, channels=tuple(line.map), columns=line.columns)
    assert np.allclose(got.targets_mm, reference.targets_mm, atol=1e-9)
    for ch in ("linear", "pitch", "yaw", "roll"):
        assert np.allclose(got.channels[ch], reference.channels[ch], atol=2e-3), ch
    assert got.n_runs == 2
    if "time" in line.columns.fields:
        assert np.allclose(got.time_s, reference.time_s)


def test_dialect_file_fits(tmp_path):
    from abbe.cli.entry import main
    m = _machine(tmp_path, "semicolon_comma_nm_arcsec.csv",
                 DIALECTS["semicolon_comma_nm_arcsec.csv"])
    assert main(["fit", str(m), "-o", str(tmp_path / "out"), "--no-clib-check", "--no-report",
                 "-q"]) == 0


@pytest.mark.parametrize("edit,field,text", [
    (("Error", "Eror"), "Eror", "missing column 'Eror' (did you mean 'Error'?)"),
    (("decimal = \",\"", "decimal = \".\""), "Target", "declare decimal"),
    (("linear = { column = \"Error\", sign = -1 }",
      "linear = { column = \"Error\", unit = \"um\", sign = -1 }"), "Error", "units row says"),
    (("direction_values = [\"fwd\", \"bwd\"]", "direction_values = [\"+\", \"-\"]"),
     "Direction", "expected '+' or '-', got 'Fwd'"),
])
def test_declaration_errors_name_file_line_column(tmp_path, edit, field, text):
    cols = DIALECTS["semicolon_comma_nm_arcsec.csv"].replace(*edit)
    m = load_machine(_machine(tmp_path, "semicolon_comma_nm_arcsec.csv", cols))
    line = m.laser["X"]
    with pytest.raises(AbbeInputError) as ei:
        read_laser_csv(line.file, channels=tuple(line.map), columns=line.columns)
    e = ei.value
    assert e.file == str(line.file) and e.line is not None and e.field == field, str(e)
    assert text in e.message, str(e)


@pytest.mark.parametrize("bad,field", [
    ("delimiter = \"::\"", "laser.X.columns.delimiter"),
    ("decimal = \",\"\ndelimiter = \",\"", "laser.X.columns.decimal"),
    ("linear = { column = \"Error\", unit = \"furlong\" }", "laser.X.columns.linear.unit"),
    ("linear = { column = \"Error\", sign = 2 }", "laser.X.columns.linear.sign"),
    ("pitch = { colum = \"P\" }", "laser.X.columns.pitch.colum"),
    ("lienar = \"Error\"", "laser.X.columns.lienar"),
    ("skip_lines = -1", "laser.X.columns.skip_lines"),
    ("encoding = \"ebcdic\"", "laser.X.columns.encoding"),
    ("direction_values = [\"a\", \"A\"]", "laser.X.columns.direction_values"),
])
def test_bad_declarations_name_the_machine_file_line(tmp_path, bad, field):
    m = _machine(tmp_path, "reference.csv", bad)
    with pytest.raises(AbbeInputError) as ei:
        load_machine(m)
    e = ei.value
    assert e.file == str(m) and e.field == field and e.line is not None, str(e)


def test_ballbar_export_with_wrapped_angles(tmp_path):
    ref = read_ballbar_csv(FIX / "ballbar_reference.csv")
    from abbe.formats.columns import BALLBAR_ROLES, parse_columns

    def err(dotted, msg):
        return AbbeInputError(msg, field=dotted)
    cols = parse_columns({"delimiter": ";", "decimal": ",", "units_row": True,
                          "direction": "Direction", "angle": "Angle",
                          "radial": "Deviation", "time": "Time"},
                         BALLBAR_ROLES, "ballbar.c.columns", err, ("ccw", "cw"))
    got = read_ballbar_csv(FIX / "ballbar_wrapped_comma_mm_ms.csv", columns=cols)
    assert list(got.direction) == list(ref.direction)
    assert np.allclose(got.angle_deg, ref.angle_deg)
    assert np.allclose(got.radial_um, ref.radial_um, atol=1e-6)
    assert np.allclose(got.time_s, ref.time_s)


def test_ballbar_columns_in_a_machine_file(tmp_path):
    shutil.copyfile(FIX / "ballbar_wrapped_comma_mm_ms.csv", tmp_path / "bb.csv")
    m = tmp_path / "m.toml"
    m.write_text(MACHINE.format(file="x.csv", columns="") + """
[ballbar.c1]
file = "bb.csv"
plane = "XY"
center_mm = [250.0, -200.0, -100.0]
radius_mm = 100.0
feed_mm_min = 200.0
[ballbar.c1.columns]
delimiter = ";"
decimal = ","
units_row = true
direction = "Direction"
angle = "Angle"
radial = { column = "Deviation", sign = -1 }
time = "Time"
""".replace("[laser.X.columns]\n", ""))
    mach = load_machine(m)
    bt = mach.ballbar["c1"]
    got = read_ballbar_csv(bt.file, columns=bt.columns)
    ref = read_ballbar_csv(FIX / "ballbar_reference.csv")
    assert np.allclose(got.radial_um, -ref.radial_um, atol=1e-6)
