"""Five-axis identification on virtual campaigns (abbe.sim.five_axis): observable errors
within their intervals, unobservable ones named without a number, the CLI's outputs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from abbe.analysis.five_axis.data import load_plan
from abbe.analysis.five_axis.identify import identify
from abbe.analysis.five_axis.problem import build_params
from abbe.analysis.five_axis.spheres import fit_sphere
from abbe.cli.entry import main
from abbe.errors import AbbeInputError
from abbe.formats.machine import load_machine
from abbe.model.five_axis import TrunnionGeometry
from abbe.sim.five_axis import VirtualFiveAxis, probing_positions, random_errors, write_campaign


def _geom(kind: str) -> TrunnionGeometry:
    off = (0.0, 20.0, -80.0) if kind == "xyzac-trt" else (15.0, 0.0, -80.0)
    tilt = "A" if kind == "xyzac-trt" else "B"
    return TrunnionGeometry(kind, (0.0, 0.0, -300.0), off, 120.0,
                            {tilt: (-110.0, 110.0), "C": (-360.0, 360.0)})


def _campaign(tmp: Path, kind: str, seed: int, **kw) -> tuple[Path, VirtualFiveAxis]:
    g = _geom(kind)
    rng = np.random.default_rng(seed)
    vm = VirtualFiveAxis(g, random_errors(g, rng), sphere_offset_mm=(0.05, -0.03, 0.02),
                         sphere_radius_error_mm=0.001, probe_noise_um=0.5, seed=seed, **kw)
    return write_campaign(vm, tmp, positions=probing_positions(g, 4, 8),
                          sphere_mm=(60.0, 0.0, 30.0)), vm


def test_sphere_fit_recovers_centre_and_radius() -> None:
    rng = np.random.default_rng(0)
    d = rng.normal(size=(9, 3))
    d[:, 2] = np.abs(d[:, 2])  # an upper cap, as a probe reaches it
    d /= np.linalg.norm(d, axis=1)[:, None]
    c, r, rms = fit_sphere(np.array([10.0, -5.0, 3.0]) + 14.0 * d)
    assert np.allclose(c, [10.0, -5.0, 3.0], atol=1e-9) and abs(r - 14.0) < 1e-9 and rms < 1e-6


@pytest.mark.parametrize("kind", ["xyzac-trt", "xyzbc-trt"])
def test_location_errors_within_their_intervals(tmp_path: Path, kind: str) -> None:
    mf, vm = _campaign(tmp_path, kind, seed=11)
    spec = load_machine(mf).five_axis
    plan = load_plan(spec)
    params = build_params(spec, plan.blocks)
    res = identify(spec, plan.blocks, params)
    n_obs = 0
    for i, p in enumerate(params):
        if p.kind != "location":
            continue
        if res.obs.observable[i]:
            n_obs += 1
            tol = max(1.96 * res.sd[i], 1.0 if p.unit == "um" else 5.0)
            assert abs(res.x[i] - vm.errors.location[p.name]) <= tol, p.name
        else:
            assert np.isnan(res.x[i]) and np.isnan(res.sd[i])  # never a number
    assert n_obs >= 5
    # The angular zero of C is confounded with the sphere's place on the table.
    ec0c = [i for i, p in enumerate(params) if p.name == "EC0C"][0]
    assert not res.obs.observable[ec0c]
    assert res.dispersion_after_um < res.dispersion_before_um / 5
    assert res.heldout_after_um < res.heldout_before_um / 5
    assert res.obs.rank < len(params) and np.isfinite(res.obs.condition)


def test_cli_writes_the_report_and_refuses_bad_files(tmp_path: Path, capsys) -> None:
    mf, _vm = _campaign(tmp_path / "c", "xyzac-trt", seed=3)
    out = tmp_path / "out"
    assert main(["fit", str(mf), "-o", str(out)]) == 0
    doc = json.loads((out / "five_axis.json").read_text())
    assert doc["kinematics"] == "xyzac-trt"
    assert doc["table"]["location"]["EC0C"] is None  # unobservable: no number
    ec0c = [r for r in doc["parameters"] if r["name"] == "EC0C"][0]
    assert ec0c["seen_by"] and ec0c["confounded_with"]
    assert (out / "report" / "index.html").exists() and "NOT OBSERVABLE" in (
        out / "report.txt").read_text()
    # A corrupted probing file: exit 2, the old output kept.
    probe = tmp_path / "c" / "probe.csv"
    lines = probe.read_text().splitlines()
    lines[3] = lines[3].replace(",", ",NaN", 1)
    probe.write_text("\n".join(lines) + "\n")
    assert main(["fit", str(mf), "-o", str(out)]) == 2
    assert "probe.csv:4" in capsys.readouterr().err
    assert json.loads((out / "five_axis.json").read_text()) == doc


def test_radius_check_rejects_a_bad_position(tmp_path: Path) -> None:
    mf, _vm = _campaign(tmp_path, "xyzac-trt", seed=4)
    probe = tmp_path / "probe.csv"
    rows = probe.read_text().splitlines()
    # Position 0's points 0.05 mm further from their centre: its fit misses the radius.
    pts = np.array([[float(v) for v in r.split(",")[4:]] for r in rows[1:8]])
    c, _r, _q = fit_sphere(pts)
    pts = c + (pts - c) * (1.0 + 0.05 / np.linalg.norm(pts - c, axis=1))[:, None]
    for k in range(7):
        cells = rows[1 + k].split(",")
        rows[1 + k] = ",".join(cells[:4] + [f"{v:.6f}" for v in pts[k]])
    probe.write_text("\n".join(rows) + "\n")
    plan = load_plan(load_machine(mf).five_axis)
    assert [r[:2] for r in plan.rejected] == [("S1", 0)]
    assert len(plan.blocks[0].obs) == 31


def test_too_few_good_positions_is_an_input_error(tmp_path: Path) -> None:
    mf, _vm = _campaign(tmp_path, "xyzac-trt", seed=4)
    text = mf.read_text().replace("sphere_radius_mm = 12.5", "sphere_radius_mm = 13.5")
    mf.write_text(text)
    with pytest.raises(AbbeInputError, match="pass the radius check"):
        load_plan(load_machine(mf).five_axis)


def test_a_plan_smaller_than_its_unknowns_still_answers(tmp_path: Path) -> None:
    """3 probing positions (9 residuals) for 13 unknowns: rank and unobservable errors named,
    no crash."""
    g = _geom("xyzac-trt")
    vm = VirtualFiveAxis(g, random_errors(g, np.random.default_rng(1)), probe_noise_um=0.3)
    mf = write_campaign(vm, tmp_path, positions=np.array([[0.0, 0.0], [30.0, 90.0], [-30.0, 200.0]]),
                        sphere_mm=(60.0, 0.0, 30.0))
    spec = load_machine(mf).five_axis
    plan = load_plan(spec)
    res = identify(spec, plan.blocks, build_params(spec, plan.blocks))
    assert res.obs.rank <= 9 and (~res.obs.observable).sum() >= 4
    assert np.all(np.isnan(res.x[~res.obs.observable]))
