"""abbe export on synthetic tables: the ISO 230-1 mapping is exact at full resolution,
the grid choice names a point limit that causes residual, thermal terms are named,
the model loader takes every model form."""

from __future__ import annotations

import copy
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from export_readers import READERS, read_isg

from abbe.cli.entry import main as cli_main
from abbe.formats.blob import read_blob, write_blob
from abbe.exports import run_export
from abbe.exports.terms import model_error
from abbe.formats.table_json import table_to_json
from abbe.model.examples import paper_table
from abbe.model.reference import spatial_error
from abbe.model.table import AXES, FourierBlock

HERE = Path(__file__).resolve().parent
DEMO = HERE / "golden" / "vmc500-demo" / "model.bin"


def quantized(t):
    return read_blob(write_blob(t))


@pytest.fixture(scope="module")
def paper():
    t = paper_table()
    return quantized(replace(t, tool_offset_mm=(12.0, -30.0, 150.0),
                             squareness_urad=(20.0, -15.0, 8.0)))


def run(tmp: Path, table, target: str, *opts: str) -> tuple[Path, dict]:
    model = tmp / "model.bin"
    model.write_bytes(write_blob(table))
    out = tmp / target
    assert cli_main(["export", str(model), "--format", target, "-o", str(out),
                     *[a for o in opts for a in ("--set", o)]]) == 0
    return out, json.loads((out / "residual.json").read_text())


def test_model_error_is_the_reference(paper) -> None:
    rng = np.random.default_rng(3)
    P = rng.random((400, 3)) * [500.0, -400.0, -300.0]
    s = np.where(rng.random((400, 3)) < 0.5, -1.0, 1.0)
    assert np.allclose(model_error(paper, P, s), spatial_error(paper, P, s), atol=1e-12)


def test_isg_components_hold_all_21_errors_exactly(tmp_path, paper) -> None:
    """Angular errors, lever arms moved to the machine origin, squareness as C0Y / B0Z /
    A0Z, a tool offset: with enough records only interpolation and text rounding remain."""
    out, rep = run(tmp_path, paper, "isg-csv", "max_records=30000")
    assert rep["volume"]["residual"]["norm"]["max_um"] < 0.01
    assert rep["volume"]["uncompensated"]["norm"]["max_um"] > 20.0
    corr = read_isg(out, tool=paper.tool_offset_mm)  # the CNC's active tool = the model's
    P = np.random.default_rng(5).random((2000, 3)) * [500.0, -400.0, -300.0]
    ref = np.asarray(paper.reference_mm)[None, :]
    z = np.zeros((1, 3))
    r = spatial_error(paper, P) + corr(P, np.ones_like(P))
    r -= spatial_error(paper, ref)[0] + corr(ref, z)[0]
    assert np.max(np.abs(r)) < 0.01


def test_isg_grid_layout_is_convention_free_but_coarse(tmp_path, paper) -> None:
    out, rep = run(tmp_path, paper, "isg-csv", "layout=grid")
    (t,) = rep["tables"]
    assert t["points"] <= 2000 and t["limit_is_cause"]
    corr = READERS["isg-csv"](out)
    P = np.random.default_rng(6).random((2000, 3)) * [500.0, -400.0, -300.0]
    ref = np.asarray(paper.reference_mm)[None, :]
    r = spatial_error(paper, P) + corr(P, np.ones_like(P)) - corr(ref, np.ones((1, 3)))[0]
    assert np.max(np.linalg.norm(r, axis=1)) <= 1.25 * rep["volume"]["residual"]["norm"]["max_um"] + 0.05


