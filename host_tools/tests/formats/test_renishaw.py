"""Renishaw readers: the laser .rtl export and the Ballbar 20 .b5r file, from samples
written from the public descriptions (tests/renishaw_samples.py); every refusal names
file, line and field; the 20 deg C normalisation of .rtl and CSV files."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from abbe.analysis.iso230_2 import evaluate
from abbe.errors import AbbeInputError
from abbe.formats import thermal20
from abbe.formats.laser_csv import read_laser_csv
from abbe.formats.laser_file import read_laser_line
from abbe.formats.machine import load_machine
from abbe.formats.positioning import load_positioning
from abbe.formats.renishaw_b5r import read_b5r
from abbe.formats.renishaw_rtl import read_rtl

from cases.renishaw import (PUBLIC_ENV, b5r_from_trace, b5r_text, rtl_from_updown, rtl_text,
                              sample_rtl, write)

ROOT = Path(__file__).resolve().parents[3]
VMC = ROOT / "examples" / "vmc500"
ABBE = [sys.executable, "-m", "abbe.cli"]


def write_csv(path: Path, t, up, down) -> Path:
    """The same readings as abbe's laser CSV (linear channel), in measured order."""
    rows = ["run,direction,target_mm,linear_um"]
    for r in range(up.shape[0]):
        rows += [f"{r + 1},+,{x},{v}" for x, v in zip(t, up[r])]
        rows += [f"{r + 1},-,{x},{v}" for x, v in zip(t[::-1], down[r][::-1])]
    path.write_text("\n".join(rows) + "\n")
    return path


def test_rtl_reads_back_exactly(tmp_path: Path) -> None:
    text, t, up, down = sample_rtl()
    d = load_positioning(write(tmp_path / "x.rtl", text))
    np.testing.assert_array_equal(d.targets_mm, t)
    np.testing.assert_allclose(d.up_um, up, atol=1e-12)
    np.testing.assert_allclose(d.down_um, down, atol=1e-12)
    r = read_rtl(tmp_path / "x.rtl")
    assert r.owner == "Linear" and r.n_runs == 5 and r.text["Axis"] == "X"
    assert r.environment["Air press"] == (99.039005, 99.049346)
    assert r.material_temp_c() == pytest.approx((20.203292 + 20.321342) / 2)  # -10 = unconnected


def test_rtl_descending_target_list_odd_passes_are_minus(tmp_path: Path) -> None:
    t = np.array([0.0, -50.0, -120.0, -200.0])
    odd = np.array([1.0, 2.0, 3.0, 4.0])      # in list order: 0, -50, -120, -200 (moving -)
    even = np.array([11.0, 12.0, 13.0, 14.0])
    passes = [odd, even, odd + 0.1, even + 0.1]
    d = load_positioning(write(tmp_path / "y.rtl", rtl_text(t, passes)))
    np.testing.assert_array_equal(d.targets_mm, [-200, -120, -50, 0])
    np.testing.assert_allclose(d.down_um[0], odd[::-1])       # odd passes: '-' approach
    np.testing.assert_allclose(d.up_um[1], even[::-1] + 0.1)  # even passes: '+' approach


def test_rtl_iso230_2_matches_the_same_data_as_csv(tmp_path: Path) -> None:
    text, t, up, down = sample_rtl(seed=3)
    write_csv(tmp_path / "x.csv", t, up, down)
    a = evaluate(load_positioning(write(tmp_path / "x.rtl", text))).to_json()
    b = evaluate(load_positioning(tmp_path / "x.csv")).to_json()
    for k in ("B_um", "R_um", "E_um", "A_um", "M_um"):
        assert a[k] == pytest.approx(b[k], abs=1e-9)
    assert a["normalisation_20c"]["status"] == thermal20.BY_INSTRUMENT
    assert a["normalisation_20c"]["nominal_differential_expansion_um"] == pytest.approx(
        8.0 * ((20.203292 + 20.321342) / 2 - 20.0) * 500.0 * 1e-3)
    assert b["normalisation_20c"] is None


