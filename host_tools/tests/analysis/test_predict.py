"""abbe predict and the demo pipeline: prediction through the C library,
compensation in the loop, bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from abbe.cli.entry import main as cli_main
from abbe.errors import AbbeInputError
from abbe.formats.blob import quantize, write_blob
from abbe.formats.machine import load_machine
from abbe.model import clib
from abbe.sim.truth import load_truth, truth_table
from doc_json_readers import read_predict

REPO = Path(__file__).resolve().parents[3]
VMC = REPO / "examples" / "vmc500"

pytestmark = pytest.mark.skipif(not clib.available(), reason="C library not built (build/lib/libabbe.so)")


@pytest.fixture(scope="module")
def true_model(tmp_path_factory) -> Path:
    """The virtual machine's true table (squareness and all) as a blob."""
    t = quantize(truth_table(load_truth(VMC / "truth" / "truth.json")))
    path = tmp_path_factory.mktemp("truth") / "model.bin"
    path.write_bytes(write_blob(t))
    return path


def test_true_model_predicts_the_trace(true_model: Path) -> None:
    """With the true table, what is left is servo lag (direction dependent,
    about v * dtau / 2 = 1.7 um on this machine), the 8 mm screw cycles the
    table's 10 mm laser spacing cannot see, and noise: far less than the trace."""
    from abbe.analysis.predict import predict

    p = predict(load_machine(VMC / "machine.toml"), true_model, "circle1")
    assert p.roundness_before_um > 15.0
    assert p.max_residual_um < 4.5
    assert p.ideal_G_um < 0.4 * p.roundness_before_um


def test_prediction_sees_the_servo_mismatch_direction(true_model: Path) -> None:
    """The residual of the true table is the servo lag: its sin(2 theta) part
    flips sign between CCW and CW (notes §4), so it is no fitting artefact."""
    from abbe.analysis.predict import predict

    p = predict(load_machine(VMC / "machine.toml"), true_model, "circle1")
    m = p.trace.data_mask()
    ang, dirs = np.radians(p.trace.angle_deg[m]), p.trace.direction[m]
    amp = {}
    for d in ("ccw", "cw"):
        k = dirs == d
        A = np.stack([np.sin(2 * ang[k]), np.cos(2 * ang[k])], axis=1)
        amp[d] = np.linalg.lstsq(A, p.residual_um[k], rcond=None)[0][0]
    assert amp["ccw"] * amp["cw"] < 0
    assert 1.0 < abs(amp["ccw"]) < 2.5 and 1.0 < abs(amp["cw"]) < 2.5


def test_predict_cli_json_and_plot(true_model: Path, tmp_path: Path, capsys) -> None:
    rc = cli_main(["predict", str(VMC / "machine.toml"), "--model", str(true_model), "--ballbar", "circle1",
                   "--json", "-", "-o", str(tmp_path)])
    assert rc == 0
    d = json.loads(capsys.readouterr().out)
    (pred,) = d["predictions"]
    assert pred["ballbar"] == "circle1" and 0 < pred["residual_max_um"] < 4.5
    read_predict(tmp_path / "predict.json")  # the docs' reader, --mc 200
    assert (tmp_path / "predict_circle1.png").stat().st_size > 10_000
    # every figure with U (k = 2) and the budget it comes from (the ballbar class defaults:
    # the machine file declares none); the roundness's U is the one abbe ballbar states
    assert d["k"] == 2 and d["budget"]["source"].startswith("class defaults")
    assert d["budget"]["figures"]["resolution_um"] > 0
    capsys.readouterr()
    assert cli_main(["ballbar", str(VMC / "machine.toml"), "circle1", "--no-plot",
                     "--json", "-"]) == 0
    bb = json.loads(capsys.readouterr().out)["uncertainty"]["results"]["G_bidirectional"]
    assert pred["roundness_before_U_um"] == pytest.approx(bb["U_um"], abs=1e-4)
    u = pred["uncertainty"]
    assert u["monte_carlo"]["draws"] == 200
    for key, top in (("max_abs", "residual_max"), ("rms", "residual_rms")):
        assert u[key]["value_um"] == pytest.approx(pred[f"{top}_um"], abs=1e-4)
        assert pred[f"{top}_U_um"] == pytest.approx(u[key]["U_stated_um"], abs=1e-4)
        assert pred[f"{top}_U_um"] > 0
    # the RMS: first order and Monte Carlo agree within 10 %
    assert abs(u["rms"]["U_mc_um"] / u["rms"]["U_um"] - 1) <= 0.10, u["rms"]
    capsys.readouterr()
    assert cli_main(["predict", str(VMC / "machine.toml"), "--model", str(true_model),
                     "--ballbar", "circle1", "--mc", "0"]) == 0
    text = capsys.readouterr().out
    assert f"RMS {pred['residual_rms_um']:.2f} +- " in text and "(U, k = 2; budget:" in text


