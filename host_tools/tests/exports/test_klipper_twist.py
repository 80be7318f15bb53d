"""klipper-twist: the probe-vs-nozzle error along X that Klipper's axis twist
compensation holds, from a table whose X carriage rolls."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from abbe.cli.entry import main
from abbe.formats.blob import read_blob, write_blob
from abbe.model.reference import spatial_error

HERE = Path(__file__).resolve().parent
DEMO = HERE / "golden" / "vmc500-demo" / "model.bin"


def _parse(out: Path) -> dict:
    vals = {}
    for line in (out / "axis_twist_compensation.cfg").read_text().splitlines():
        line = line.split("#")[0].strip()
        if ":" in line:
            k, v = line.split(":", 1)
            vals[k.strip()] = v.strip()
    return vals


def test_a_rolling_carriage_gives_the_probe_a_twist(tmp_path):
    t = read_blob(DEMO.read_bytes())
    x = t.axes["X"]
    # a roll of X growing along its travel: 40 urad end to end on the T1 row
    ex = np.zeros(x.n_basis())
    ex[1] = 20.0
    x.coef = {**x.coef, "ex": ex}
    model = tmp_path / "roll.bin"
    model.write_bytes(write_blob(t))
    t = read_blob(model.read_bytes())
    out = tmp_path / "tw"
    assert main(["export", str(model), "--format", "klipper-twist", "-o", str(out), "--set",
                 "probe_y_offset=40", "sample_count=5", "calibrate_y=-100"]) == 0
    v = _parse(out)
    comp = np.array([float(c) for c in v["z_compensations"].split(",")])
    x0, x1 = float(v["compensation_start_x"]), float(v["compensation_end_x"])
    xs = np.linspace(x0, x1, 5)
    # the definition (Klipper's calibration): z_offset = nozzle's z - probe's z at each
    # nozzle point, compensations = mean - z_offset; nozzle's and probe's z from the model
    probe = replace(t, tool_offset_mm=(t.tool_offset_mm[0], t.tool_offset_mm[1] + 40.0,
                                       t.tool_offset_mm[2]))
    b = np.column_stack([xs, np.full(5, -100.0), np.full(5, t.reference_mm[2])])
    off = (spatial_error(t, b)[:, 2] - spatial_error(probe, b - [0, 40, 0])[:, 2]) * 1e-3
    assert np.allclose(comp, off.mean() - off, atol=1.5e-6)
    assert np.ptp(comp) > 1e-3  # the roll shows: more than a micrometre across X
    rep = json.loads((out / "residual.json").read_text())
    tab = rep["tables"][0]
    assert tab["on_the_line_after_max_um"] < 0.1 * tab["before_max_um"]


def test_options_are_checked(tmp_path, capsys):
    out = tmp_path / "tw"
    assert main(["export", str(DEMO), "--format", "klipper-twist", "-o", str(out), "--set",
                 "calibrate_y=5000"]) == 2
    assert "calibrate_y" in capsys.readouterr().err
    assert not out.exists()
