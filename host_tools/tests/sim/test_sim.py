"""Tests of the virtual machine (abbe.sim.truth, abbe.sim.virtual_machine), the 6D laser simulation and the spec."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from abbe.cli.entry import main
from abbe.errors import AbbeInputError
from abbe.model.backlash import backlash_state
from abbe.model.reference import spatial_error, term_values
from abbe.model.table import TERMS
from abbe.sim.campaign import simulate_campaign
from abbe.sim.instruments import simulate_laser_line
from abbe.sim.spec import LaserLinePlan, NoiseSpec, load_spec
from abbe.sim.truth import load_truth, truth_table
from abbe.sim.virtual_machine import VirtualMachine

from textnum import differences
from sim_helpers import EXAMPLE, REF, make_truth, random_positions, typical_shapes

RNG = np.random.default_rng(12345)


def _scaled(truth, k: float):
    for ax in truth.axes.values():
        for t in TERMS:
            ax.coef[t] = ax.coef[t] * k
    return truth


# --------------------------------------------------------------------------- kinematics


def test_linearisation_error_demo_far_below_0p1_um():
    """Exact chain vs Eq. 3 (abbe.model.reference) on the demo machine's true table."""
    truth = load_spec(EXAMPLE / "spec.toml").truth()
    vm = VirtualMachine(truth)
    pos = random_positions(3000, seed=3)
    ds = RNG.choice([-1.0, 1.0], size=(3000, 3))
    t = RNG.random(3000) * 20000.0
    exact = vm.tool_error_um(pos, ds, t)
    temp = np.repeat(truth.temperature_c(t)[:, None], 3, axis=1)
    lin = spatial_error(truth_table(truth), pos, ds, temp)
    diff = float(np.max(np.abs(exact - lin)))
    print(f"demo linearisation error: max {diff:.3e} um (max |E| {np.abs(exact).max():.2f} um)")
    assert np.abs(exact).max() > 5.0      # a real machine error, not zero
    assert diff < 0.01                    # far below 0.1 um


def test_linearisation_error_is_second_order():
    """Scaling every error by k scales (exact - Eq. 3) by k^2: the chain is really nonlinear."""
    pos = random_positions(500, seed=4)
    diffs = []
    for k in (1.0, 30.0):
        truth = _scaled(make_truth(typical_shapes(), squareness_urad=(30.0, 10.0, -8.0),
                                   tool_offset_mm=(10.0, -20.0, -120.0)), k)
        truth.effects.squareness_urad = tuple(k * v for v in truth.effects.squareness_urad)
        exact = VirtualMachine(truth).tool_error_um(pos)
        lin = spatial_error(truth_table(truth), pos)
        diffs.append(np.max(np.abs(exact - lin)))
    ratio = diffs[1] / diffs[0]
    assert 0.8 * 900 < ratio < 1.25 * 900, (diffs, ratio)


def test_exact_rotation_of_the_table():
    """A large yaw of X (mrad) against the closed-form rotated workpiece point."""
    truth = make_truth({"X": {"ez": {"slope_urad_per_m": 20000.0}}})
    pos = random_positions(200, seed=5)
    e = VirtualMachine(truth).tool_error_um(pos)
    x, y, z = (pos - np.array(REF)).T
    a = 20000.0 * 1e-3 * x * 1e-6  # rad
    ex = (-x * (1 - np.cos(a)) - y * np.sin(a)) * 1e3
    ey = (-y * (1 - np.cos(a)) + x * np.sin(a)) * 1e3
    np.testing.assert_allclose(e[:, 0], ex, atol=1e-6)
    np.testing.assert_allclose(e[:, 1], ey, atol=1e-6)
    np.testing.assert_allclose(e[:, 2], 0.0, atol=1e-6)
    lin = spatial_error(truth_table(truth), pos)
    assert np.max(np.abs(lin - e)) > 1.0  # the linearisation is visibly off at mrad


