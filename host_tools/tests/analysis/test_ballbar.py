"""Tests of the ballbar: simulated signatures, ISO 230-4 evaluation, CSV checks, prediction,
compensation in the loop and the `abbe ballbar` command."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from abbe.analysis.iso230_4 import evaluate_ballbar, fit_circle
from abbe.analysis.predict import predict_ballbar, predict_trace
from abbe.cli.entry import main
from abbe.errors import AbbeInputError
from abbe.formats.ballbar_csv import BallbarTrace, read_ballbar_csv
from abbe.sim.compensation import model_compensator_step, run_circle_with_compensation
from abbe.sim.instruments import simulate_ballbar
from abbe.sim.truth import truth_table
from abbe.sim.virtual_machine import VirtualMachine

from sim_helpers import EXAMPLE, make_truth, paper_circle, typical_shapes


def _lsc_residual(trace: BallbarTrace, values: np.ndarray, direction: str | None = None):
    m = trace.data_mask(direction)
    return trace.angle_deg[m], fit_circle(trace.angle_deg[m], values[m], 100.0).residual_um


# --------------------------------------------------------------------------- signatures


def test_pure_squareness_gives_R_S_over_2_sin_2theta():
    S = 40.0
    tr = make_truth(squareness_urad=(S, 0.0, 0.0))
    test = paper_circle()
    trace = simulate_ballbar(VirtualMachine(tr), test)
    for d in ("ccw", "cw"):
        ang, res = _lsc_residual(trace, trace.radial_um, d)
        exp = 100.0 * S * 1e-3 / 2.0 * np.sin(np.radians(2 * ang))
        np.testing.assert_allclose(res, exp, atol=1e-3)
    r = evaluate_ballbar(trace, test)
    assert r.both.G_um == pytest.approx(100.0 * S * 1e-3, rel=1e-3)
    assert r.H_um < 1e-3


def test_pure_backlash_step_signature():
    """Lost motion b on X: the tool lags by b/2 along x, dR = -(b/2) s_x cos(theta),
    s_x = sign(dx/dt): steps at 0/180 deg, mirrored between CCW and CW."""
    b = 6.0
    tr = make_truth(backlash_um=(b, 0.0, 0.0), backlash_takeup_mm=(0.001, 0.1, 0.1))
    test = paper_circle(sample_deg=0.5)
    trace = simulate_ballbar(VirtualMachine(tr), test)
    th = np.radians(trace.angle_deg)
    d = np.where(trace.direction == "cw", -1.0, 1.0)
    s_x = np.sign(-np.sin(th) * d)
    exp = -(b / 2.0) * s_x * np.cos(th)
    m = trace.data_mask() & (np.abs(np.sin(th)) > 0.02)
    np.testing.assert_allclose(trace.radial_um[m], exp[m], atol=1e-3)
    r = evaluate_ballbar(trace, test)
    assert r.H_um == pytest.approx(b, abs=0.05)  # CCW and CW differ by b at 0/180 deg


def test_servo_mismatch_flips_between_directions():
    """Lags tau_x, tau_y: dR ~ (v (tau_x - tau_y) / 2) sin(2 theta), opposite for CW."""
    tx, ty = 0.010, 0.014
    tr = make_truth(servo_lag_ms=(tx * 1e3, ty * 1e3, 0.0))
    test = paper_circle(feed_mm_min=2000.0)
    v = 2000.0 / 60.0
    trace = simulate_ballbar(VirtualMachine(tr), test)
    for d, sgn in (("ccw", 1.0), ("cw", -1.0)):
        ang, res = _lsc_residual(trace, trace.radial_um, d)
        exp = sgn * v * (tx - ty) / 2.0 * 1e3 * np.sin(np.radians(2 * ang))
        np.testing.assert_allclose(res, exp, atol=0.02 * np.abs(exp).max())
    assert evaluate_ballbar(trace, test).H_um == pytest.approx(v * (ty - tx) * 1e3, rel=0.03)


def test_setup_offset_shows_as_centre_offset():
    tr = make_truth()
    test = paper_circle(setup_offset_um=(-5.2, 1.8, 0.0))
    r = evaluate_ballbar(simulate_ballbar(VirtualMachine(tr), test), test)
    assert r.both.center_um == pytest.approx((5.2, -1.8), abs=1e-3)
    assert r.both.G_um < 1e-3


# --------------------------------------------------------------------------- evaluation


def _synthetic(ex=3.0, ey=-2.0, dr=1.5, lobe=0.8, h=0.0, step=1.0) -> BallbarTrace:
    a = np.arange(-45.0, 405.0 + step / 2, step)
    th = np.radians(a)
    base = ex * np.cos(th) + ey * np.sin(th) + dr + lobe * np.sin(3 * th)
    ang = np.concatenate([a, a[::-1]])
    rad = np.concatenate([base, (base + h * np.cos(2 * th))[::-1]])
    dirs = np.array(["ccw"] * a.size + ["cw"] * a.size)
    return BallbarTrace(dirs, ang, rad, np.arange(ang.size) * 0.1)


def test_evaluation_known_circle_values():
    tr = _synthetic(ex=3.0, ey=-2.0, dr=1.5, lobe=0.8, h=0.6)
    test = paper_circle()
    r = evaluate_ballbar(tr, test)
    cc = r.per_direction["ccw"]
    assert cc.center_um == pytest.approx((3.0, -2.0), abs=1e-4)
    assert cc.radius_dev_um == pytest.approx(1.5, abs=1e-4)
    assert cc.G_um == pytest.approx(1.6, abs=1e-3)     # 0.8 sin(3 theta): max - min = 1.6
    assert r.H_um == pytest.approx(0.6, abs=1e-3)      # CW = CCW + 0.6 cos(2 theta)
    assert r.both.center_um == pytest.approx((3.0, -2.0), abs=1e-3)
    assert r.n_samples == {"ccw": 360, "cw": 360}       # feed arcs excluded


def test_feed_arcs_are_excluded():
    tr = _synthetic(lobe=0.0)
    m = (tr.angle_deg < 0) | (tr.angle_deg >= 360)
    tr.radial_um[m] += 50.0  # garbage on the feed arcs must not matter
    r = evaluate_ballbar(tr, paper_circle())
    assert r.both.G_um < 1e-3  # (the synthetic dR is the linearised circle)


def test_large_setup_offset_is_fitted_exactly():
    """Centre ball 0.5 mm off (and 0.2 mm in y), bar 30 um long: exact, where the
    linearised circle fit leaves a cos(2 theta) residual of ~1 um."""
    a = np.arange(0.0, 360.0, 1.0)
    th = np.radians(a)
    R, bx, by = 100.0, 0.5, -0.2
    dr = (np.hypot(R * np.cos(th) - bx, R * np.sin(th) - by) - R) * 1e3 + 30.0
    cf = fit_circle(a, dr, R)
    assert cf.center_um == pytest.approx((-500.0, 200.0), abs=1e-6)
    assert cf.radius_dev_um == pytest.approx(30.0, abs=1e-6)
    assert cf.G_um < 1e-6
    A = np.stack([np.cos(th), np.sin(th), np.ones_like(th)], axis=1)
    lin = dr - A @ np.linalg.lstsq(A, dr, rcond=None)[0]
    assert np.ptp(lin) > 1.0


# --------------------------------------------------------------------------- CSV checks


def _good_csv(tmp_path: Path) -> tuple[Path, list[str]]:
    tr = make_truth(squareness_urad=(30.0, 0.0, 0.0))
    trace = simulate_ballbar(VirtualMachine(tr), paper_circle(sample_deg=2.0))
    lines = trace.to_csv().splitlines()
    p = tmp_path / "bb.csv"
    p.write_text("\n".join(lines) + "\n")
    return p, lines


def test_read_good_csv_round_trip(tmp_path):
    p, lines = _good_csv(tmp_path)
    tr = read_ballbar_csv(p)
    assert tr.direction.size == len(lines) - 1
    assert int(tr.line_no[0]) == 2


def _broken(lines: list[str], kind: str) -> tuple[list[str], int, str]:
    """Return broken lines, the expected error line (1-based) and field."""
    ls = list(lines)
    ccw = [i for i, l in enumerate(ls) if l.startswith("ccw,")]
    cw = [i for i, l in enumerate(ls) if l.startswith("cw,")]
    if kind == "gap":
        i0 = ccw[0] + 60  # angle -45 + 2*60 = 75 deg
        del ls[i0:i0 + 10]
        return ls, i0 + 1, "angle_deg"
    if kind == "nonmonotonic":
        i = ccw[0] + 80
        ls[i], ls[i + 1] = ls[i + 1].replace(",", ",", 1), ls[i]
        a = ls[i].split(","); b = ls[i + 1].split(",")
        a[3], b[3] = b[3], a[3]  # keep time increasing
        ls[i], ls[i + 1] = ",".join(a), ",".join(b)
        return ls, i + 2, "angle_deg"
    if kind == "missing_cw":
        return ls[: cw[0]], cw[0], "direction"
    if kind == "cw_first":
        body = [ls[i] for i in cw] + [ls[i] for i in ccw]
        return [ls[0]] + body, 2, "direction"
    if kind == "mixed_units_header":
        ls[0] = "direction,angle_deg,radial_mm,time_s"
        return ls, 1, "radial_mm"
    if kind == "mixed_units_value":
        i = ccw[0] + 100
        a = ls[i].split(",")
        a[2] = "3500.0"
        ls[i] = ",".join(a)
        return ls, i + 1, "radial_um"
    if kind == "bad_cell":
        i = cw[0] + 5
        a = ls[i].split(",")
        a[1] = "12.5deg"
        ls[i] = ",".join(a)
        return ls, i + 1, "angle_deg"
    if kind == "time_back":
        i = cw[0] + 3
        a = ls[i].split(",")
        a[3] = "0.0"
        ls[i] = ",".join(a)
        return ls, i + 1, "time_s"
    raise AssertionError(kind)


@pytest.mark.parametrize("kind", ["gap", "nonmonotonic", "missing_cw", "cw_first",
                                  "mixed_units_header", "mixed_units_value", "bad_cell",
                                  "time_back"])


def test_bad_ballbar_files_name_file_line_field(tmp_path, kind):
    p, lines = _good_csv(tmp_path)
    bad, line, field = _broken(lines, kind)
    p.write_text("\n".join(bad) + "\n")
    with pytest.raises(AbbeInputError) as ei:
        read_ballbar_csv(p)
    e = ei.value
    assert (e.file, e.line, e.field) == (str(p), line, field), str(e)


# --------------------------------------------------------------------------- prediction


def _thermal_truth():
    return make_truth(typical_shapes(), squareness_urad=(30.0, 10.0, -5.0),
                      backlash_um=(3.0, 4.0, 2.0), backlash_takeup_mm=(0.05, 0.05, 0.05),
                      cyclic_um=(0.6, 0.8, 0.0), cyclic_period_mm=(8.0, 8.0, 10.0),
                      thermal_rise_k=1.5, thermal_time_constant_s=3600.0,
                      thermal_expansion_ppm_per_k=(4.0, 4.0, 4.0),
                      thermal_offset_um_per_k=(1.0, -1.0, 0.5), tool_offset_mm=(0.0, 0.0, -80.0))


def test_prediction_with_true_table_matches_simulation():
    """Servo and noise off: the true table predicts the simulated trace (after LSC) to
    nanometres; what is left is the backlash take-up ramp and the nonlinearity."""
    tr = _thermal_truth()
    test = paper_circle(sample_deg=1.0)
    t0 = 5000.0
    trace = simulate_ballbar(VirtualMachine(tr), test, start_time_s=t0)
    temp = np.repeat(tr.temperature_c(t0 + trace.time_s)[:, None], 3, axis=1)
    pred = predict_trace(truth_table(tr), trace, test, temp_c=temp)
    ang, res = _lsc_residual(trace, trace.radial_um - pred)
    print(f"true-table prediction residual after LSC: {np.abs(res).max():.4f} um "
          f"(trace G {evaluate_ballbar(trace, test).both.G_um:.2f} um)")
    assert np.abs(res).max() < 0.02
    # a table without the squareness misses exactly the (R S/2) sin 2theta oval
    pred2 = predict_trace(truth_table(tr, include=("cyclic", "backlash", "thermal",
                                                    "tool_offset")), trace, test, temp_c=temp)
    ang, res2 = _lsc_residual(trace, trace.radial_um - pred2)
    np.testing.assert_allclose(res2, 100 * 30e-3 / 2 * np.sin(np.radians(2 * ang)), atol=0.02)


def test_prediction_via_c_library_if_built():
    clib = pytest.importorskip("abbe.model.clib")
    if not clib.available():
        pytest.skip("libabbe.so not built")
    from abbe.formats.blob import write_blob
    tr = make_truth(typical_shapes(), squareness_urad=(30.0, 0.0, 0.0))
    test = paper_circle(sample_deg=3.0)
    tab = truth_table(tr)
    ang = np.arange(0.0, 360.0, 3.0)
    p64 = predict_ballbar(tab, test, ang)
    pc = predict_ballbar(clib.CModel(write_blob(tab)), test, ang)
    print(f"C f32 vs float64 prediction: max {np.abs(pc - p64).max():.4f} um")
    assert np.abs(pc - p64).max() < 0.05
    assert np.ptp(p64) > 5.0


# --------------------------------------------------------------------------- compensation


def test_compensation_in_the_loop():
    tr = make_truth(typical_shapes(), squareness_urad=(30.0, 0.0, 0.0),
                    servo_lag_ms=(5.0, 5.0, 5.0))
    test = paper_circle(radius_mm=80.0, center_mm=(250.0, -200.0, -150.0),
                        feed_mm_min=6000.0, sample_deg=2.0)
    vm = VirtualMachine(tr)
    plain = simulate_ballbar(vm, test)
    zero = run_circle_with_compensation(vm, test, lambda q, d, t: np.zeros(3), cycle_hz=250.0)
    np.testing.assert_allclose(zero.radial_um, plain.radial_um, atol=1e-12)
    comp = run_circle_with_compensation(vm, test, model_compensator_step(truth_table(tr)),
                                        cycle_hz=250.0)
    g0 = evaluate_ballbar(plain, test).both.G_um
    g1 = evaluate_ballbar(comp, test).both.G_um
    print(f"compensated circle (true table, ideal compensator): G {g0:.3f} -> {g1:.3f} um")
    assert g0 > 3.0
    assert g1 < 0.1 * g0


def test_compensation_correction_is_applied_to_the_commanded_position():
    """A constant +2 um x correction moves the circle centre by +2 um in x."""
    tr = make_truth()
    test = paper_circle(radius_mm=20.0, center_mm=(250.0, -200.0, -150.0),
                        feed_mm_min=3000.0, sample_deg=2.0)
    tr_c = run_circle_with_compensation(VirtualMachine(tr), test,
                                        lambda q, d, t: np.array([2e-3, 0.0, 0.0]), cycle_hz=100.0)
    r = evaluate_ballbar(tr_c, test)
    assert r.both.center_um == pytest.approx((2.0, 0.0), abs=1e-6)


# --------------------------------------------------------------------------- CLI


def test_cli_ballbar_on_the_example(tmp_path, capsys):
    png = tmp_path / "bb.png"
    assert main(["ballbar", str(EXAMPLE / "machine.toml"), "circle1", "--json",
                 "-", "--plot", str(png)]) == 0
    d = json.loads(capsys.readouterr().out)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    g = d["bidirectional"]["G_um"]
    print(f"demo circle: G both {g} um, CCW {d['ccw']['G_um']}, CW {d['cw']['G_um']}, "
          f"H {d['H_um']}, centre {d['bidirectional']['center_x_um']}/"
          f"{d['bidirectional']['center_y_um']} um")
    assert 15.0 < g < 25.0          # of the order of the paper's 19.9 um
    assert d["samples"] == {"ccw": 720, "cw": 720}


def _campaign(tmp_path: Path) -> Path:
    import shutil
    dst = tmp_path / "m"
    (dst / "ballbar").mkdir(parents=True)
    shutil.copy(EXAMPLE / "ballbar" / "circle1.csv", dst / "ballbar" / "circle1.csv")
    text = (EXAMPLE / "machine.toml").read_text()
    text = text.split("[laser.X]")[0] + "[ballbar.circle1]" + text.split("[ballbar.circle1]")[1]
    (dst / "machine.toml").write_text(text)
    return dst / "machine.toml"


@pytest.mark.parametrize("old,new,field", [
    ("center_mm = [343.507, -285.09, -286.43]", "center_mm = [443.507, -285.09, -286.43]",
     "ballbar.circle1.radius_mm"),
    ("center_mm = [343.507, -285.09, -286.43]", "center_mm = [643.507, -285.09, -286.43]",
     "ballbar.circle1.center_mm"),
    ("radius_mm = 100.0", "radius_mm = 50.0", "time_s"),
])


def test_cli_ballbar_inconsistent_circle(tmp_path, capsys, old, new, field):
    mf = _campaign(tmp_path)
    text = mf.read_text()
    assert old in text
    mf.write_text(text.replace(old, new))
    assert main(["ballbar", str(mf), "circle1", "--no-plot"]) == 2
    err = capsys.readouterr().err
    assert f"field '{field}'" in err
    if field.startswith("ballbar."):
        line = next(i for i, l in enumerate(mf.read_text().splitlines(), 1)
                    if l.startswith(field.rsplit(".", 1)[1]))
        assert f"{mf}:{line}:" in err
    else:
        assert "circle1.csv:" in err and "radius_mm" in err


def test_cli_ballbar_unknown_test(tmp_path, capsys):
    mf = _campaign(tmp_path)
    assert main(["ballbar", str(mf), "nosuch", "--no-plot"]) == 2
    err = capsys.readouterr().err
    assert str(mf) in err and "field 'ballbar.nosuch'" in err and "circle1" in err


def test_compensation_with_the_c_compensator_if_built():
    clib = pytest.importorskip("abbe.model.clib")
    if not clib.available():
        pytest.skip("libabbe.so not built")
    from abbe.formats.blob import write_blob
    from abbe.sim.compensation import ccompensator_step
    tr = make_truth(typical_shapes(), squareness_urad=(30.0, 0.0, 0.0),
                    backlash_um=(3.0, 3.0, 0.0), backlash_takeup_mm=(0.05, 0.05, 0.05))
    test = paper_circle(radius_mm=80.0, center_mm=(250.0, -200.0, -150.0),
                        feed_mm_min=6000.0, sample_deg=2.0)
    vm = VirtualMachine(tr)
    comp = clib.CCompensator({"warn_nm": 200_000, "limit_nm": 500_000,
                              "rate_nm_per_cycle": 100_000, "fade_cycles": 1,
                              "stale_cycles": 10}, clib.CModel(write_blob(truth_table(tr))))
    comp.enable()
    g0 = evaluate_ballbar(simulate_ballbar(vm, test), test).both.G_um
    trace = run_circle_with_compensation(vm, test, ccompensator_step(comp), cycle_hz=250.0)
    g1 = evaluate_ballbar(trace, test).both.G_um
    print(f"C compensator in the loop: G {g0:.3f} -> {g1:.3f} um")
    assert g0 > 3.0
    assert g1 < 0.15 * g0


def test_temp_c_column_is_read_and_checked(tmp_path):
    """Optional temp_c (deg C per sample): read when present; written by the simulator
    with thermal drift on; a bad or non-finite cell is refused with line and column."""
    tr = make_truth(thermal_rise_k=2.0, thermal_time_constant_s=600.0,
                    thermal_expansion_ppm_per_k=(5.0, 5.0, 5.0))
    trace = simulate_ballbar(VirtualMachine(tr), paper_circle(sample_deg=2.0), start_time_s=300.0,
                             temp_sensor_k=0.0)
    assert trace.temp_c is not None and np.all(np.diff(trace.temp_c) >= 0)
    p = tmp_path / "bb.csv"
    p.write_text(trace.to_csv())
    assert p.read_text().splitlines()[0] == "direction,angle_deg,radial_um,time_s,temp_c"
    back = read_ballbar_csv(p)
    assert np.allclose(back.temp_c, trace.temp_c, atol=1e-3)
    lines = p.read_text().splitlines()
    a = lines[7].split(",")
    a[4] = "nan"
    lines[7] = ",".join(a)
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(AbbeInputError) as ei:
        read_ballbar_csv(p)
    assert (ei.value.line, ei.value.field) == (8, "temp_c")
    # without thermal drift: no temperature column
    plain = simulate_ballbar(VirtualMachine(make_truth()), paper_circle(sample_deg=2.0))
    assert plain.temp_c is None and "temp_c" not in plain.to_csv().splitlines()[0]
