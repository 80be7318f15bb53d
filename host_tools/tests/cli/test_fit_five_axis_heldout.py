"""End to end (issue 33): campaigns of the INDEPENDENT generator
(cases/five_axis_independent.py, seeds no other test uses) -> ``abbe fit`` (the command,
a fitted table, never the truth) -> the C library evaluates model_five.bin at poses
outside the plan -> compared with the generator's truth, the best rigid placement of the
workpiece fitted out (a probing plan cannot see it; a workpiece datum absorbs it,
cases/five_axis_heldout.py).

Done when: the median residual over the campaigns is <= 5 % of the uncompensated RMS
(and every campaign <= 10 %), and the table re-predicts the campaign it was fitted from
within 1.5 x the reported "after" dispersion, both as the report states it (through the
C library) and recomputed here from the generator's noise-free centres.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from abbe.cli.entry import main
from abbe.model import clib
from abbe.model.clib import CFiveModel
from cases.five_axis_heldout import judge, rigid_residual, rms
from cases.five_axis_independent import make_campaign, rodrigues

pytestmark = pytest.mark.skipif(not clib.available(), reason="C library not built")

#: (seed, plan): seeds 900.. are used nowhere else; even seeds A/C, odd B/C
CASES = [(900, "probe"), (901, "probe"), (902, "ballbar"), (903, "ballbar"),
         (904, "rtest"), (905, "rtest")]


def _campaign(seed: int, plan: str):
    camp = make_campaign(seed)
    camp.rtest = plan == "rtest"
    camp.ballbar = plan == "ballbar"
    return camp


def _fit(camp, work: Path) -> tuple[dict, bytes]:
    mf = camp.write(work / "case")
    out = work / "out"
    assert main(["fit", str(mf), "-o", str(out), "--no-report", "--quiet"]) == 0
    doc = json.loads((out / "five_axis.json").read_text(encoding="utf-8"))
    return doc, (out / "model_five.bin").read_bytes()


def _truth_centres_left(camp, blob: bytes) -> float:
    """The generator's noise-free sphere centres at the plan's poses (its own kinematics)
    re-predicted through the table by the C library, the sphere's place refitted (RMS um)."""
    s_true = camp.sphere_nominal + camp.sphere_shift_mm
    ang = np.array(camp.positions())
    m = np.array([camp.actual(s_true, a, c, 900.0) for a, c in ang])
    kt = np.eye(3)[0 if camp.tilt == "A" else 1]
    R = np.array([rodrigues(kt, math.radians(a)) @ rodrigues(np.array([0.0, 0.0, 1.0]),
                                                             math.radians(c)) for a, c in ang])
    # the nominal transform x -> R x + t: t is where it takes the origin
    t = np.array([camp.nominal(np.zeros(3), a, c) for a, c in ang])
    model = CFiveModel(blob)
    s = camp.sphere_nominal.copy()
    for _ in range(2):
        e = model.error_f32(np.einsum("nij,j->ni", R, s) + t, ang)[0] * 1e-3
        s = np.mean(np.einsum("nji,nj->ni", R, m + e - t), axis=0)
    return rms((m - (np.einsum("nij,j->ni", R, s) + t - e)) * 1e3)


@pytest.fixture(scope="module")
def results(tmp_path_factory) -> list[dict]:
    out = []
    for seed, plan in CASES:
        camp = _campaign(seed, plan)
        doc, blob = _fit(camp, tmp_path_factory.mktemp(f"h{seed}"))
        h = judge(camp, blob, n=200, seed=seed)
        out.append({"seed": seed, "plan": plan, "kind": camp.kind, "h": h, "doc": doc,
                    "truth_left": _truth_centres_left(camp, blob)})
    return out


def test_the_table_compensates_held_out_poses(results) -> None:
    ratios = [r["h"].ratio for r in results]
    for r in results:
        h = r["h"]
        assert h.uncompensated_rms_um > 10.0  # the machines have errors to compensate
        assert h.ratio <= 0.10, (r["seed"], r["plan"], r["kind"], h)
    assert float(np.median(ratios)) <= 0.05, ratios
    kinds = {(r["kind"], r["plan"]) for r in results}
    assert len(kinds) == 6  # A/C and B/C x probing, + ballbar, + R-test


def test_the_table_repredicts_its_campaign(results) -> None:
    for r in results:
        d, rp = r["doc"]["dispersion_um"], r["doc"]["blob"]["repredicted"]
        assert rp["evaluated_by"].startswith("C library")
        assert rp["before"] > 10.0 * rp["after"]
        assert rp["after"] <= 1.5 * d["after"], (r["seed"], rp, d)
        # recomputed here from the generator's noise-free centres
        assert r["truth_left"] <= 1.5 * d["after"], (r["seed"], r["truth_left"], d)


def test_the_convention_is_stated(results) -> None:
    for r in results:
        cv = r["doc"]["blob"]["convention"]
        tilt = "A" if r["kind"] == "xyzac-trt" else "B"
        assert {f"E{tilt}0{tilt}", "EC0C"} <= set(cv["fixed_at_zero"])
        line = {"A": ("EY0C", "EA0C"), "B": ("EX0C", "EB0C")}[tilt]
        held = cv["determined_in_convention"]
        assert set(line) <= set(held), held
        assert all(math.isfinite(v) for v in held.values())
        assert "workpiece datum" in cv["workpiece_datum"]


def test_a_bc_machine_with_only_ex0c_is_compensated(tmp_path: Path) -> None:
    """Issue 33's focused case: EX0C = 30 um alone on a B/C machine (the fit's convention
    cannot see it alone; the table used to leave all 30 um)."""
    camp = make_campaign(907)
    assert camp.kind == "xyzbc-trt"
    camp.loc = {k: 0.0 for k in camp.loc} | {"EX0C": 30.0}
    camp.motions, camp.drift_um_per_h, camp.rtest, camp.ballbar = {}, 0.0, False, False
    doc, blob = _fit(camp, tmp_path)
    h = judge(camp, blob, n=200, seed=907)
    assert h.uncompensated_rms_um > 20.0
    assert h.residual_rigid_rms_um <= 0.05 * h.uncompensated_rms_um, h
    rp = doc["blob"]["repredicted"]
    assert rp["after"] <= 1.5 * doc["dispersion_um"]["after"], (rp, doc["dispersion_um"])


def test_rigid_residual_removes_a_placement_and_only_it() -> None:
    """The judge's placement fit takes out a rigid placement exactly, and leaves an error a
    placement cannot make (a tilt-dependent shift) mostly in place."""
    rng = np.random.default_rng(5)
    w = rng.uniform(-100, 100, (50, 3))
    ang = rng.uniform(-80, 80, (50, 2))
    R = np.array([rodrigues(np.array([1.0, 0, 0]), math.radians(a))
                  @ rodrigues(np.array([0, 0, 1.0]), math.radians(c)) for a, c in ang])
    om, tau = np.array([20e-6, -10e-6, 30e-6]), np.array([5.0, -3.0, 2.0])  # rad, um
    placed = np.einsum("nij,nj->ni", R, np.cross(om, w) * 1e3 + tau)
    assert rms(rigid_residual(placed, w, R, np.zeros(3))) < 1e-9
    other = np.column_stack([10.0 * np.sin(np.deg2rad(ang[:, 0])), np.zeros(50), np.zeros(50)])
    assert rms(rigid_residual(other, w, R, np.zeros(3))) > 0.5 * rms(other)