@pytest.mark.parametrize("case", ["Ydx", "Zdy", "Yez", "Sxy", "Syz", "tool_Zey", "Xey"])
def test_sign_conventions_single_terms(case):
    """Eq. 3 written out by hand (notes.md §1) for one term at a time."""
    pos = random_positions(300, seed=6)
    x, y, z = ((pos - np.array(REF)) * 1e-3).T  # mm * urad * 1e-3 = um
    if case == "Ydx":
        tr = make_truth({"Y": {"dx": {"bow_um": 7.0}}})
        exp = np.stack([-tr.term_values("Y", "dx", pos[:, 1]), 0 * x, 0 * x], axis=1)
    elif case == "Zdy":
        tr = make_truth({"Z": {"dy": {"bow_um": 5.0}}})
        exp = np.stack([0 * x, tr.term_values("Z", "dy", pos[:, 2]), 0 * x], axis=1)
    elif case == "Yez":
        tr = make_truth({"Y": {"ez": {"slope_urad_per_m": 80.0}}})
        exp = np.stack([-y * tr.term_values("Y", "ez", pos[:, 1]), 0 * x, 0 * x], axis=1)
    elif case == "Sxy":
        tr = make_truth(squareness_urad=(40.0, 0.0, 0.0))
        exp = np.stack([y * 40.0, 0 * x, 0 * x], axis=1)
    elif case == "Syz":
        tr = make_truth(squareness_urad=(0.0, 0.0, 25.0))
        exp = np.stack([0 * x, -z * 25.0, 0 * x], axis=1)
    elif case == "Xey":
        tr = make_truth({"X": {"ey": {"bow_urad": 30.0}}})
        eps = tr.term_values("X", "ey", pos[:, 0])
        exp = np.stack([-z * eps, 0 * x, -x * eps], axis=1)
    else:  # tool offset t_z with Z pitch: dX += t_z eps_zy, dZ -= t_x ... (t_x = 0)
        tr = make_truth({"Z": {"ey": {"bow_urad": 30.0}}}, tool_offset_mm=(0.0, 0.0, -100.0))
        eps = tr.term_values("Z", "ey", pos[:, 2])
        exp = np.stack([-100.0 * 1e-3 * eps, 0 * x, 0 * x], axis=1)
    got = VirtualMachine(tr).tool_error_um(pos)
    np.testing.assert_allclose(got, exp, atol=2e-3)
    assert np.abs(exp).max() > 0.5


def test_truth_shapes():
    """Shapes: relative to the reference, bow/wave/slope exact, straightness detrended."""
    tr = make_truth({"X": {"dx": {"slope_um_per_m": 12.0, "bow_um": 3.0, "wave_um": [2.0],
                                  "wave_phase_deg": [30.0]},
                           "dy": {"bow_um": 4.0, "wave_um": [1.5], "cantilever_um": 2.0}}},
                    wave_period_mm={"X": 125.0})
    p = np.linspace(0.0, 500.0, 5001)
    u = (2 * p - 500.0) / 500.0

    def raw(q):
        uq = (2 * q - 500.0) / 500.0
        return (12.0e-3 * (q - REF[0]) + 3.0 * (1 - uq ** 2)
                + 2.0 * np.sin(2 * np.pi * q / 125.0 + math.radians(30.0)))
    np.testing.assert_allclose(tr.term_values("X", "dx", p), raw(p) - raw(np.array([REF[0]])),
                               atol=1e-9)
    s = (1 + u) / 2
    g = 4.0 * (1 - u ** 2) + 1.5 * np.sin(2 * np.pi * p / 125.0) + 2.0 * s ** 2 * (3 - s) / 2
    line = np.polyval(np.polyfit(p, g, 1), p)
    dy = tr.term_values("X", "dy", p)
    ref_val = np.interp(REF[0], p, g - line)
    np.testing.assert_allclose(dy, g - line - ref_val, atol=2e-3)
    assert abs(np.polyfit(p, dy, 1)[0]) < 1e-6
    assert abs(tr.term_values("X", "dy", np.array([REF[0]]))[0]) < 1e-12
    tab = truth_table(tr)
    for t in TERMS:
        np.testing.assert_allclose(term_values(tab, "X", t, p), tr.term_values("X", t, p),
                                   atol=1e-12)


def test_backlash_state_ramps_over_takeup():
    p = np.array([0.0, 1.0, 2.0, 1.9, 1.85, 1.7, 1.7, 3.0])
    s = backlash_state(p, 0.2, -1.0)
    np.testing.assert_allclose(s, [-1.0, 1.0, 1.0, 0.0, -0.5, -1.0, -1.0, 1.0], atol=1e-12)


# --------------------------------------------------------------------------- laser


