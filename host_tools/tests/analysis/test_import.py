"""abbe import: ISG CSV (and its .lis) and the Etalon exchange format into an abbe table,
fitted with the laser path's selection; round trips; bad input refused with file, line
and field."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from abbe.cli.entry import main as cli_main
from abbe.formats.blob import read_blob, write_blob
from abbe.formats.model_file import load_table
from abbe.model.examples import paper_table
from abbe.model.reference import spatial_error, term_values
from abbe.model.table import AXES

REPO = Path(__file__).resolve().parents[3]
GOLDEN = REPO / "host_tools" / "tests" / "exports" / "golden"
MACHINE = REPO / "examples" / "vmc500" / "machine.toml"
ISO = {"dx": "X", "dy": "Y", "dz": "Z", "ex": "A", "ey": "B", "ez": "C"}


def volume_points(n: int = 4000) -> np.ndarray:
    return np.random.default_rng(11).random((n, 3)) * [500.0, -400.0, -300.0]


def test_isg_export_import_round_trip(tmp_path) -> None:
    src = GOLDEN / "vmc500-fit" / "isg-csv" / "volcomp.lis"
    assert cli_main(["import", str(src), "-o", str(tmp_path), "--machine", str(MACHINE)]) == 0
    a = load_table(GOLDEN / "vmc500-fit" / "model.bin")
    b = load_table(tmp_path / "model.bin")
    P = volume_points()
    assert np.max(np.abs(spatial_error(a, P) - spatial_error(b, P))) < 0.03  # um
    d = json.loads((tmp_path / "model.json").read_text())
    assert d["format"] == "abbe-import" and d["squareness"]["in_file"]
    t = d["axes"]["Y"]["terms"]["dy"]
    assert t["iso_name"] == "EYY"
    for m in ("chosen", "paper_fourier3", "paper_poly7"):
        assert set(t["metrics"][m]) == {"in_sample", "held_out"}
    assert t["conversion_residual_um"] < 0.05


def _etalon(path: Path, table, extra: str = "") -> None:
    lines = ["// synthetic Etalon exchange file (Vendor variant)"]
    for k, name in enumerate(("C0Y", "B0Z", "A0Z")):
        s = table.squareness_urad[k] * (-1.0 if name == "B0Z" else 1.0)
        lines += [f"[{name}]", f"VALUE = {s * 1e-6:.15e}"]
    for a in AXES:
        q = np.linspace(*table.axes[a].travel_mm, 81)
        for t in ("dx", "dy", "dz", "ex", "ey", "ez"):
            v = term_values(table, a, t, q) * (1e-3 if t[0] == "d" else 1e-6)
            lines += [f"[E{ISO[t]}{a}]", "Gridpoints = {"]
            lines += [f"   {x:.4f} {y:.15e}" for x, y in zip(q, v)]
            lines.append(f"}}  // end of E{ISO[t]}{a}")
    path.write_text("\n".join(lines) + "\n" + extra)


def test_etalon_import_reproduces_the_model(tmp_path) -> None:
    t = read_blob(write_blob(replace(paper_table(), squareness_urad=(25.0, -12.0, 6.0))))
    f = tmp_path / "result.exc"
    _etalon(f, t, "[C0B]\nVALUE = 0.0001\n")
    ref = [str(v) for v in t.reference_mm]
    tool = [str(v) for v in t.tool_offset_mm]
    assert cli_main(["import", str(f), "-o", str(tmp_path / "o"), "--reference", *ref,
                     "--tool-offset", *tool, "--no-unfold"]) == 0
    b = load_table(tmp_path / "o" / "model.bin")
    assert b.squareness_urad == pytest.approx(t.squareness_urad, abs=1e-6)
    P = volume_points()
    assert np.max(np.abs(spatial_error(t, P) - spatial_error(b, P))) < 0.05
    d = json.loads((tmp_path / "o" / "model.json").read_text())
    assert any(s.startswith("C0B") for s in d["ignored"])  # a rotary axis: named, not dropped


@pytest.mark.parametrize("text,where", [
    ("X EXX\n0 0.001\n10 abc\n", ":3: field 'EXX'"),
    ("X EXX EQX\n0 0 0\n", ":1: field 'EQX'"),
    ("X EXX\n0 0.001\n10 nan\n", ":3: field 'EXX'"),
    ("X Y EXX\n0 0 0\n", ":1: field 'X Y'"),
    ("X EXX\n0 0.001 3\n", ":2: field"),
    ("X EXX\n10 0\n0 0\n", "field 'EXX'"),
    ("X EXY\n0 0\n1 0\n", "field 'EXY'"),
])
def test_bad_isg_csv_is_refused_with_line_and_field(tmp_path, capsys, text, where) -> None:
    f = tmp_path / "bad.csv"
    f.write_text(text)
    assert cli_main(["import", str(f), "-o", str(tmp_path / "o"), "--reference", "0", "0", "0"]) == 2
    err = capsys.readouterr().err
    assert where in err, err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("text,where", [
    ("[EXX]\nGridpoints = {\n 0 0\n 1 0\n", "not closed"),
    ("[EXX]\nGridpoints = {\n 0 x\n}\n", ":3: field 'EXX value'"),
    ("VALUE = 1\n", "before the first"),
    ("[EQQ]\nVALUE = 1\n", "field 'EQQ'"),
    ("[C0Y]\nVALUE = 1e-4\n[C0Y]\nVALUE = 2e-4\n", "twice"),
])
def test_bad_etalon_is_refused(tmp_path, capsys, text, where) -> None:
    f = tmp_path / "bad.exc"
    f.write_text(text)
    assert cli_main(["import", str(f), "-o", str(tmp_path / "o"), "--reference", "0", "0", "0"]) == 2
    assert where in capsys.readouterr().err


def test_reference_outside_the_samples_is_refused(tmp_path, capsys) -> None:
    src = GOLDEN / "vmc500-fit" / "isg-csv" / "volcomp.csv"
    assert cli_main(["import", str(src), "-o", str(tmp_path / "o"), "--reference",
                     "900", "-100", "-100"]) == 2
    assert "outside" in capsys.readouterr().err