def test_the_point_limit_is_named_when_it_causes_residual(tmp_path) -> None:
    """A 5 mm screw-lead term on X: 256 COMP_FILE points over 500 mm cannot follow it."""
    t = copy.deepcopy(paper_table())
    ax = t.axes["X"]
    blk = FourierBlock(period_mm=5.0, origin_mm=0.0, harmonics=1)
    ax.blocks = (ax.blocks[0], blk)
    for term in list(ax.coef):
        ax.coef[term] = np.concatenate([ax.coef[term], [0.0, 0.0]])
    ax.coef["dx"][-2] = 1.5  # um: sin(2 pi x / 5 mm)
    out, rep = run(tmp_path, quantized(t), "linuxcnc-comp")
    tx = next(d for d in rep["tables"] if d["name"].startswith("X.comp"))
    assert tx["limit_is_cause"] and tx["interpolation_residual_um"] > 0.3
    assert tx["twice_the_points_residual_um"] < 0.75 * tx["interpolation_residual_um"]
    ty = next(d for d in rep["tables"] if d["name"].startswith("Y.comp"))
    assert not ty["limit_is_cause"]


def test_thermal_terms_are_named_per_kelvin(tmp_path) -> None:
    t = copy.deepcopy(paper_table())
    t.axes["X"].thermal_expansion_ppm_per_k = 11.5
    t.axes["X"].thermal_tref_c = 20.0
    _, rep = run(tmp_path, quantized(t), "linuxcnc-comp")
    d = next(d for d in rep["not_held"] if d["kind"] == "thermal")
    # 11.5 ppm/K over the largest |x - x_ref| of the travel, at 1 K
    expect = 11.5 * max(163.626, 500.0 - 163.626) * 1e-3
    assert d["per_kelvin"] and d["max_um"] == pytest.approx(expect, rel=1e-3)


def test_without_a_machine_file_the_volume_is_the_model_travel(paper) -> None:
    exp, rep = run_export(paper, "klipper-skew")
    ax = rep["volume"]["axes"]
    assert [ax[a]["min_mm"] for a in AXES] == [paper.axes[a].travel_mm[0] for a in AXES]
    assert rep["circles"] == {}


def test_every_model_form_is_accepted_and_garbage_refused(tmp_path, capsys) -> None:
    table = read_blob(DEMO.read_bytes())
    (tmp_path / "t.json").write_text(json.dumps(table_to_json(table)))
    (tmp_path / "fit.json").write_text(json.dumps({"format": "abbe-fit",
                                                   "table": {"crc32": "0x0", **table_to_json(table)}}))
    outs = []
    for name in ("t.json", "fit.json"):
        out = tmp_path / f"o-{name}"
        assert cli_main(["export", str(tmp_path / name), "-f", "marlin", "-o", str(out)]) == 0
        outs.append((out / "marlin.gcode").read_text())
    assert outs[0] == outs[1]
    (tmp_path / "bad.json").write_text("{\"format\": \"other\"}")
    assert cli_main(["export", str(tmp_path / "bad.json"), "-f", "marlin", "-o",
                     str(tmp_path / "x")]) == 2
    assert "format" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_an_empty_model_exports_or_is_refused_cleanly(tmp_path, capsys) -> None:
    """A table with no terms: every target either writes a null correction (residual 0)
    or refuses with exit 2 (CEC: nothing to tabulate), never a traceback."""
    from abbe.exports import TARGETS
    from abbe.model.table import AxisTable, Table
    t = Table(axes={a: AxisTable(travel_mm=tr) for a, tr in
                    zip(AXES, ((0.0, 500.0), (-400.0, 0.0), (-300.0, 0.0)))},
              reference_mm=(163.626, -212.772, -290.704))
    model = tmp_path / "empty.bin"
    model.write_bytes(write_blob(t))
    for target in TARGETS:
        out = tmp_path / target
        rc = cli_main(["export", str(model), "-f", target, "-o", str(out)])
        if rc == 2:
            assert target == "sinumerik-cec" and "no single-axis part" in capsys.readouterr().err
            continue
        assert rc == 0, target
        rep = json.loads((out / "residual.json").read_text())
        assert rep["volume"]["residual"]["norm"]["max_um"] < 1e-3, target
        assert rep["not_held"] == []