def test_unknown_ballbar_is_refused(true_model: Path, capsys) -> None:
    rc = cli_main(["predict", str(VMC / "machine.toml"), "--model", str(true_model), "--ballbar", "nope"])
    err = capsys.readouterr().err
    assert rc == 2 and "machine.toml" in err and "ballbar.nope" in err and "circle1" in err


def test_model_of_another_machine_is_refused(tmp_path: Path) -> None:
    from abbe.analysis.predict import predict

    t = quantize(truth_table(load_truth(VMC / "truth" / "truth.json")))
    t.axes["X"].travel_mm = (0.0, 900.0)  # a bigger machine
    other = tmp_path / "other.bin"
    other.write_bytes(write_blob(t))
    with pytest.raises(AbbeInputError) as e:
        predict(load_machine(VMC / "machine.toml"), other, "circle1")
    assert e.value.field == "axes.X.travel_mm" and "another machine" in str(e.value)
    t = quantize(truth_table(load_truth(VMC / "truth" / "truth.json")))
    t.reference_mm = (0.0, 0.0, 0.0)
    other.write_bytes(write_blob(t))
    with pytest.raises(AbbeInputError) as e:
        predict(load_machine(VMC / "machine.toml"), other, "circle1")
    assert e.value.field == "reference_mm"


def test_damaged_model_is_refused(true_model: Path, tmp_path: Path, capsys) -> None:
    blob = bytearray(true_model.read_bytes())
    blob[300] ^= 0x40
    bad = tmp_path / "bad.bin"
    bad.write_bytes(bytes(blob))
    rc = cli_main(["predict", str(VMC / "machine.toml"), "--model", str(bad), "--ballbar", "circle1"])
    assert rc == 2 and "ABBE_E_CRC" in capsys.readouterr().err


def test_compensation_in_the_loop_with_the_true_model(true_model: Path) -> None:
    """The C compensator with the true table removes nearly everything it can
    represent: what stays is servo lag, sub-spacing cycles and noise."""
    from abbe.analysis.iso230_4 import evaluate_ballbar
    from abbe.analysis.predict import predict
    from abbe.sim.compensation import campaign_test, compensated_circle

    p = predict(load_machine(VMC / "machine.toml"), true_model, "circle1")
    test, end_s, gap_s, noise = campaign_test(VMC / "truth" / "truth.json", "circle1")
    trace, stats = compensated_circle(VMC / "truth" / "truth.json", test, true_model.read_bytes(),
                                      end_s + gap_s, noise, seed=3)
    after = evaluate_ballbar(trace, test)
    assert stats["limit_trips"] == 0 and stats["invalid_inputs"] == 0 and stats["model_swaps"] == 1
    improvement = 1 - after.both.G_um / p.roundness_before_um
    ideal = 1 - p.ideal_G_um / p.roundness_before_um
    assert improvement > 0.6 and improvement > 0.9 * ideal
