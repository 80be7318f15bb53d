"""The five-axis identification judged on the independent generator (a seeded subset of
bench/bench_five_axis.py's suite; never used to tune)."""

from __future__ import annotations

from pathlib import Path

from cases.five_axis_suite import run_suite, summary

#: A/C and B/C, with and without R-test and hidden error motions (seed % 2, % 3, % 4).
SEEDS = [0, 1, 2, 3]


def test_independent_campaigns(tmp_path: Path) -> None:
    scores = run_suite(SEEDS, tmp_path)
    s = summary(scores)
    assert s["observable_location_errors"] >= 4 * len(SEEDS)
    assert s["within_tolerance_fraction"] >= 0.95, [c.worst for c in scores]
    assert s["unseen_named_every_case"] == 1.0
    assert s["median_heldout_ratio"] <= 0.2
    kinds = {c.kind for c in scores}
    assert kinds == {"xyzac-trt", "xyzbc-trt"}
    assert any(c.motions for c in scores) and any(c.rtest for c in scores)


def test_error_motions_where_the_plan_resolves_them(tmp_path: Path) -> None:
    """A B/C campaign with hidden error motions fitted up to the 3rd harmonic: every motion
    coefficient the plan resolves lies within max(95 % interval, 1 um / 5 urad) of the truth
    (bench/bench_five_axis.py --harmonics 3 runs 32 campaigns)."""
    # motions 8x the suite's (up to 4.8 um / 24 urad): at the suite's size every coefficient
    # is inside the 1 um / 5 urad floor whatever the fit says; here a wrong sign or phase fails
    s = summary(run_suite([3], tmp_path, harmonics=3, motion_scale=8.0))
    assert s["observable_motion_coefficients"] >= 10
    assert s["motion_within_fraction"] >= 0.95
    assert s["motion_within_ci95_only_fraction"] >= 0.9
