"""Printer maps in, a table out: Klipper bed meshes and RepRapFirmware height maps
written here from the firmwares' documented shapes (not by abbe), with a known bed."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from abbe.analysis.printer_fit import fit_height_map, squareness_from_artefacts
from abbe.cli.entry import main
from abbe.errors import AbbeInputError
from abbe.formats.blob import read_blob
from abbe.formats.printer_maps import (SkewArtefact, read_height_map, read_klipper_twist,
                                       read_rrf_heightmap, read_skew_csv)
from abbe.model import clib
from abbe.model.reference import spatial_error


def bed(x, y):
    """A bed of two axis straightnesses, mm: a bow along X, a wave along Y."""
    fx = 0.08 * ((x - 110) / 100) ** 2 - 0.02 * (x - 110) / 100
    gy = 0.03 * np.sin(2 * np.pi * (y - 10) / 360.0)
    return fx + gy


def klipper_cfg(x, y, z, name="default") -> str:
    rows = "\n".join("#*# \t  " + ", ".join(f"{v:.6f}" for v in row) for row in z)
    return ("[printer]\nkinematics: cartesian\n\n"
            "#*# <---------------------- SAVE_CONFIG ---------------------->\n"
            "#*# DO NOT EDIT THIS BLOCK OR BELOW. The contents are auto-generated.\n#*#\n"
            f"#*# [bed_mesh {name}]\n#*# version = 1\n#*# points =\n{rows}\n"
            f"#*# x_count = {len(x)}\n#*# y_count = {len(y)}\n#*# mesh_x_pps = 2\n"
            "#*# mesh_y_pps = 2\n#*# algo = bicubic\n#*# tension = 0.2\n"
            f"#*# min_x = {x[0]}\n#*# max_x = {x[-1]}\n#*# min_y = {y[0]}\n#*# max_y = {y[-1]}\n"
            "#*#\n#*# [axis_twist_compensation]\n#*# z_compensations = 0.0125, 0.005, -0.0175\n"
            "#*# compensation_start_x = 20.0\n#*# compensation_end_x = 183.0\n")


def rrf_csv(x, y, z, new_header=True, unprobed=()) -> str:
    """As Grid.cpp writes it: values padded to 7, an unprobed point a bare 0."""
    head = ("axis0,axis1,min0,max0,min1,max1,radius,spacing0,spacing1,num0,num1\n"
            f"X,Y,{x[0]:.2f},{x[-1]:.2f},{y[0]:.2f},{y[-1]:.2f},-1.00,{x[1] - x[0]:.2f},"
            f"{y[1] - y[0]:.2f},{len(x)},{len(y)}\n") if new_header else (
            "xmin,xmax,ymin,ymax,radius,xspacing,yspacing,xnum,ynum\n"
            f"{x[0]:.2f},{x[-1]:.2f},{y[0]:.2f},{y[-1]:.2f},-1.00,{x[1] - x[0]:.2f},"
            f"{y[1] - y[0]:.2f},{len(x)},{len(y)}\n")
    rows = []
    for j, row in enumerate(z):
        rows.append(",".join(f"{'0':>7}" if (j, i) in unprobed else f"{v:7.3f}"
                             for i, v in enumerate(row)))
    return ("RepRapFirmware height map file v2 generated at 2026-12-04 10:00, min error -0.1, "
            "max error 0.1, mean 0.0, deviation 0.05\n" + head + "\n".join(rows) + "\n")


@pytest.fixture
def grid():
    x = np.linspace(10.0, 210.0, 9)
    y = np.linspace(10.0, 190.0, 7)
    X, Y = np.meshgrid(x, y)
    rng = np.random.default_rng(11)
    return x, y, bed(X, Y) + rng.normal(0, 0.002, X.shape)


def test_klipper_mesh_fitted_separable_bed(tmp_path, grid):
    x, y, z = grid
    p = tmp_path / "printer.cfg"
    p.write_text(klipper_cfg(x, y, z))
    (hm,) = read_height_map(p)
    assert hm.kind == "klipper-bed-mesh" and hm.name == "default"
    assert np.allclose(hm.z_mm, np.round(z, 6))
    fit = fit_height_map(hm)
    # the profiles found: d_z(x) + d_z(y) + c reproduces the bed within the noise
    assert fit.fit_rms_um < 3.0
    # held out: a separable bed is held by abbe's fit better than by the mesh at 2x spacing
    assert fit.heldout_rms_um < fit.firmware_heldout_rms_um < fit.raw_rms_um / 3
    tw = read_klipper_twist(p)
    assert tw is not None and tw.z_mm.tolist() == [0.0125, 0.005, -0.0175]


def test_table_evaluates_the_bed_through_the_c_library(tmp_path, grid):
    """abbe printer fit end to end: the table's dZ at the mesh points is minus the bed
    (relative to the reference), in the Python reference and in the C library."""
    x, y, z = grid
    p = tmp_path / "printer.cfg"
    p.write_text(klipper_cfg(x, y, z))
    out = tmp_path / "fit"
    assert main(["printer", "fit", str(p), "-o", str(out)]) == 0
    table = read_blob((out / "model.bin").read_bytes())
    X, Y = np.meshgrid(x, y)
    pos = np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, 125.0)])
    dz = spatial_error(table, pos)[:, 2]
    h = z.ravel() * 1e3
    # dZ = -(h - c): the same shape up to a constant
    d = dz + h
    assert np.std(d) < 3.0
    if clib.available():
        cm = clib.CModel((out / "model.bin").read_bytes())
        e, _ = cm.error_f32(pos)
        assert np.max(np.abs(e[:, 2] - dz)) < 0.01
    doc = json.loads((out / "printer_fit.json").read_text())
    assert doc["heldout"]["points"] == 35


def test_rrf_heightmap_both_headers_and_unprobed(tmp_path, grid):
    x, y, z = grid
    for new in (True, False):
        p = tmp_path / f"hm{new}.csv"
        p.write_text(rrf_csv(x, y, z, new_header=new, unprobed={(0, 0), (3, 4)}))
        hm = read_rrf_heightmap(p)
        assert np.isnan(hm.z_mm[0, 0]) and np.isnan(hm.z_mm[3, 4])
        assert np.allclose(hm.z_mm[1], np.round(z[1], 3))
        assert hm.points()[1].size == z.size - 2
        assert "not probed" in hm.notes[0]
        assert fit_height_map(hm).fit_rms_um < 3.0


def test_rrf_oldest_label_line(tmp_path, grid):
    """RRF's oldest label line has one spacing for both axes (Grid.cpp HeightMapLabelLines[0])."""
    x = np.linspace(10.0, 190.0, 7)
    y = np.linspace(10.0, 130.0, 5)
    X, Y = np.meshgrid(x, y)
    z = bed(X, Y)
    text = rrf_csv(x, y, z, new_header=False).splitlines()
    text[1] = "xmin,xmax,ymin,ymax,radius,spacing,xnum,ynum"
    text[2] = f"{x[0]:.2f},{x[-1]:.2f},{y[0]:.2f},{y[-1]:.2f},-1.00,30.00,{len(x)},{len(y)}"
    p = tmp_path / "hm.csv"
    p.write_text("\n".join(text) + "\n")
    hm = read_rrf_heightmap(p)
    assert np.allclose(hm.x_mm, x) and np.allclose(hm.y_mm, y)
    assert np.allclose(hm.z_mm, np.round(z, 3))


