"""The second independent generator (cases/independent2, issue 36): written from the
docs only -- it imports neither the simulator nor the other generators -- its exact
transforms reduce to Eq. 3 of docs/table-format.md to first order, and a fixed-seed
case is diagnosed through the documented files (the full suite: bench/bench_independent2.py)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from cases.independent2 import machine as m2

PKG = Path(__file__).resolve().parents[2] / "cases" / "independent2"


def test_written_without_the_other_generators() -> None:
    for f in PKG.glob("*.py"):
        src = "\n".join(ln for ln in f.read_text().splitlines()
                        if ln.lstrip().startswith(("import ", "from ")))
        for banned in ("abbe.sim", "cases.hidden_effects", "cases.independent ", "cases.independent.",
                       "from cases.independent import", "abbe.diagnose"):
            if banned == "abbe.diagnose" and f.name == "suite.py":
                continue        # the suite runs the diagnosis it scores
            assert banned not in src, f"{f.name} uses {banned}"
        assert not re.search(r"import cases\.independent\b(?!2)", src)


def _eq3(mach: m2.Machine, q: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Eq. 3 of docs/table-format.md (plus the Abbe terms), written from the page."""
    x, y, z = q - mach.ref
    e = {a: {k: float(mach.motions[a][k](np.array([q[j]]))[0]) for k in m2.TERMS}
         for j, a in enumerate(m2.AXES)}
    S = mach.squareness_urad
    u = 1e-3   # urad x mm -> um
    dX = (-e["X"]["dx"] - e["Y"]["dx"] + e["Z"]["dx"]
          + u * (-y * (e["X"]["ez"] + e["Y"]["ez"]) - z * (e["X"]["ey"] + e["Y"]["ey"])
                 + y * S["xy"] - z * S["xz"]
                 + t[1] * (e["X"]["ez"] + e["Y"]["ez"] - e["Z"]["ez"])
                 + t[2] * (e["Z"]["ey"] - e["X"]["ey"] - e["Y"]["ey"])))
    dY = (-e["X"]["dy"] - e["Y"]["dy"] + e["Z"]["dy"]
          + u * (x * e["X"]["ez"] + z * (e["X"]["ex"] + e["Y"]["ex"]) - z * S["yz"]
                 + t[0] * (e["Z"]["ez"] - e["X"]["ez"] - e["Y"]["ez"])
                 + t[2] * (e["X"]["ex"] + e["Y"]["ex"] - e["Z"]["ex"])))
    dZ = (-e["X"]["dz"] - e["Y"]["dz"] + e["Z"]["dz"]
          + u * (-x * e["X"]["ey"] + y * (e["X"]["ex"] + e["Y"]["ex"])
                 + t[0] * (e["X"]["ey"] + e["Y"]["ey"] - e["Z"]["ey"])
                 + t[1] * (e["Z"]["ex"] - e["X"]["ex"] - e["Y"]["ex"])))
    return np.array([dX, dY, dZ])


def test_exact_transforms_reduce_to_eq3() -> None:
    rng = np.random.default_rng(3)
    t = np.array([5.0, -8.0, 120.0])
    mach, _ = m2.random_machine(rng, t)
    mach.squareness_urad = {"xy": 30.0, "xz": -20.0, "yz": 15.0}
    worst = 0.0
    for _ in range(20):
        q = np.array([rng.uniform(lo, hi) for lo, hi in mach.travel.values()])
        worst = max(worst, float(np.max(np.abs(mach.error_um(q[None, :])[0] - _eq3(mach, q, t)))))
    # second order only: tens of urad over hundreds of mm -> well below 0.01 um
    assert worst < 0.01


def test_a_fixed_seed_case_through_the_files(tmp_path) -> None:
    from cases.independent2.suite import Case, build, run, score
    b = build(Case("squareness_xy_fixed", "single", ("squareness_xy",), 20261204), tmp_path)
    s = score(b, run(b))
    assert s["exact"], s
    assert not s["tool_changed_where_right"]
    assert all(v[3] for v in s["values"]), s["values"]


def test_issue36_squareness_only_keeps_the_declared_tool(tmp_path) -> None:
    """Issue 36's first case, on this generator (a right tool declared, the model fitted
    by abbe fit with its own angular error, circles at one Z height only, where a tool
    offset and the model's angular error look alike): the squareness is found and the
    declared tool length is not changed."""
    from abbe.diagnose.run import diagnose_machine
    from cases.independent2.suite import Case, build
    b = build(Case("sq_only", "single", ("squareness_xy",), 3601), tmp_path)
    assert b.declared_tool_mm > 0
    res = diagnose_machine(b.machine, b.model, ballbar=["xy_slow", "xy_fast"], laser=[])
    keys = {e.key for e in res.effects}
    assert "tool_offset" not in keys, keys
    assert "squareness_xy" in keys, keys


