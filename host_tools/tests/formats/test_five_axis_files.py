"""Five-axis machine sections and measurement files: strict readers, located errors,
round trips of the writers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from abbe.errors import AbbeInputError
from abbe.formats.five_axis import (indexer_csv, probe_csv, read_indexer, read_probe_points,
                                    read_rtest, rtest_csv)
from abbe.formats.machine import load_machine

BASE = """[axes.X]
travel_mm = [-500.0, 500.0]
[axes.Y]
travel_mm = [-500.0, 500.0]
[axes.Z]
travel_mm = [-600.0, 0.0]
[reference]
point_mm = [0.0, 0.0, 0.0]
"""
ROTARY_AC = """[rotary]
kinematics = "xyzac-trt"
x_rot_point_mm = 10.0
y_rot_point_mm = 20.0
z_rot_point_mm = -300.0
y_offset_mm = 20.0
z_offset_mm = -80.0
tool_length_mm = 120.0
[rotary.A]
travel_deg = [-110.0, 110.0]
[rotary.C]
travel_deg = [-360.0, 360.0]
[probing.S1]
file = "probe.csv"
sphere_mm = [60.0, 20.0, -270.0]
sphere_radius_mm = 12.5
stylus_radius_mm = 1.5
"""
PROBE = "position,t_s,a_deg,c_deg,x_mm,y_mm,z_mm\n" + "".join(
    f"0,{i},0,0,{x},{y},{z}\n" for i, (x, y, z) in enumerate(
        [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1)]))


def _machine(tmp_path: Path, text: str, probe: str = PROBE) -> Path:
    (tmp_path / "probe.csv").write_text(probe)
    p = tmp_path / "machine.toml"
    p.write_text(BASE + text)
    return p


def test_trunnion_machine_file_is_read(tmp_path: Path) -> None:
    m = load_machine(_machine(tmp_path, ROTARY_AC))
    fa = m.five_axis
    assert fa.geometry.kind == "xyzac-trt" and fa.geometry.rotaries == ("A", "C")
    assert fa.geometry.rot_point_mm == (10.0, 20.0, -300.0)
    assert fa.geometry.offset_mm == (0.0, 20.0, -80.0)
    assert np.allclose(fa.geometry.pivot("A"), [10.0, 40.0, -380.0])
    assert fa.geometry.travel_deg == {"A": (-110.0, 110.0), "C": (-360.0, 360.0)}
    assert fa.probing["S1"].file == (tmp_path / "probe.csv").resolve()
    assert fa.probing["S1"].radius_tolerance_mm == 0.02
    assert fa.probing["S1"].datum_u_um is None  # a set-up unknown unless declared a datum
    datum = ROTARY_AC.replace("stylus_radius_mm = 1.5", "stylus_radius_mm = 1.5\ndatum_u_um = 1.5")
    assert load_machine(_machine(tmp_path, datum)).five_axis.probing["S1"].datum_u_um == 1.5
    assert fa.fit.harmonics == 0
    bc = ROTARY_AC.replace("xyzac", "xyzbc").replace("y_offset_mm", "x_offset_mm") \
        .replace("rotary.A]", "rotary.B]")
    g = load_machine(_machine(tmp_path, bc)).five_axis.geometry
    assert g.rotaries == ("B", "C") and g.offset_mm == (20.0, 0.0, -80.0)
    assert load_machine(_machine(tmp_path, "")).five_axis is None


@pytest.mark.parametrize("edit, field, words", [
    (('kinematics = "xyzac-trt"', 'kinematics = "xyzca"'), "rotary.kinematics", "expected one of"),
    (("y_offset_mm", "x_offset_mm"), "rotary.x_offset_mm", "unknown key"),
    (("[-110.0, 110.0]", "[110.0, -110.0]"), "rotary.A.travel_deg", "min < max"),
    (("[-110.0, 110.0]", "[-110.0, nan]"), "rotary.A.travel_deg", "finite"),
    (("tool_length_mm = 120.0", "tool_length_mm = -1.0"), "rotary.tool_length_mm", "in [0"),
    (("sphere_radius_mm = 12.5", "sphere_radius_mm = 0.0"), "probing.S1.sphere_radius_mm", "in [0.5"),
    (('file = "probe.csv"\n', ""), "probing.S1", "missing required key 'file'"),
    (("[rotary.C]\ntravel_deg = [-360.0, 360.0]\n", ""), "rotary", "missing [rotary.C]"),
    (("sphere_mm = [60.0, 20.0, -270.0]", "sphere_mm = [60.0, 20.0]"), "probing.S1.sphere_mm",
     "array of 3"),
    (("stylus_radius_mm = 1.5", "stylus_radius_mm = 1.5\ndatum_u_um = 0.0"),
     "probing.S1.datum_u_um", "in [0.01"),
    (("stylus_radius_mm = 1.5", "stylus_radius_mm = 1.5\ndatum_u_um = nan"),
     "probing.S1.datum_u_um", "finite"),
    (("stylus_radius_mm = 1.5", 'stylus_radius_mm = 1.5\ndatum_u_um = "1"'),
     "probing.S1.datum_u_um", "expected"),
])
def test_bad_five_axis_sections_are_located(tmp_path: Path, edit, field, words) -> None:
    text = ROTARY_AC.replace(*edit)
    with pytest.raises(AbbeInputError) as ei:
        load_machine(_machine(tmp_path, text))
    assert ei.value.field == field and words in str(ei.value) and ei.value.line is not None


def test_probing_without_rotary_is_an_error(tmp_path: Path) -> None:
    with pytest.raises(AbbeInputError, match=r"needs a \[rotary\]"):
        load_machine(_machine(tmp_path, '[probing.S1]\nfile = "probe.csv"\n'))


def test_writers_round_trip_through_the_readers(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    ang = np.repeat(rng.uniform(-90, 90, (3, 2)), 5, axis=0)
    pts = rng.uniform(-100, 100, (15, 3))
    p = tmp_path / "p.csv"
    p.write_text(probe_csv("B", np.repeat(np.arange(3), 5), np.arange(15.0), ang, pts))
    r = read_probe_points(p, "B")
    assert np.allclose(r.points_mm, pts, atol=1e-6) and np.allclose(r.angles_deg, ang, atol=1e-6)
    assert list(r.line_no[:2]) == [2, 3]
    q = tmp_path / "r.csv"
    d = rng.normal(0, 5, (10, 3))
    q.write_text(rtest_csv("A", np.arange(10.0), rng.uniform(0, 90, (10, 2)), d))
    assert np.allclose(read_rtest(q, "A").displacement_um, d, atol=1e-6)
    ix = tmp_path / "i.csv"
    ix.write_text(indexer_csv(np.array([1, 1, 1, 1]), np.array([1, 1, -1, -1]),
                              np.array([0.0, 90.0, 90.0, 0.0]), np.array([0.0, 3.5, 4.0, 1.0])))
    runs = read_indexer(ix)
    assert list(runs.direction) == [1, 1, -1, -1] and runs.deviation_urad[1] == 3.5
    with pytest.raises(ValueError):
        rtest_csv("A", np.array([0.0]), np.zeros((1, 2)), np.array([[np.nan, 0, 0]]))


@pytest.mark.parametrize("text, line, words", [
    ("position,t_s,a_deg,c_deg,x_mm,y_mm\n0,0,0,0,1,2\n", 1, "expected the header"),
    (PROBE.replace("0,2,0,0,0,1,0", "0,2,0,0,0,NaN,0"), 4, "finite"),
    (PROBE.replace("0,2,0,0,0,1,0", "0,2,0,0,0,1e9,0"), 4, "in [-2147"),
    (PROBE.replace("0,3,0,0,0,-1,0", "0,1,0,0,0,-1,0"), 5, "time goes backwards"),
    (PROBE.replace("0,3,0,0,0,-1,0", "0,3,0,5,0,-1,0"), 5, "angles change"),
    ("position,t_s,a_deg,c_deg,x_mm,y_mm,z_mm\n0,0,0,0,1,0,0\n0,1,0,0,0,1,0\n", 2, "at least 4"),
    ("position,t_s,a_deg,c_deg,x_mm,y_mm,z_mm\n", None, "no data rows"),
])
def test_bad_probing_files_are_located(tmp_path: Path, text: str, line, words: str) -> None:
    p = tmp_path / "p.csv"
    p.write_text(text)
    with pytest.raises(AbbeInputError) as ei:
        read_probe_points(p, "A")
    assert words in str(ei.value) and ei.value.line == line


def test_bad_indexer_direction(tmp_path: Path) -> None:
    p = tmp_path / "i.csv"
    p.write_text("run,direction,target_deg,deviation_urad\n1,+,0,0\n1,up,90,1\n")
    with pytest.raises(AbbeInputError) as ei:
        read_indexer(p)
    assert ei.value.line == 3 and "'+' or '-'" in str(ei.value)


@pytest.mark.parametrize("bad", ['kinematics = ["xyzac-trt"]', "kinematics = 3", "fit = 2",
                                 "A = 1"])
def test_wrong_types_are_input_errors(tmp_path: Path, bad: str) -> None:
    key = bad.split(" =")[0]
    text = ROTARY_AC.replace('kinematics = "xyzac-trt"', bad) if key == "kinematics" else \
        ROTARY_AC.replace("[rotary.A]\n", "[rotary.X]\n").replace("[rotary]\n", f"[rotary]\n{bad}\n") \
        if key == "A" else ROTARY_AC.replace("[rotary]\n", f"[rotary]\n{bad}\n")
    with pytest.raises(AbbeInputError):
        load_machine(_machine(tmp_path, text))
