"""``abbe table uncertainty``: the predicted error and U (k = 2) from a fit's model.json, at
points and along an axis; its figures are the analysis' (checked against a separate Monte
Carlo in tests/analysis/test_fit_uncertainty.py); bad input exits 2 naming the field."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from abbe.analysis.fit.uncertainty import point_u, terms_from_json
from abbe.cli.entry import main
from abbe.formats.blob import read_blob
from abbe.model.reference import spatial_error, term_values
from cases.synthetic_laser import make_dataset


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("fitu")
    syn = make_dataset(tmp / "d", n_targets={"X": 26, "Y": 21, "Z": 16}, n_runs=3,
                       wave_period_mm=130.0, seed=5)
    out = tmp / "out"
    assert main(["fit", str(syn.machine), "-o", str(out), "--no-clib-check"]) == 0
    return out


def test_points_json_matches_the_table_and_the_covariance(fitted, tmp_path: Path) -> None:
    js = tmp_path / "u.json"
    pts = [10.0, -50.0, -40.0, 200.0, -150.0, -100.0]
    assert main(["table", "uncertainty", str(fitted / "model.json"), *map(str, pts),
                 "--json", str(js)]) == 0
    d = json.loads(js.read_text())
    assert d["k"] == 2.0 and len(d["points"]) == 2
    table = read_blob((fitted / "model.bin").read_bytes())
    pos = np.array(pts).reshape(-1, 3)
    want = spatial_error(table, pos)
    md = json.loads((fitted / "model.json").read_text())
    terms = terms_from_json(md["uncertainty"], table, "model.json")
    U = 2 * point_u(table, terms, pos)
    for i, p in enumerate(d["points"]):
        assert np.allclose(p["error_um"], want[i], atol=1e-9)
        assert np.allclose(p["U_um"], U[i], rtol=1e-9)
        assert min(p["U_um"]) > 0


def test_along_an_axis_text_and_json(fitted, capsys) -> None:
    assert main(["table", "uncertainty", str(fitted), "--along", "Y", "--points", "5",
                 "--json", "-"]) == 0
    d = json.loads(capsys.readouterr().out)
    blk = d["along"]["Y"]
    assert len(blk["pos_mm"]) == 5 and set(blk["terms"]) == {"dx", "dy", "dz", "ex", "ey", "ez"}
    table = read_blob((fitted / "model.bin").read_bytes())
    v = term_values(table, "Y", "dy", np.array(blk["pos_mm"]))
    assert np.allclose(blk["terms"]["dy"]["value"], v, atol=1e-9)
    assert max(blk["terms"]["dy"]["U"]) > 0
    assert main(["table", "uncertainty", str(fitted), "--along", "X", "--points", "3"]) == 0
    text = capsys.readouterr().out
    assert "U (k = 2)" in text and text.count("\n") >= 5


def _bad(fitted: Path, tmp_path: Path, edit) -> Path:
    d = json.loads((fitted / "model.json").read_text())
    edit(d)
    p = tmp_path / "model.json"
    p.write_text(json.dumps(d))
    return p


@pytest.mark.parametrize("edit, field", [
    (lambda d: d.pop("uncertainty"), "uncertainty"),
    (lambda d: d["uncertainty"]["axes"]["X"]["terms"]["dx"]["covariance_um2"].pop(),
     "covariance_um2"),
    (lambda d: d["uncertainty"]["axes"]["X"]["terms"]["dx"]["covariance_um2"][0].__setitem__(
        1, 1e6), "covariance_um2"),
    (lambda d: d["uncertainty"]["axes"]["Y"]["terms"].__setitem__("dq", {}), "dq"),
])
def test_bad_model_json_exits_2_naming_the_field(fitted, tmp_path: Path, capsys, edit,
                                                 field: str) -> None:
    p = _bad(fitted, tmp_path, edit)
    assert main(["table", "uncertainty", str(p), "0", "-100", "-100"]) == 2
    err = capsys.readouterr().err
    assert field in err and str(p) in err


def test_bad_points_exit_2(fitted, capsys) -> None:
    assert main(["table", "uncertainty", str(fitted), "1", "2"]) == 2
    assert "X Y Z triples" in capsys.readouterr().err
    assert main(["table", "uncertainty", str(fitted)]) == 2
    assert "--along" in capsys.readouterr().err


def test_fit_report_has_the_compact_uncertainty_table(fitted) -> None:
    html = (fitted / "report" / "index.html").read_text()
    md = json.loads((fitted / "model.json").read_text())
    # one compact table per axis (the verdict band's summary table has its own header, in um)
    assert html.count("<th>compensated max |r| &plusmn; U</th>") == len(md["axes"])
    dy = md["uncertainty"]["axes"]["Y"]["terms"]["dy"]
    assert f"<td>{dy['U_max_um']:.3g}</td>" in html