def test_issue36_clean3_a_lateral_change_is_judged_on_lateral_arms(tmp_path) -> None:
    """Issue 36, second generator's ``clean_3`` (seed 631078656): a clean machine with a
    right declared tool (151.3 mm) was named a tool offset of 88.8 mm whose change was
    mostly lateral (t_x 27, t_y 84, t_z 12 mm), judged against the model-angle
    uncertainty of the circles' *vertical* lever (0.061 um; log K 4.2). A change along
    t_y multiplies the angular terms the circles' y arm multiplies: against that lever
    (0.081 um) its log K is -2.0, and the declared tool stays."""
    from abbe.diagnose.run import diagnose_machine
    from cases.independent2.suite import Case, build, score
    b = build(Case("clean_3", "clean", (), 1995020907), tmp_path)
    assert b.declared_tool_mm > 0 and b.truth == {}
    res = diagnose_machine(b.machine, b.model)
    s = score(b, res)
    assert not s["tool_changed_where_right"], s
    tool = res.to_json()["candidates"]["tool_offset"]
    assert tool["log_evidence"] < 2.94, tool


def test_issue36_the_tables_own_fit_error_moves_no_declared_tool(tmp_path) -> None:
    """Issue 36, the nineteenth round's ``servo_mismatch_xy_4`` (seed 926288747): the same
    machine with no effect at all was named a tool offset of 128.6 mm for the declared and
    right 61.574 mm. The commissioning laser's noise had left the fitted table's angular
    terms wrong by about their own uncertainty (0.1 urad), and a tool change multiplies
    exactly those terms: the tool's evidence was judged against an assumed model-angle
    figure only, not against the table's covariance (model.json) that every other
    candidate carries. With it (t_y's standard deviation 37 mm from the table alone) the
    declared tool stays; the servo mismatch beside it is still named, within 10 %."""
    from abbe.diagnose.run import diagnose_machine
    from cases.independent2.suite import Case, build, score
    b = build(Case("twin", "clean", (), 926288747), tmp_path / "twin")
    assert abs(b.declared_tool_mm - 61.574) < 1e-9 and b.truth == {}
    res = diagnose_machine(b.machine, b.model)
    s = score(b, res)
    assert not s["tool_changed_where_right"], s
    assert s["named"] == [], s
    tool = res.to_json()["candidates"]["tool_offset"]
    assert tool["log_evidence"] < 2.94, tool
    b = build(Case("servo_mismatch_xy_4", "single", ("servo_mismatch_xy",), 926288747),
              tmp_path / "servo")
    s = score(b, diagnose_machine(b.machine, b.model))
    assert not s["tool_changed_where_right"], s
    assert s["exact"], s
    assert s["values"] and all(v[3] for v in s["values"]), s["values"]


def test_issue36_the_tables_error_is_not_counted_twice_against_a_wrong_tool(tmp_path) -> None:
    """The other side of the test above: the table's covariance *replaces* the assumed
    model-angle figure it stood for. Counting both (tried first: the twentieth round,
    second generator seed 1052841905) missed `tool_offset_0` (case seed 312009980), a tool
    of 86.4 mm the machine file does not declare (seen 0.37 um): log K 6.4 -> 1.4. With
    the table's error alone it is 4.3: the tool is named, the truth within its interval
    or 10 %."""
    from abbe.diagnose.run import diagnose_machine
    from cases.independent2.suite import Case, build, score
    b = build(Case("tool_offset_0", "single", ("tool_offset",), 312009980), tmp_path)
    s = score(b, diagnose_machine(b.machine, b.model))
    assert s["exact"], s
    assert s["values"] and all(v[3] for v in s["values"]), s["values"]


def test_issue36_a_scale_of_x_is_never_called_y_alone(tmp_path) -> None:
    """Issue 36's second case: a thermal drift with a scale error of X, seen on circles (which
    see only kx - ky): the answer names scale_x or is undecided with scale_x among the
    explanations, never scale_y alone; the declared tool stays."""
    from abbe.diagnose.run import diagnose_machine
    from cases.independent2.suite import Case, build
    b = build(Case("drift_scale", "pair", ("thermal_drift_x", "scale_x"), 3602), tmp_path)
    res = diagnose_machine(b.machine, b.model, ballbar=["xy_slow", "xy_fast", "xy_high"],
                           laser=[])
    said = set()
    for e in res.effects:
        said |= {e.key} | {a["key"] for a in (e.undecided or {}).get("alternatives", [])}
        assert e.key != "tool_offset"
    named_y_alone = any(e.key == "scale_y" and not e.undecided for e in res.effects)
    assert not named_y_alone, [e.key for e in res.effects]
    assert "scale_x" in said, said          # named, or among the undecided explanations