def _plan(axis: str, start, end, **kw) -> LaserLinePlan:
    from abbe.sim.spec import DEFAULT_MAPS
    d = dict(axis=axis, file=f"laser/{axis.lower()}.csv", start_mm=tuple(start),
             end_mm=tuple(end), map=dict(DEFAULT_MAPS[axis]))
    d.update(kw)
    return LaserLinePlan(**d)


X_LINE = ((0.0, REF[1], REF[2]), (500.0, REF[1], REF[2]))
Y_LINE = ((REF[0], 0.0, REF[2]), (REF[0], -400.0, REF[2]))
Z_LINE = ((243.22, -294.885, 0.0), (243.22, -294.885, -300.0))


@pytest.mark.parametrize("axis,line", [("X", X_LINE), ("Y", Y_LINE)])
def test_laser_line_through_reference_reads_the_terms(axis, line):
    tr = make_truth(typical_shapes())
    plan = _plan(axis, *line, runs=1)
    run = simulate_laser_line(VirtualMachine(tr), plan, 0.0, NoiseSpec(), RNG)
    j = "XYZ".index(axis)
    p = run.target_mm
    for ch, (sign, term) in plan.parsed_map().items():
        v = tr.term_values(axis, term, p)
        np.testing.assert_allclose(run.channels[ch], sign * (v - v[0]), atol=1e-6,
                                   err_msg=f"{axis} {ch}")
    assert np.ptp(run.channels["linear"]) > 1.0
    assert run.pos_mm[:, j].tolist() == p.tolist()


def test_laser_z_line_offset_from_reference():
    """The Z line stands off the reference point: linear and angles read the Z terms, the
    straightness only gains a line (table tilt at the line's x, y)."""
    tr = make_truth(typical_shapes())
    plan = _plan("Z", *Z_LINE, runs=1)
    run = simulate_laser_line(VirtualMachine(tr), plan, 0.0, NoiseSpec(), RNG)
    p = run.target_mm
    for ch, (sign, term) in plan.parsed_map().items():
        v = sign * tr.term_values("Z", term, p)
        got = run.channels[ch] - run.channels[ch][0]
        exp = v - v[0]
        if ch.startswith("straight"):
            got = got - np.polyval(np.polyfit(p, got, 1), p)
            exp = exp - np.polyval(np.polyfit(p, exp, 1), p)
        np.testing.assert_allclose(got, exp, atol=2e-3, err_msg=ch)


def test_laser_offset_x_line_sees_abbe_terms():
    """X line 100 mm above and 50 mm beside the reference: the linear channel reads
    d_x + z0 eps_xy + y0 eps_xz = -dX of Eq. 3 (varying part)."""
    tr = make_truth(typical_shapes())
    y0, z0 = REF[1] - 50.0, REF[2] + 100.0
    plan = _plan("X", (0.0, y0, z0), (500.0, y0, z0), runs=1)
    run = simulate_laser_line(VirtualMachine(tr), plan, 0.0, NoiseSpec(), RNG)
    p = run.target_mm
    exp = (tr.term_values("X", "dx", p) + 100.0e-3 * tr.term_values("X", "ey", p)
           + (-50.0e-3) * tr.term_values("X", "ez", p))
    np.testing.assert_allclose(run.channels["linear"], exp - exp[0], atol=2e-3)
    pos = np.stack([p, np.full_like(p, y0), np.full_like(p, z0)], axis=1)
    mdx = -spatial_error(truth_table(tr), pos)[:, 0]
    np.testing.assert_allclose(run.channels["linear"], mdx - mdx[0], atol=2e-3)
    abbe = 100.0e-3 * tr.term_values("X", "ey", p)
    assert np.ptp(abbe) > 0.5  # the Abbe part is really there


@pytest.mark.parametrize("axis,line,sign", [("X", X_LINE, 1.0), ("Z", Z_LINE, -1.0)])
def test_laser_backlash_reversal(axis, line, sign):
    """Lost motion b: ISO reversal of the own positioning term is +b on X, -b on Z,
    and equals the true table's backlash_um."""
    b = 4.0
    tr = make_truth(backlash_um=(b, b, b), backlash_takeup_mm=(0.2, 0.2, 0.2))
    plan = _plan(axis, *line, runs=2, overrun_mm=1.0)
    run = simulate_laser_line(VirtualMachine(tr), plan, 0.0, NoiseSpec(), RNG)
    lin = run.channels["linear"]
    up = lin[run.direction == "+"].reshape(2, -1)
    down = lin[run.direction == "-"].reshape(2, -1)[:, ::-1]
    rev = up.mean(axis=0) - down.mean(axis=0)
    np.testing.assert_allclose(rev, sign * b, atol=1e-9)
    assert truth_table(tr).axes[axis].backlash_um == pytest.approx(sign * b)


