"""`abbe diagnose` end to end (the demo machine examples/vmc500) and its bad-input errors:
each names the file, the line and the field, exits 2 and writes nothing."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from abbe.cli.entry import main
from abbe.diagnose.checks import BallbarCheck
from abbe.diagnose.selection import diagnose
from abbe.errors import AbbeInputError
from abbe.formats.blob import read_blob, write_blob
from abbe.formats.table_json import table_from_json
from abbe.model import clib

REPO = Path(__file__).resolve().parents[3]
VMC = REPO / "examples" / "vmc500"
MACHINE = VMC / "machine.toml"
BACKEND = "c" if clib.available() else "reference"


def _true_table():
    return table_from_json(json.loads((VMC / "truth" / "true_table.json").read_text()))


@pytest.fixture(scope="module")
def model_without_squareness(tmp_path_factory) -> Path:
    t = _true_table()
    t.squareness_urad = (0.0, t.squareness_urad[1], t.squareness_urad[2])
    p = tmp_path_factory.mktemp("model") / "model.bin"
    p.write_bytes(write_blob(t))
    return p


def _line_of(path: Path, text: str) -> int:
    for no, ln in enumerate(path.read_text().splitlines(), start=1):
        if ln.strip().startswith(text):
            return no
    raise AssertionError(text)


def test_demo_machine_names_squareness_and_servo(model_without_squareness: Path,
                                                 tmp_path: Path, capsys) -> None:
    out = tmp_path / "out"
    rc = main(["diagnose", str(MACHINE), "--model", str(model_without_squareness),
               "--ballbar", "circle1", "--json", str(tmp_path / "d.json"), "-o", str(out),
               "--backend", BACKEND])
    assert rc == 0
    d = json.loads((tmp_path / "d.json").read_text())
    assert (out / "diagnose.json").read_text() == (tmp_path / "d.json").read_text()
    eff = {e["key"]: e for e in d["effects"]}
    assert set(eff) == {"squareness_xy", "servo_mismatch_xy"}
    sq = eff["squareness_xy"]
    assert sq["id"] == "squareness_xy" and sq["unit"] == "urad"
    assert sq["ci95"][0] < 30.0 < sq["ci95"][1] or abs(sq["value"] - 30.0) < 1.5  # truth 30 urad
    assert sq["compensated_by"] == "table"
    sv = eff["servo_mismatch_xy"]
    assert abs(sv["value"] - 1.0) < 0.1 and sv["compensated_by"] == "prediction model only"
    for k in ("residual_before", "residual_after", "delta_bic", "heldout_change_percent"):
        assert k in sq["evidence"]
    g = d["gap"]
    assert g["after"]["rms_um"] < 0.5 * g["before"]["rms_um"]
    assert g["held_out_after"]["rms_um"] < 0.5 * g["held_out_before"]["rms_um"]
    assert d["model"] == str(out / "model.bin")
    # the updated table carries the squareness the library evaluates (quantised)
    t = read_blob((out / "model.bin").read_bytes())
    assert t.squareness_urad[0] == pytest.approx(sq["value"], abs=1e-3)
    for f in ("abbe_model.c", "abbe_model.h", "model.json", "report.txt",
              "plots/residual_circle1.png", "plots/effect_squareness_xy.png"):
        assert (out / f).is_file(), f
    assert "squareness_xy" in capsys.readouterr().out


def _expect_error(argv: list[str], capsys, file: str, field: str, line: int | None = None) -> str:
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 2, err
    where = f"{file}:{line}:" if line is not None else f"{file}"
    assert where in err, err
    assert f"field '{field}'" in err, err
    return err


def test_model_of_another_machine_is_refused(tmp_path: Path, capsys) -> None:
    t = _true_table()
    t.reference_mm = (100.0, -200.0, -250.0)
    bad = tmp_path / "other.bin"
    bad.write_bytes(write_blob(t))
    out = tmp_path / "out"
    _expect_error(["diagnose", str(MACHINE), "--model", str(bad), "-o", str(out)], capsys,
                  str(MACHINE), "reference.point_mm", _line_of(MACHINE, "point_mm"))
    assert not out.exists() or not any(out.iterdir())


def test_ballbar_outside_the_models_travel(tmp_path: Path, capsys) -> None:
    t = _true_table()
    ax = t.axes["X"]
    ax.travel_mm = (0.0, 400.0)  # the circle reaches x = 443.5 mm
    bad = tmp_path / "short.bin"
    bad.write_bytes(write_blob(t))
    out = tmp_path / "out"
    err = _expect_error(["diagnose", str(MACHINE), "--model", str(bad), "--ballbar", "circle1",
                         "-o", str(out)], capsys, str(MACHINE), "ballbar.circle1.center_mm",
                        _line_of(MACHINE, "[ballbar.circle1]"))
    assert "travel" in err
    assert not out.exists() or not any(out.iterdir())


def test_unknown_test_name_and_missing_model(tmp_path: Path, capsys,
                                            model_without_squareness: Path) -> None:
    _expect_error(["diagnose", str(MACHINE), "--model", str(model_without_squareness),
                   "--ballbar", "circle9", "-o", str(tmp_path / "o")], capsys, str(MACHINE),
                  "ballbar.circle9")
    _expect_error(["diagnose", str(MACHINE), "-o", str(tmp_path / "o")], capsys, str(MACHINE),
                  "model")


def test_garbage_model_file(tmp_path: Path, capsys) -> None:
    bad = tmp_path / "junk.bin"
    bad.write_bytes(b"not a table at all")
    _expect_error(["diagnose", str(MACHINE), "--model", str(bad), "-o", str(tmp_path / "o")],
                  capsys, str(bad), "model")


def test_iso230_2_needs_an_axis(tmp_path: Path, capsys) -> None:
    f = tmp_path / "x.dat"
    f.write_text("TGT_DATA[1]=0\n")
    rc = main(["diagnose", "--iso230-2", str(f), "-o", str(tmp_path / "o")])
    assert rc == 2 and "field 'axis'" in capsys.readouterr().err


def test_single_laser_run_cannot_decide(tmp_path: Path, capsys) -> None:
    f = tmp_path / "one_run.csv"
    rows = ["run,direction,target_mm,linear_um"]
    tg = np.linspace(0.0, 100.0, 11)
    rows += [f"1,+,{p:.3f},{0.01 * p:.4f}" for p in tg]
    rows += [f"1,-,{p:.3f},{0.01 * p + 2.0:.4f}" for p in tg[::-1]]
    f.write_text("\n".join(rows) + "\n")
    _expect_error(["diagnose", "--iso230-2", str(f), "--axis", "X", "-o", str(tmp_path / "o"),
                   "--backend", BACKEND], capsys, str(f), "run")


def test_too_few_points_to_decide() -> None:
    from cases.hidden_effects import REFERENCE_MM
    t = _true_table()
    ang = np.concatenate([np.arange(0.0, 360.0, 30.0), np.arange(330.0, -1.0, -30.0)])
    d = np.array(["ccw"] * 12 + ["cw"] * 12)
    tm = np.arange(ang.size) * 10.0
    c = BallbarCheck("tiny", "XY", (343.507, -285.09, -286.43), 100.0, 200.0, d, ang,
                     np.zeros(ang.size), tm, REFERENCE_MM)
    with pytest.raises(AbbeInputError) as ei:
        diagnose(t, [c])
    assert "too few points" in str(ei.value) and ei.value.field == "checks"


def test_strict_json_no_nan(model_without_squareness: Path, tmp_path: Path) -> None:
    """Linear drifts have tau = inf: the JSON must stay strict (no NaN / Infinity)."""
    from abbe.diagnose.report import clean_json
    d = clean_json({"a": math.inf, "b": [1.0, math.nan], "c": np.float64(2.0)})
    assert d == {"a": None, "b": [1.0, None], "c": 2.0}
    json.dumps(d, allow_nan=False)