def test_rtl_keys_in_the_c_writer_spelling(tmp_path: Path) -> None:
    """The C# writer's (commented) environment lines capitalise 'Air Press', 'Air Humid'."""
    env = {("Air Press" if k == "Air press" else "Air Humid" if k == "Air humid" else k): v
           for k, v in PUBLIC_ENV.items()}
    _, t, up, down = sample_rtl()
    r = read_rtl(write(tmp_path / "c.rtl", rtl_from_updown(t, up, down, env=env)))
    assert r.environment["Air press"][0] == 99.039005


def test_rtl_expansion_coefficient_zero_is_not_applied(tmp_path: Path) -> None:
    env = dict(PUBLIC_ENV, **{"Exp coeff": "0.000000 0.000000 0"})
    _, t, up, down = sample_rtl()
    d = load_positioning(write(tmp_path / "z.rtl", rtl_from_updown(t, up, down, env=env)))
    assert d.normalisation.status == thermal20.NOT_APPLIED
    assert "coefficient is 0" in d.normalisation.reason


def test_csv_temperature_and_coefficient_normalise_to_20c(tmp_path: Path) -> None:
    t = np.array([0.0, 100.0, 230.0, 400.0])
    rows = ["run,direction,target_mm,linear_um,temp_c,expansion_ppm_per_k"]
    for r in (1, 2, 3):
        rows += [f"{r},+,{x},1.0,22.0,11.5" for x in t]
        rows += [f"{r},-,{x},-1.0,22.0,11.5" for x in t[::-1]]
    (tmp_path / "c.csv").write_text("\n".join(rows) + "\n")
    d = load_positioning(tmp_path / "c.csv")
    corr = 11.5 * 2.0 * t * 1e-3
    np.testing.assert_allclose(d.up_um[0], 1.0 - corr)
    np.testing.assert_allclose(d.down_um[2], -1.0 - corr)
    assert d.normalisation.status == thermal20.APPLIED
    assert d.normalisation.nominal_differential_expansion_um == pytest.approx(11.5 * 2 * 0.4)
    out = subprocess.run(ABBE + ["iso230-2", str(tmp_path / "c.csv"), "--json", "-"],
                         capture_output=True, text=True, check=True)
    assert json.loads(out.stdout)["normalisation_20c"]["status"] == "applied by abbe"
    bad = rows[:2] + [rows[2].replace(",11.5", ",12")] + rows[3:]
    (tmp_path / "d.csv").write_text("\n".join(bad) + "\n")
    with pytest.raises(AbbeInputError, match="property of the material") as e:
        read_laser_csv(tmp_path / "d.csv", channels=("linear",))
    assert e.value.line == 3 and e.value.field == "expansion_ppm_per_k"


@pytest.mark.parametrize("old,new,line,field,msg", [
    ("Owner      : Linear", "Owner      : Rotary", 3, "Owner", "not one abbe can interpret"),
    ("File type  : rtl", "File type  : rtx", 2, "File type", "expected 'rtl'"),
    ("Flags: 0 0 2 0", "Flags: 0 1 2 0", 13, "Flags", "unidirectional"),
    ("Flags: 0 0 2 0", "Flags: 0 0 2", 13, "Flags", "four integers"),
    ("Target-count: 11", "Target-count: 12", 12, "Targets", "Target-count is 12"),
    ("Run-count:10", "Run-count:9", 25, "Run-count", "odd"),
    ("Run-count:10", "Run-count:12", 138, "Run Target Data", "deviation rows"),
    ("1   2      ", "1   3      ", 30, "target", "expected run 1 target 2"),
    ("Machine:  vmc500", "Machinist: me", 16, "Machinist", "unknown key"),
    ("Air temp   : 20.337280", "Air temp   : nan", None, "Air temp", "finite number"),
    ("Air humid  : 46.954897 46.893887", "Air humid  : 146.9 46.8", None, "Air humid", "100"),
    ("0.000 48.300", "0.000 0.000", 10, "Targets", "strictly monotonic"),
])
def test_rtl_refusals_name_line_and_field(tmp_path: Path, old, new, line, field, msg) -> None:
    text = sample_rtl()[0]
    assert old in text
    p = write(tmp_path / "bad.rtl", text.replace(old, new, 1))
    with pytest.raises(AbbeInputError, match=msg) as e:
        load_positioning(p)
    assert e.value.file == str(p) and e.value.field == field
    if line is not None:
        assert e.value.line == line