def test_laser_csv_structure_and_timing():
    tr = make_truth(typical_shapes(), thermal_rise_k=1.0, thermal_expansion_ppm_per_k=(5, 5, 5))
    plan = _plan("X", *X_LINE, runs=5, dwell_s=4.0, feed_mm_min=200.0)
    run = simulate_laser_line(VirtualMachine(tr), plan, 0.0, NoiseSpec(), RNG)
    lines = run.to_csv().splitlines()
    assert lines[0] == ("run,direction,target_mm,linear_um,straight_h_um,straight_v_um,"
                        "pitch_urad,yaw_urad,roll_urad,time_s,temp_c")
    assert len(lines) == 1 + 5 * 2 * 51
    assert list(run.run[:102]) == [1] * 102 and run.run[-1] == 5
    assert list(run.direction[:51]) == ["+"] * 51 and list(run.direction[51:102]) == ["-"] * 51
    assert np.all(np.diff(run.target_mm[:51]) == 10.0)
    assert np.all(np.diff(run.target_mm[51:102]) == -10.0)
    dt = np.diff(run.time_s[:51])
    np.testing.assert_allclose(dt, 10.0 / (200.0 / 60.0) + 4.0)
    assert np.all(np.diff(run.time_s) > 0)
    tr2 = make_truth(typical_shapes())
    run2 = simulate_laser_line(VirtualMachine(tr2), plan, 0.0, NoiseSpec(), RNG)
    assert "temp_c" not in run2.to_csv().splitlines()[0]


def test_laser_misalignment_adds_only_a_line():
    tr = make_truth(typical_shapes())
    vm = VirtualMachine(tr)
    base = simulate_laser_line(vm, _plan("X", *X_LINE, runs=1), 0.0, NoiseSpec(), RNG)
    mis = simulate_laser_line(vm, _plan("X", *X_LINE, runs=1, misalignment_urad=(80.0, -40.0)),
                              0.0, NoiseSpec(), RNG)
    p = base.target_mm
    for ch, a in (("straight_h", 80.0), ("straight_v", -40.0)):
        d = mis.channels[ch] - base.channels[ch]
        slope = np.polyfit(p, d, 1)[0]
        assert abs(abs(slope) - abs(a) * 1e-3) < 1e-4 * abs(a) * 1e-3
        # beyond the line only the tilt x (deviation) cross-talk: nanometres
        assert np.max(np.abs(d - np.polyval(np.polyfit(p, d, 1), p))) < 2e-3


def test_laser_thermal_drift_and_temperature():
    tr = make_truth(thermal_rise_k=2.0, thermal_time_constant_s=3600.0, thermal_start_c=20.0,
                    thermal_expansion_ppm_per_k=(10.0, 0.0, 0.0),
                    thermal_offset_um_per_k=(1.0, 0.0, 0.0))
    plan = _plan("X", *X_LINE, runs=3)
    t0 = 1000.0
    run = simulate_laser_line(VirtualMachine(tr), plan, t0, NoiseSpec(), RNG)
    temp = 20.0 + 2.0 * (1 - np.exp(-(t0 + run.time_s) / 3600.0))
    np.testing.assert_allclose(run.temp_c, temp, atol=1e-12)
    f = 10.0 * (temp - 20.0) * (run.target_mm - REF[0]) * 1e-3 + 1.0 * (temp - 20.0)
    np.testing.assert_allclose(run.channels["linear"], f - f[0], atol=1e-6)
    assert np.ptp(f) > 1.0


