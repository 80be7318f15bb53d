"""Every abbe command that evaluates writes an output folder (-o DIR) that `abbe history
add` reads: each folder is added as a campaign and the values stored are read back from
the database against the command's own JSON (not against numbers written here)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import sqlalchemy as sa

from abbe.cli.entry import main
from doc_json_readers import read_predict

REPO = Path(__file__).resolve().parents[3]
VMC = REPO / "examples" / "vmc500"
TRUNNION = REPO / "examples" / "trunnion5ax"


def _stored(db: str) -> dict[str, tuple[float, float | None, float | None]]:
    from abbe.history.database import open_database
    base = open_database(db)
    try:
        with base.read() as conn:
            rows = conn.execute(sa.text("SELECT series, value, ci_low, ci_high FROM results")).all()
    finally:
        base.close()
    return {s: (v, lo, hi) for s, v, lo, hi in rows}


def _add(db: str, folder: Path, *extra: str) -> dict[str, tuple[float, float | None, float | None]]:
    assert main(["history", "--db", db, "add", str(folder), "--date", "2026-03-01", *extra]) == 0
    return _stored(db)


@pytest.fixture()
def sqlite(tmp_path) -> str:
    return str(tmp_path / "history.sqlite")


def test_iso230_2_and_ballbar_folders(sqlite, tmp_path):
    out = tmp_path / "iso"
    assert main(["iso230-2", str(VMC / "laser" / "x.csv"), "--mc", "0", "-o", str(out)]) == 0
    doc = json.loads((out / "iso230_2.json").read_text())
    vals = _add(sqlite, out, "--axis", "X", "--machine", "vmc500")
    assert vals["iso230-2 E X bi"][0] == doc["E_um"]
    bb = tmp_path / "bb"
    assert main(["ballbar", str(VMC / "machine.toml"), "circle1", "--mc", "0", "-o",
                 str(bb)]) == 0
    d = json.loads((bb / "ballbar.json").read_text())
    vals = _add(str(tmp_path / "h2.sqlite"), bb)
    assert vals["ballbar H XY F200"][0] == d["H_um"]


def test_five_axis_fit_and_diagnose_folders(sqlite, tmp_path):
    out = tmp_path / "fit5"
    assert main(["fit", str(TRUNNION / "machine.toml"), "-o", str(out)]) == 0
    doc = json.loads((out / "five_axis.json").read_text())
    vals = _add(sqlite, out)
    located = [p for p in doc["parameters"] if p["kind"] == "location" and p["observable"]]
    assert located
    for p in located:
        v, lo, hi = vals[f"five-axis {p['name']}"]
        assert v == p["value"] and hi - lo == pytest.approx(2 * p["ci95"])
    # the errors the plan cannot see are not stored as numbers (never as 0)
    for p in doc["parameters"]:
        if p["kind"] == "location" and not p["observable"]:
            assert f"five-axis {p['name']}" not in vals
    assert vals["five-axis dispersion heldout after"][0] == doc["dispersion_um"]["heldout_after"]
    diag = tmp_path / "diag5"
    assert main(["diagnose", str(TRUNNION / "machine.toml"), "-o", str(diag)]) == 0
    d = json.loads((diag / "diagnose_five_axis.json").read_text())
    vals = _add(str(tmp_path / "h2.sqlite"), diag)
    assert vals["five-axis diagnose heldout after"][0] == d["heldout_after_um"]


def test_thermal_folders(sqlite, tmp_path):
    from cases.thermal_independent import generate
    from thermal_helpers import machine_text
    csv, _truth, _ = generate(seed=3, noise_um=0.3)
    (tmp_path / "record.csv").write_text(csv)
    m = tmp_path / "machine.toml"
    m.write_text(machine_text("record.csv", {"chz": "z", "chx": "x"}))
    ev = tmp_path / "evaluate"
    assert main(["thermal", "evaluate", str(m), "-o", str(ev)]) == 0
    doc = json.loads((ev / "iso230_3.json").read_text())
    vals = _add(sqlite, ev)
    assert vals["iso230-3 envelope"][0] == doc["envelope"]["range_um"]
    for ch in doc["channels"]:
        assert vals[f"iso230-3 range {ch['name']}"][0] == ch["range"]
    assert (ev / "report.html").stat().st_size > 1000 and (ev / "drift.png").is_file()
    fit = tmp_path / "fit"
    assert main(["thermal", "fit", str(m), "-o", str(fit)]) == 0
    f = json.loads((fit / "fit.json").read_text())
    vals = _add(str(tmp_path / "h2.sqlite"), fit)
    for s in f["signals"]:
        assert vals[f"thermal fit {s['name']} held-out rms model"][0] == s["rms_model"]
    dg = tmp_path / "diag"
    assert main(["thermal", "diagnose", str(m), "-o", str(dg)]) == 0
    d = json.loads((dg / "diagnosis.json").read_text())
    vals = _add(str(tmp_path / "h3.sqlite"), dg)
    for ch in d["channels"]:
        assert vals[f"thermal diagnose {ch['channel']} held-out gap before"][0] == \
            ch["gap_heldout_um"]


def test_printer_fit_folder(sqlite, tmp_path):
    x = np.linspace(10.0, 210.0, 9)
    y = np.linspace(10.0, 190.0, 7)
    X, Y = np.meshgrid(x, y)
    z = 0.05 * np.sin(X / 60.0) + 0.03 * (Y / 190.0) ** 2 + 0.0004 * X * Y / 200.0
    rows = "\n".join("#*# \t  " + ", ".join(f"{v:.6f}" for v in row) for row in z)
    cfg = tmp_path / "printer.cfg"
    cfg.write_text("[printer]\nkinematics: cartesian\n\n"
                   "#*# <---------------------- SAVE_CONFIG ---------------------->\n"
                   "#*# DO NOT EDIT THIS BLOCK OR BELOW. The contents are auto-generated.\n#*#\n"
                   f"#*# [bed_mesh default]\n#*# version = 1\n#*# points =\n{rows}\n"
                   f"#*# x_count = {len(x)}\n#*# y_count = {len(y)}\n#*# mesh_x_pps = 2\n"
                   "#*# mesh_y_pps = 2\n#*# algo = bicubic\n#*# tension = 0.2\n"
                   f"#*# min_x = {x[0]}\n#*# max_x = {x[-1]}\n#*# min_y = {y[0]}\n"
                   f"#*# max_y = {y[-1]}\n")
    out = tmp_path / "pf"
    assert main(["printer", "fit", str(cfg), "-o", str(out)]) == 0
    doc = json.loads((out / "printer_fit.json").read_text())
    vals = _add(sqlite, out, "--machine", "printer-1")
    assert vals["printer held-out RMS, abbe"][0] == doc["heldout"]["abbe_rms_um"]


def test_predict_folder(sqlite, tmp_path):
    from abbe.model import clib
    try:
        clib.load_library()
    except clib.LibraryNotFound:
        pytest.skip("the C library is not built: abbe predict needs it")
    fit = tmp_path / "fit"
    assert main(["fit", str(VMC / "machine.toml"), "-o", str(fit), "--no-report", "-q"]) == 0
    out = tmp_path / "pred"
    assert main(["predict", str(VMC / "machine.toml"), "--model", str(fit / "model.bin"),
                 "--ballbar", "circle1", "-o", str(out), "--mc", "0"]) == 0  # U checked elsewhere
    doc = read_predict(out / "predict.json")  # the docs' reader, without a Monte Carlo
    vals = _add(sqlite, out)
    p = doc["predictions"][0]
    assert vals["predict circle1 prediction residual max"][0] == p["residual_max_um"]


def test_a_bad_value_in_a_new_output_is_refused_with_its_place(sqlite, tmp_path, capsys):
    out = tmp_path / "ev"
    out.mkdir()
    (out / "iso230_3.json").write_text(json.dumps(
        {"format": "abbe-iso230-3 1.0", "machine": "m", "channels": [{"name": "c", "range": -1}],
         "tilts": [], "envelope": {"range_um": 1.0}}, indent=1))
    assert main(["history", "--db", sqlite, "add", str(out)]) == 2
    err = capsys.readouterr().err
    assert "iso230_3.json" in err and "channels[0].range" in err


def test_export_folders(sqlite, tmp_path):
    """abbe export -o: residual.json (three- and five-axis) stored against its own values."""
    fit = tmp_path / "fit"
    assert main(["fit", str(VMC / "machine.toml"), "-o", str(fit), "--no-report", "-q"]) == 0
    out = tmp_path / "lcnc"
    assert main(["export", str(fit / "model.bin"), "-f", "linuxcnc-comp", "-o", str(out),
                 "--machine", str(VMC / "machine.toml")]) == 0
    doc = json.loads((out / "residual.json").read_text())
    vals = _add(sqlite, out, "--machine", "vmc500")
    vol = doc["volume"]
    assert vals["export linuxcnc-comp volume residual |E| max"][0] == vol["residual"]["norm"]["max_um"]
    assert (vals["export linuxcnc-comp volume uncompensated |E| rms"][0]
            == vol["uncompensated"]["norm"]["rms_um"])
    assert doc["circles"]  # the machine file's circles are evaluated and stored too
    for name, c in doc["circles"].items():
        assert vals[f"export linuxcnc-comp circle {name} residual |E| max"][0] == \
            c["residual"]["norm"]["max_um"]
    fit5 = tmp_path / "fit5"
    assert main(["fit", str(TRUNNION / "machine.toml"), "-o", str(fit5)]) == 0
    trt = tmp_path / "trt"
    assert main(["export", str(fit5 / "model_five.bin"), "-f", "linuxcnc-trt", "-o", str(trt),
                 "--machine", str(TRUNNION / "machine.toml")]) == 0
    d5 = json.loads((trt / "residual.json").read_text())
    vals = _add(str(tmp_path / "h5.sqlite"), trt, "--machine", "trunnion5ax")
    assert (vals["export linuxcnc-trt tcp path residual |E| rms"][0]
            == d5["tcp_path"]["residual"]["norm"]["rms_um"])


def test_a_bad_export_residual_is_refused_with_its_place(sqlite, tmp_path, capsys):
    out = tmp_path / "ex"
    out.mkdir()
    stats = {"norm": {"max_um": 1.0, "rms_um": 0.5}}
    (out / "residual.json").write_text(json.dumps(
        {"format": "abbe-export-residual", "version": 1, "target": "marlin",
         "volume": {"residual": {"norm": {"max_um": float("nan"), "rms_um": 0.5}},
                    "uncompensated": stats}, "circles": {}}, indent=1))
    assert main(["history", "--db", sqlite, "add", str(out), "--machine", "m"]) == 2
    err = capsys.readouterr().err
    assert "residual.json:" in err and "NaN" in err