def test_rtl_structure_refusals(tmp_path: Path) -> None:
    text = sample_rtl()[0]
    for bad, msg in ((text.replace("EOF::", "EOF::\r\nmore"), "after EOF"),
                     (text.replace("EOF::", ""), "missing section EOF"),
                     ("junk\r\n" + text, "before the first section"),
                     (text.replace("RUNS::", "DEVIATIONS::"), "appears twice"),
                     (text.replace("Owner", "Angular").replace("Angular      :", "Owner :")
                      if False else text.replace("Linear", "Angular"), "needs a 'Linear'")):
        with pytest.raises(AbbeInputError, match=msg):
            load_positioning(write(tmp_path / "b.rtl", bad))


def _rtl_machine(tmp_path: Path, files: str) -> Path:
    shutil.copytree(VMC, tmp_path / "m")
    m = (tmp_path / "m" / "machine.toml").read_text()
    m = m.replace('file = "laser/x.csv"', files)
    (tmp_path / "m" / "machine.toml").write_text(m)
    return tmp_path / "m" / "machine.toml"


def _csv_to_rtl(csv: Path, ch: str, owner: str, dest: Path) -> None:
    d = read_laser_csv(csv)
    v = d.channels[ch]
    write(dest, rtl_from_updown(d.targets_mm, v[:, 0, :], v[:, 1, :], owner=owner))


def test_machine_file_names_rtl_files_per_channel(tmp_path: Path) -> None:
    csv = VMC / "laser" / "x.csv"
    mf = _rtl_machine(tmp_path, 'files = { linear = "laser/x_lin.rtl", yaw = "laser/x_yaw.rtl", '
                                'straight_h = "laser/x_sh.rtl" }')
    _csv_to_rtl(csv, "linear", "Linear", mf.parent / "laser/x_lin.rtl")
    _csv_to_rtl(csv, "yaw", "Angular", mf.parent / "laser/x_yaw.rtl")
    _csv_to_rtl(csv, "straight_h", "Straightness", mf.parent / "laser/x_sh.rtl")
    text = mf.read_text()
    text = text.replace('map = { linear = "+dx", straight_h = "+dy", straight_v = "+dz", '
                        'pitch = "-ey", yaw = "-ez", roll = "+ex" }',
                        'map = { linear = "+dx", straight_h = "+dy", yaw = "-ez" }', 1)
    mf.write_text(text)
    m = load_machine(mf)
    line = m.laser["X"]
    d = read_laser_line(line, channels=tuple(line.map))
    ref = read_laser_csv(csv)
    for ch in ("linear", "yaw", "straight_h"):
        np.testing.assert_allclose(d.channels[ch], ref.channels[ch], atol=5e-5)
    # a file whose measurement type cannot give its channel
    _csv_to_rtl(csv, "yaw", "Angular", mf.parent / "laser/x_sh.rtl")
    with pytest.raises(AbbeInputError, match="cannot give channel 'straight_h'"):
        read_laser_line(line, channels=tuple(line.map))


def test_machine_file_file_or_files(tmp_path: Path) -> None:
    mf = _rtl_machine(tmp_path, 'file = "laser/x.csv"\nfiles = { linear = "laser/x.rtl" }')
    with pytest.raises(AbbeInputError, match="not both"):
        load_machine(mf)
    mf.write_text(mf.read_text().replace('files = { linear = "laser/x.rtl" }',
                                         'files = { linear = "laser/x.txt" }').replace(
                                             'file = "laser/x.csv"\n', ''))
    with pytest.raises(AbbeInputError, match="expected a Renishaw .rtl file") as e:
        load_machine(mf)
    assert e.value.field == "laser.X.files.linear"