def test_a_probed_zero_is_a_height(tmp_path, grid):
    x, y, z = grid
    z = z.copy()
    z[2, 2] = 0.0
    p = tmp_path / "hm.csv"
    p.write_text(rrf_csv(x, y, z))
    assert read_rrf_heightmap(p).z_mm[2, 2] == 0.0  # "  0.000" is measured, "0" is not


@pytest.mark.parametrize("mutate, match", [
    (lambda s: s.replace("#*# y_count = 7", "#*# y_count = 8"), "rows of points"),
    (lambda s: s.replace("0.0", "nan", 1), "finite|number"),
    (lambda s: s.replace("#*# min_x = 10.0\n", ""), "no min_x"),
    (lambda s: s.replace("#*# x_count = 9", "#*# x_count = 1000"), "integer"),
    (lambda s: s.replace("[bed_mesh default]", "[bed_mesh_x]"), "no #\\*# \\[bed_mesh"),
])
def test_klipper_refusals_name_the_line(tmp_path, grid, mutate, match):
    x, y, z = grid
    p = tmp_path / "printer.cfg"
    p.write_text(mutate(klipper_cfg(x, y, z)))
    with pytest.raises(AbbeInputError, match=match) as ei:
        read_height_map(p)
    assert ei.value.file == str(p)