def test_issue36_drift_of_x_rate_not_inflated_by_the_ballbar(tmp_path) -> None:
    """Issue 36, "the known drift-of-X miss": a drift linear in time (um/h) seen on a
    laser line of X (20 min) and on ballbar traces of minutes. The traces cannot tell a
    warm-up's shape (each starts its own clock; their ccw / cw pair carries a
    direction-dependent centre the drift column picks up), so they must not choose the
    time constant: before, they made a warm-up of tau = the laser's span win and the rate
    reported (the slope at each check's start) was -8.94 for a true -5.71."""
    from cases.independent2.suite import Case, build, run, score
    b = build(Case("thermal_drift_x_0", "single", ("thermal_drift_x",), 1780183835), tmp_path)
    res = run(b)
    s = score(b, res)
    assert s["exact"], s
    d = {e["key"]: e for e in res.to_json()["effects"]}["thermal_drift_x"]
    assert d.get("scan") in (None, {}) or d["scan"]["tau_h"] is None or \
        d["scan"]["tau_h"] > 1.0, d.get("scan")   # linear (inf), not a warm-up within the check
    assert all(v[3] for v in s["values"]), s["values"]
    assert abs(d["value"] - b.truth["thermal_drift_x"]["value"]) < 0.1 * 5.706


def test_what_the_checks_see_of_an_effect_is_measured_and_counted_apart(tmp_path) -> None:
    """Issue 36, twelfth round, second generator seed 1909725787: ``tool_offset_4`` (86.3 mm
    run, none declared) was scored a miss, but a tool shows only through the machine's
    angular errors times its length: on this machine its true noise-free contribution to
    the checks is 0.11 um RMS at most (at the tool tip, nothing removed, as the diagnosis
    sizes a tool; 0.07 um once the circles' set-up is removed), below the 0.15 um size
    threshold, so the scorer counts it apart (``unobservable``) instead of as a miss. The same measure on
    ``limit_squareness_yz_0`` (5.30 urad) is the analytic oval of a squareness on the YZ
    circle, |S| r / (2 sqrt 2) = 0.19 um (0.18 um on the runs' samples, whose arcs overlap):
    observable, still scored."""
    import importlib.util
    from cases.independent2.suite import Case, build, unobservable
    spec = importlib.util.spec_from_file_location(
        "bench_independent2", PKG.parents[1] / "bench" / "bench_independent2.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    summarise = bench.summarise
    tool = build(Case("tool_offset_4", "single", ("tool_offset",), 1970364177),
                 tmp_path / "t", fit=False)
    assert 0.1 < tool.seen_um["tool_offset"] < 0.12, tool.seen_um
    assert unobservable(tool) == ["tool_offset"]
    sq = build(Case("limit_squareness_yz_0", "limit", ("squareness_yz",), 721559547),
               tmp_path / "s", fit=False)
    import tomllib
    r_yz = float(tomllib.loads(sq.machine.read_text())["ballbar"]["yz"]["radius_mm"])
    oval = abs(sq.truth["squareness_yz"]["value"]) * 1e-3 * r_yz / (2 * np.sqrt(2))
    assert abs(sq.seen_um["squareness_yz"] - oval) < 0.05 * oval, (sq.seen_um, oval)
    assert unobservable(sq) == []
    rows = [{"case": "tool_offset_4", "kind": "single", "truth": ["tool_offset"], "named": [],
             "exact": False, "undecided": False, "values": [], "tool_changed_where_right": False,
             "unobservable": ["tool_offset"], "seen_um": {"tool_offset": 0.07}},
            {"case": "a", "kind": "single", "truth": ["scale_x"], "named": ["scale_x"],
             "exact": True, "undecided": False, "values": [], "tool_changed_where_right": False,
             "unobservable": [], "seen_um": {"scale_x": 1.0}}]
    s = summarise(rows)
    assert (s["effect_cases"], s["exact"]) == (2, 1)            # the raw figure stays
    assert (s["observable_effect_cases"], s["observable_exact"]) == (1, 1)
    assert s["unobservable"] and s["unobservable"][0].startswith("tool_offset_4")


def test_issue36_correlated_ballbar_noise_names_no_reversal_or_scale(tmp_path) -> None:
    """Issue 36, twelfth round's only false name (second generator seed 1909725787,
    ``thermal_drift_x_0``, a drift of X of 7.18 um/h): the fast circle's noise is
    correlated over a few samples (0.167 um, lag-1 0.51); the scatter about the saturated
    fit gave 0.118 um and inflation 1.00, so that circle weighed 6 x too much and its noise
    named a reversal of X (0.40 um) and a scale of Y (1.16 ppm) beside the drift (7.94, 10.5 %
    high). The same machine and noise without the drift named the two as well; without the
    noise, the drift alone. With the noise estimated through the fit: the drift alone."""
    from cases.independent2.suite import Case, build, run, score
    b = build(Case("thermal_drift_x_0", "single", ("thermal_drift_x",), 1630505371), tmp_path)
    res = run(b)
    s = score(b, res)
    assert s["named"] == ["thermal_drift_x"], s["named"]
    fast = res.to_json()["noise"]["xy_fast:radial"]
    assert fast["sigma"] * fast["inflation"] ** 0.5 > 0.2, fast      # 0.118 before
    d = {e["key"]: e for e in res.to_json()["effects"]}["thermal_drift_x"]
    assert abs(d["value"] - b.truth["thermal_drift_x"]["value"]) < 0.1 * 7.184, d["value"]