def test_laser_noise_and_repeatability_statistics():
    tr = make_truth()
    noise = NoiseSpec(laser_linear_um=0.2, laser_straightness_um=0.5, laser_angle_urad=0.3,
                      repeatability_um=(0.4, 0.0, 0.0))
    run = simulate_laser_line(VirtualMachine(tr), _plan("X", *X_LINE), 0.0, noise,
                              np.random.default_rng(7))
    sd_lin = np.std(run.channels["linear"] - run.channels["linear"].mean())
    assert abs(sd_lin - math.hypot(0.2, 0.4)) < 0.05
    assert abs(np.std(run.channels["straight_h"]) - 0.5) < 0.06
    assert abs(np.std(run.channels["roll"]) - 0.3) < 0.04


# --------------------------------------------------------------------------- spec


SPEC_OK = """\
[machine]
name = "m1"
seed = 7
travel_mm = { X = [0.0, 200.0], Y = [-150.0, 0.0], Z = [-100.0, 0.0] }
reference_mm = [100.0, -75.0, -50.0]

[errors.X]
dx = { slope_um_per_m = 10.0, wave_um = [2.0] }
dy = { bow_um = 3.0 }

[effects.squareness]
xy_urad = 20.0

[effects.backlash]
lost_motion_um = [2.0, 2.0, 1.0]
takeup_mm = [0.2, 0.2, 0.2]

[noise]
ballbar_um = 0.1

[laser.X]
start_mm = [0.0, -75.0, -50.0]
end_mm = [200.0, -75.0, -50.0]
spacing_mm = 20.0
runs = 2
dwell_s = 1.0

[ballbar.c]
plane = "XY"
center_mm = [100.0, -75.0, -50.0]
radius_mm = 50.0
feed_mm_min = 3000.0
sample_deg = 2.0
"""


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "spec.toml"
    p.write_text(text)
    return p


def _line_of(text: str, needle: str) -> int:
    for no, line in enumerate(text.splitlines(), start=1):
        if needle in line:
            return no
    raise AssertionError(needle)


@pytest.mark.parametrize("old,new,field,needle", [
    ("takeup_mm = [0.2, 0.2, 0.2]", "takeup_mm = [0.2, 0.2, 0.2]\nlostmotion_um = 3.0",
     "effects.backlash.lostmotion_um", "lostmotion_um"),
    ("xy_urad = 20.0", "xy_urad = 5000.0", "effects.squareness.xy_urad", "xy_urad"),
    ("dy = { bow_um = 3.0 }", "dy = { slope_um_per_m = 3.0 }", "errors.X.dy.slope_um_per_m",
     "dy = {"),
    ("end_mm = [200.0, -75.0, -50.0]", "end_mm = [260.0, -75.0, -50.0]", "laser.X.end_mm",
     "end_mm = [260"),
    ("radius_mm = 50.0", "radius_mm = 90.0", "ballbar.c.radius_mm", "radius_mm"),
    ("lost_motion_um = [2.0, 2.0, 1.0]", "lost_motion_um = [2.0, -2.0, 1.0]",
     "effects.backlash.lost_motion_um", "lost_motion_um"),
    ("dwell_s = 1.0", "dwell_s = 1.0\nmap = { linear = \"+dy\", straight_h = \"+dx\", "
     "straight_v = \"+dz\", pitch = \"-ey\", yaw = \"-ez\", roll = \"+ex\" }",
     "laser.X.map.linear", "map = {"),
    ("[noise]", "[nosie]", "nosie", "[nosie]"),
    ("wave_um = [2.0]", "wave_um = [2.0, 1, 1, 1, 1, 1, 1, 1, 1]", "errors.X.dx.wave_um",
     "dx = {"),
])


def test_spec_errors_name_file_line_field(tmp_path, old, new, field, needle):
    assert old in SPEC_OK
    text = SPEC_OK.replace(old, new)
    p = _write(tmp_path, text)
    with pytest.raises(AbbeInputError) as ei:
        load_spec(p)
    e = ei.value
    assert e.file == str(p)
    assert e.field == field
    assert e.line == _line_of(text, needle)


def test_spec_missing_seed(tmp_path):
    p = _write(tmp_path, SPEC_OK.replace("seed = 7\n", ""))
    with pytest.raises(AbbeInputError) as ei:
        load_spec(p)
    assert ei.value.field == "machine" and "seed" in ei.value.message and ei.value.line == 1


def test_spec_enabled_false_switches_an_effect_off(tmp_path):
    p = _write(tmp_path, SPEC_OK.replace("xy_urad = 20.0", "enabled = false\nxy_urad = 20.0"))
    assert load_spec(p).effects.squareness_urad == (0.0, 0.0, 0.0)
    assert load_spec(_write(tmp_path, SPEC_OK)).effects.squareness_urad == (20.0, 0.0, 0.0)