def test_rrf_refusals(tmp_path, grid):
    x, y, z = grid
    text = rrf_csv(x, y, z)
    p = tmp_path / "hm.csv"
    p.write_text(text.replace(",9,7\n", ",9,8\n"))
    with pytest.raises(AbbeInputError, match="rows"):
        read_rrf_heightmap(p)
    lines = text.splitlines()
    lines[4] = lines[4].rsplit(",", 1)[0]
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(AbbeInputError, match="values") as ei:
        read_rrf_heightmap(p)
    assert ei.value.line == 5
    p.write_text(text.replace("-1.00", "150.00"))
    with pytest.raises(AbbeInputError, match="circular"):
        read_rrf_heightmap(p)


def test_skew_from_a_known_parallelogram(tmp_path):
    """A square of side 100 mm whose Y edge leans by 0.5 mrad: the diagonals follow."""
    t = 0.5e-3
    a = math.atan(t)
    ad = 100.0
    # A=(0,0), B=(s sin a, s cos a)... side AD along X; diagonals of the rhombus
    s = 100.0
    A = np.array([0.0, 0.0])
    D = np.array([ad, 0.0])
    B = np.array([s * math.sin(a), s * math.cos(a)])
    C = D + B
    ac, bd = float(np.linalg.norm(C - A)), float(np.linalg.norm(D - B))
    # Klipper's factor from these lengths equals tan of the lean (its convention)
    art = SkewArtefact("XY", ac, bd, ad, 2)
    assert abs(art.tangent()) == pytest.approx(t, rel=1e-3)
    p = tmp_path / "skew.csv"
    p.write_text(f"plane,ac_mm,bd_mm,ad_mm\nXY,{ac:.5f},{bd:.5f},{ad}\n")
    (got,) = read_skew_csv(p)
    sq, u95 = squareness_from_artefacts([got], 0.02)
    assert abs(sq["XY"]) == pytest.approx(500.0, abs=2.0)
    assert 100 < u95["XY"] < 1000  # 20 um per length over 100 mm: hundreds of urad
    p.write_text("plane,ac_mm,bd_mm,ad_mm\nXY,141,141,100\nXY,141,141,100\n")
    with pytest.raises(AbbeInputError, match="twice") as ei:
        read_skew_csv(p)
    assert ei.value.line == 3
    p.write_text("plane,ac_mm,bd_mm,ad_mm\nXY,200,100,100\n")
    with pytest.raises(AbbeInputError, match="square"):
        read_skew_csv(p)


def test_printer_fit_states_the_squareness_with_U_and_its_budget(tmp_path, grid, capsys):
    """`abbe printer fit --skew`: printer_fit.json gives the squareness's U (k = 2) beside
    its 95 % half-width (U = 2 u, u95 = 1.96 u) and the budget (the lengths' u); the text
    says U, k = 2."""
    x, y, z = grid
    p = tmp_path / "printer.cfg"
    p.write_text(klipper_cfg(x, y, z))
    skew = tmp_path / "skew.csv"
    skew.write_text("plane,ac_mm,bd_mm,ad_mm\nXY,141.4567,141.3567,100\n")
    out = tmp_path / "fit"
    assert main(["printer", "fit", str(p), "--skew", str(skew), "--length-u-mm", "0.01",
                 "-o", str(out)]) == 0
    doc = json.loads((out / "printer_fit.json").read_text())
    U, u95 = doc["squareness_U_urad"]["XY"], doc["squareness_u95_urad"]["XY"]
    assert U == pytest.approx(2 * u95 / 1.96) and U > 0
    assert doc["uncertainty"]["k"] == 2 and doc["uncertainty"]["budget"]["length_u_mm"] == 0.01
    text = capsys.readouterr().out
    assert f"+- {U:.1f} urad (U, k = 2; artefact lengths u = 0.01 mm)" in text