def test_b5r_reads_like_the_csv_it_resamples(tmp_path: Path) -> None:
    text, ccw, cw = b5r_from_trace(VMC / "ballbar" / "circle1.csv")
    t = read_b5r(write(tmp_path / "c.b5r", text))
    assert t.plane == "XY" and t.radius_mm == 100.0 and t.feed_mm_min == 200.0
    assert t.sample_rate_hz == 10.0 and t.overrun_deg == 45.0
    assert t.metadata["machine_tested"] == "vmc500" and t.metadata["operator"] == "abbe tests"
    assert t.features["AF_SQUARENESS"] == (-12.0, "um/m")
    tr = t.trace
    np.testing.assert_allclose(tr.radial_um[tr.direction == "ccw"], np.round(ccw, 4), atol=1e-9)
    a = tr.angle_deg[tr.direction == "ccw"]
    assert a[0] == -45.0 and a[-1] == pytest.approx(405.0, abs=0.5)
    assert np.all(np.diff(tr.time_s) > 0)


@pytest.mark.parametrize("edit,msg,field", [
    (('DT="UT_FEEDRATE"', 'DT="UT_FEED_INCH"'), "unit type 'UT_FEED_INCH'", "FEEDRATE"),
    (('<A_AXIS_NAME>X', '<A_AXIS_NAME>Y'), "not interpreted", "A_AXIS_NAME"),
    (('TEST_PLANE="XY"', 'TEST_PLANE="YZ"'), "does not match", "TEST_PLANE"),
    (('RUN DIRECTION="CW"', 'RUN DIRECTION="CCW"'), "expected one RUN", "RUN"),
    (('<RADIUS DT="UT_LENGTH_MM">100', '<RADIUS DT="UT_LENGTH_MM">1e9'), "range", "RADIUS"),
    (('<SAMPLE_RATE DT="UT_FREQUENCY">10', '<SAMPLE_RATE DT="UT_FREQUENCY">20'), "needs",
     "DATA"),
    (('<OVERRUN_ARC DT="UT_ANGLE">45</OVERRUN_ARC>', ''), "missing element <OVERRUN_ARC>",
     "OVERRUN_ARC"),
    (('DT="UT_SQUARENESS"', 'DT="UT_BANANA"'), "not one abbe knows", "FEATURE"),
    (('</BALLBAR_FILE>', ''), "not well-formed", None),
    (('<?xml version="1.0" encoding="utf-8"?>',
      '<?xml version="1.0"?><!DOCTYPE a [<!ENTITY x "y">]>'), "entities", None),
])
def test_b5r_refusals(tmp_path: Path, edit, msg, field) -> None:
    text = b5r_from_trace(VMC / "ballbar" / "circle1.csv")[0]
    assert edit[0] in text
    p = write(tmp_path / "b.b5r", text.replace(edit[0], edit[1], 1))
    with pytest.raises(AbbeInputError, match=msg) as e:
        read_b5r(p)
    assert e.value.file == str(p) and e.value.line is not None
    if field is not None:
        assert e.value.field == field


@pytest.mark.parametrize("space", ["\u00a0", "\u2003", "\u3000", "\u2028"])
@pytest.mark.parametrize("old,field", [
    ('DT="UT_SQUARENESS">-12.0<', "FEATURE AF_SQUARENESS"),
    ('<RADIUS DT="UT_LENGTH_MM">100<', "RADIUS"),
    ('<OVERRUN_ARC DT="UT_ANGLE">45<', "OVERRUN_ARC"),
])
def test_b5r_a_unicode_space_in_a_number_is_refused(tmp_path: Path, old, field, space) -> None:
    """A no-break (or other Unicode) space beside a number is not XML white space: the
    value is "12\u00a0", not 12. Regression: the reader stripped with str.strip(), so a
    FEATURE value "12\u00a0" was read as 12 (fuzz seed 4850 at ABBE_FUZZ_SCALE=5)."""
    text = b5r_from_trace(VMC / "ballbar" / "circle1.csv")[0]
    assert old in text
    p = write(tmp_path / "b.b5r", text.replace(old, old[:-1] + space + "<", 1))
    with pytest.raises(AbbeInputError, match="expected") as e:
        read_b5r(p)
    assert e.value.file == str(p) and e.value.line is not None and e.value.field == field
    # XML white space around the same value (space, tab, CR LF) is still read
    ok = write(tmp_path / "ok.b5r", text.replace(old, old[:-1] + " \t\r\n<", 1))
    assert read_b5r(ok).radius_mm == 100.0