def test_cli_simulate_small_campaign_is_readable_by_the_shared_readers(tmp_path):
    from abbe.analysis.iso230_2 import evaluate
    from abbe.formats.laser_csv import read_laser_csv
    from abbe.formats.machine import load_machine
    from abbe.formats.positioning import load_positioning

    spec = _write(tmp_path, SPEC_OK)
    out = tmp_path / "out"
    assert main(["simulate", str(spec), "-o", str(out)]) == 0
    m = load_machine(out / "machine.toml")
    assert set(m.laser) == {"X"} and set(m.ballbar) == {"c"}
    data = read_laser_csv(m.laser["X"].file)
    assert data.n_runs == 2 and data.targets_mm.size == 11
    res = evaluate(load_positioning(m.laser["X"].file))
    assert res.to_json()["B_um"] == pytest.approx(2.0, abs=1e-3)  # lost motion of X
    truth = load_truth(out / "truth" / "truth.json")
    assert truth.effects.squareness_urad == (20.0, 0.0, 0.0)
    pos = random_positions(50)
    pos = np.clip(pos, [0, -150, -100], [200, 0, 0])
    np.testing.assert_allclose(VirtualMachine(truth).tool_error_um(pos),
                               VirtualMachine(load_spec(spec).truth()).tool_error_um(pos),
                               atol=1e-12)


def test_cli_simulate_bad_spec_writes_nothing(tmp_path, capsys):
    spec = _write(tmp_path, SPEC_OK.replace("xy_urad = 20.0", "xy_urad = 20000.0"))
    out = tmp_path / "out"
    assert main(["simulate", str(spec), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{spec}:{_line_of(SPEC_OK, 'xy_urad')}: field 'effects.squareness.xy_urad'" in err
    assert not out.exists()


def test_example_regenerates():
    """examples/vmc500 was written by `abbe simulate spec.toml -o .`: the same files again,
    every character equal except the last digit of a number (docs/formats.md,
    "Reproducibility": float64 kernels differ between CPUs)."""
    files = simulate_campaign(load_spec(EXAMPLE / "spec.toml"))
    assert {"machine.toml", "laser/x.csv", "laser/y.csv", "laser/z.csv", "ballbar/circle1.csv",
            "truth/truth.json", "truth/true_table.json"} == set(files)
    for rel, data in files.items():
        assert differences((EXAMPLE / rel).read_text(), data.decode()) == [], rel


def test_scale_change_switches_on_at_its_time():
    tr = make_truth(scale_change_ppm=(20.0, 0.0, 0.0), scale_change_from_s=1000.0)
    pos = random_positions(100, seed=8)
    vm = VirtualMachine(tr)
    before = vm.tool_error_um(pos, time_s=np.full(100, 999.0))
    after = vm.tool_error_um(pos, time_s=np.full(100, 1000.0))
    np.testing.assert_allclose(before, 0.0, atol=1e-12)
    # d_x(x) += ppm (x - ref) 1e-3 um; dX = -d_x(x)
    np.testing.assert_allclose(after[:, 0], -20.0e-3 * (pos[:, 0] - REF[0]), atol=1e-6)


def test_unmodelled_tool_offset_is_in_the_truth_not_in_the_machine_file(tmp_path):
    tr = make_truth({"X": {"ey": {"bow_urad": 40.0}}}, tool_offset_mm=(0.0, 0.0, -100.0))
    pos = random_positions(100, seed=9)
    vm = VirtualMachine(tr)
    e_true = vm.tool_error_um(pos)
    e_decl = vm.tool_error_um(pos, tool_offset_mm=np.zeros(3))
    eps = tr.term_values("X", "ey", pos[:, 0])
    # dX += t_z (eps_zy - eps_xy - eps_yy) = -t_z eps_xy
    np.testing.assert_allclose(e_true[:, 0] - e_decl[:, 0], 100.0e-3 * eps, atol=1e-4)
    assert truth_table(tr).tool_offset_mm == (0.0, 0.0, -100.0)
    assert truth_table(tr, include=("squareness",)).tool_offset_mm == (0.0, 0.0, 0.0)