def test_b5r_in_machine_file_must_agree(tmp_path: Path) -> None:
    shutil.copytree(VMC, tmp_path / "m")
    mf = tmp_path / "m" / "machine.toml"
    text = b5r_from_trace(VMC / "ballbar" / "circle1.csv", feed_mm_min=200.0)[0]
    write(tmp_path / "m" / "ballbar" / "c.b5r", text)
    mf.write_text(mf.read_text().replace("ballbar/circle1.csv", "ballbar/c.b5r")
                  .replace("feed_mm_min = 200.0", "feed_mm_min = 250.0"))
    r = subprocess.run(ABBE + ["ballbar", str(mf), "circle1", "--no-plot"], capture_output=True,
                       text=True)
    assert r.returncode == 2 and "FEEDRATE" in r.stderr and "250" in r.stderr, r.stderr


def test_b5r_small_sample(tmp_path: Path) -> None:
    """A hand-sized file: 1000 mm/min on R 50 at 50 Hz, a constant 2 um radius error."""
    deg_s = np.degrees(1000 / 60 / 50)
    n = int(np.floor(450 / deg_s * 50 + 1e-6)) + 1
    t = read_b5r(write(tmp_path / "s.b5r", b5r_text(radius_mm=50, feed_mm_min=1000,
                                                   sample_rate_hz=50, ccw_um=[2.0] * n,
                                                   cw_um=[2.0] * n, data_dt="UT_LENGTH_MM")))
    assert np.all(t.trace.radial_um == 2000.0)  # mm -> um


def test_fit_from_an_rtl_file_equals_the_fit_from_the_csv(ws, tmp_path: Path) -> None:
    """The seed workspace's X line as .rtl (linear) and as CSV: the same fitted term."""
    import re
    from abbe.cli.entry import main
    csv_machine = ws.machine.parent / "machine_linear.toml"
    csv_machine.write_text(re.sub(r'^map = \{ linear = "\+dx".*$', 'map = { linear = "+dx" }',
                                  ws.machine.read_text(), flags=re.M))
    outs = []
    for m in (csv_machine, ws.renishaw_machine):
        out = tmp_path / m.stem
        assert main(["fit", str(m), "-o", str(out), "--no-clib-check", "--no-report", "-q"]) == 0
        outs.append(json.loads((out / "model.json").read_text())["axes"]["X"])
    a, b = outs
    np.testing.assert_allclose(a["terms"]["dx"]["coef_um"], b["terms"]["dx"]["coef_um"],
                               atol=1e-3)
    assert a["iso230_2"] == pytest.approx(b["iso230_2"], abs=1e-3)
    assert b["laser_file"].endswith("x.rtl")


def test_diagnose_reads_an_rtl_positioning_file_like_the_csv(tmp_path: Path) -> None:
    from abbe.diagnose.checks import positioning_check
    text, t, up, down = sample_rtl(seed=4)
    write_csv(tmp_path / "x.csv", t, up, down)
    ref = (0.0, -212.772, -290.704)
    a = positioning_check(write(tmp_path / "x.rtl", text), "X", ref)
    b = positioning_check(tmp_path / "x.csv", "X", ref)
    np.testing.assert_allclose(a.channels[0].values, b.channels[0].values, atol=1e-12)
    np.testing.assert_array_equal(a.targets, b.targets)
    order = a._args["order"]  # source lines: the measured (time) order of the readings
    assert order[0, 0, 0] < order[0, 0, -1] < order[0, 1, -1] < order[0, 1, 0] < order[1, 0, 0]
