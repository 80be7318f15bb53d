"""Issue 36: a declared quantity (the tool offset) is a measurement with a prior and is
changed only on an evidence ratio that includes it and the model's own uncertainty;
two explanations that reproduce each other are reported undecided, with both values."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from abbe.diagnose.candidates import Cand
from abbe.diagnose.describe import _undecided
from abbe.diagnose.effects import by_key
from abbe.diagnose.results import DiagnoseOptions, EffectResult
from abbe.diagnose.evidence import declared_tool_log_evidence
from abbe.diagnose.selection import _evidence, _judge

OPTS = DiagnoseOptions()


def _eng(tool_mm, z_heights=(0.0, -100.0), opts=OPTS):
    from abbe.diagnose.checks import BallbarCheck
    checks = [BallbarCheck.__new__(BallbarCheck) for _ in z_heights]
    for c, z in zip(checks, z_heights):
        c.center_mm = (0.0, 0.0, z)
    return SimpleNamespace(table=SimpleNamespace(tool_offset_mm=tool_mm, reference_mm=(0.0, 0.0, 0.0)),
                           prob=SimpleNamespace(checks=checks), opts=opts)


def _judged(gain, contrib, coef, drss, eng):
    c = Cand(spec=by_key()["tool_offset"], cols=np.zeros((1, 1)), param_idx=[2])
    coef = np.asarray(coef, dtype=float)
    Z = np.diag(np.sqrt(drss) / np.abs(coef))
    ev = _evidence(eng, c, coef, Z, drss, 1.0, contrib)
    st = {"ok": True, "coef": coef, "contrib_rms_um": contrib, "observable_rms_um": contrib,
          "drss": drss, "k_eff": 1,
          "heldout": {"gain": gain, "split": "x"}, "evidence": ev, "log_evidence": ev["log_evidence"]}
    return _judge(st, eng.opts)


def test_a_near_noise_change_of_a_declared_tool_offset_is_lack_of_fit() -> None:
    # issue 36's case: 15.7 mm on a declared tool, 0.16 um RMS, a held-out gain of 60 %
    # of the excess (which the old 50 % rule passed): the model's own angular
    # uncertainty (0.5 urad x ~120 mm = 0.06 um) explains as much -> not named
    ok, why = _judged(60.0, 0.16, (15.7,), 200.0, _eng((0.0, 0.0, 100.0)))
    assert not ok and "log evidence ratio" in why and "lack of fit" in why
    assert "declares" in why


def test_a_blunder_on_a_declared_tool_offset_is_named() -> None:
    ok, why = _judged(900.0, 1.5, (120.0,), 5000.0, _eng((0.0, 0.0, 100.0)))
    assert ok, why


def test_the_declared_uncertainty_decides_how_much_a_change_must_show() -> None:
    """The same 2 mm change, well measured (RSS decrease 1e5): against a presetter's
    0.01 mm it is a blunder worth naming; a machine file that states 5 mm (a tool
    measured by hand) keeps its value."""
    presetter = _eng((0.0, 0.0, 100.0))
    by_hand = _eng((0.0, 0.0, 100.0), opts=DiagnoseOptions(declared_tool_sigma_mm=5.0))
    ok, why = _judged(9e4, 3.0, (2.0,), 1e5, presetter)
    assert ok, why
    ok, why = _judged(9e4, 3.0, (2.0,), 1e5, by_hand)
    assert not ok and "+/- 5 mm" in why


def test_a_change_within_the_presetter_uncertainty_is_no_change() -> None:
    ev = declared_tool_log_evidence(1e6, np.array([0.02]), 1.0, np.array([0, 0, 100.0]), 100.0, OPTS)
    assert ev["log_evidence"] < OPTS.evidence_log_min


def test_evidence_grows_with_the_signature_and_falls_with_model_uncertainty() -> None:
    base = declared_tool_log_evidence(500.0, np.array([30.0]), 0.4, np.zeros(3), 150.0, OPTS)
    bigger = declared_tool_log_evidence(2000.0, np.array([60.0]), 0.8, np.zeros(3), 150.0, OPTS)
    worse_model = declared_tool_log_evidence(
        500.0, np.array([30.0]), 0.4, np.zeros(3), 150.0,
        DiagnoseOptions(model_angle_sigma_urad=2.0))
    assert bigger["log_evidence"] > base["log_evidence"] > worse_model["log_evidence"]


def test_two_explanations_that_reproduce_each_other_are_undecided() -> None:
    """Undecided when the misfit of the alternative to the named signature is within the
    noise: its log likelihood ratio (whitened RSS of what it cannot reproduce / 2 s^2) is
    below the evidence level log 19, whatever its R^2."""
    amb = [{"key": "scale_y", "id": "scale", "r2": 0.999, "log_lr": 0.4, "value": [-12.1],
            "unit": ["ppm"], "separating_test": "laser_Y"},
           {"key": "straightness_xy", "id": "straightness", "r2": 0.93, "log_lr": 35.0,
            "value": [2.0], "unit": ["um"], "separating_test": "laser_X"}]
    u = _undecided("scale_x", 12.0, "ppm", amb, OPTS.evidence_log_min)
    assert u is not None
    assert [a["key"] for a in u["alternatives"]] == ["scale_x", "scale_y"]
    assert u["alternatives"][1]["value"] == -12.1 and "laser_Y" in u["statement"]
    e = EffectResult(id="scale", key="scale_x", value=12.0, unit="ppm", ci95=(11.0, 13.0),
                     params=[], compensable=True, where="table", physics="", remedy="",
                     evidence={}, ambiguous_with=amb, undecided=u)
    d = e.to_json()
    assert d["state"] == "undecided" and d["undecided_between"] == ["scale_x", "scale_y"]
    # an alternative whose misfit the data see (log LR 35 > log 19) leaves the name decided
    assert _undecided("squareness_xy", 20.0, "urad", amb[1:], OPTS.evidence_log_min) is None


def test_undecided_follows_the_noise_not_a_fixed_share() -> None:
    """The same R^2 (0.75: the fifth round's drift / scale pair, below the old fixed 0.98) is
    undecided when what the alternative cannot reproduce is within the noise (log LR 1.5)
    and decided when the data see it (log LR 8.4); the old rule said "decided" for both."""
    near = [{"key": "thermal_drift_z", "id": "thermal_drift", "r2": 0.75, "log_lr": 1.5,
             "value": [0.2], "unit": ["um/h"], "separating_test": "laser_Z reversed"}]
    far = [dict(near[0], log_lr=8.4)]
    u = _undecided("scale_z", 35.0, "ppm", near, OPTS.evidence_log_min)
    assert u is not None and u["alternatives"][1]["key"] == "thermal_drift_z"
    assert _undecided("scale_z", 35.0, "ppm", far, OPTS.evidence_log_min) is None


def _diagnose_machine(monkeypatch, tool_mm: tuple, sigma: float | None):
    """run.diagnose_machine on a model whose tool is ``tool_mm`` and a machine file whose
    ``[tool] offset_sigma_mm`` is ``sigma`` (None: not stated), the diagnosis itself faked:
    (its result, the options the diagnosis got, the table)."""
    import abbe.diagnose.checks as checks
    import abbe.diagnose.run as run
    from abbe.model.table import Table
    seen = {}

    def fake_diagnose(table, chks, opts, table_cov=None):
        seen["opts"] = opts
        return SimpleNamespace()
    table = Table.__new__(Table)
    table.tool_offset_mm = tool_mm
    table.reference_mm = (0.0, 0.0, 0.0)
    monkeypatch.setattr(run, "diagnose", fake_diagnose)
    monkeypatch.setattr(run, "check_model_matches", lambda *a, **k: None)
    monkeypatch.setattr(checks, "laser_check", lambda *a, **k: "a check")
    m = SimpleNamespace(ballbar={}, laser={"X": None}, tool_offset_sigma_mm=sigma,
                        reference_mm=(0.0, 0.0, 0.0))
    return run.diagnose_machine(m, table), seen["opts"], table


def test_the_machine_file_states_the_declared_uncertainty(monkeypatch) -> None:
    """``[tool] offset_sigma_mm`` reaches the selection as the declared quantity's prior, and
    the JSON says which uncertainty was used and where it came from."""
    for sigma, want, source in ((None, OPTS.declared_tool_sigma_mm, "default"),
                                (0.5, 0.5, "machine file")):
        res, opts, _ = _diagnose_machine(monkeypatch, (0.0, 0.0, 120.0), sigma)
        assert opts.declared_tool_sigma_mm == want
        assert res.declared["tool_offset_sigma_mm"] == want
        assert res.declared["tool_offset_sigma_source"].startswith(source)
        assert res.declared["tool_offset_mm"] == [0.0, 0.0, 120.0]
        assert res.declared["tool_offset_declared"] is True


def test_a_zero_tool_is_declared_only_when_the_machine_file_states_its_uncertainty(monkeypatch) -> None:
    """A zero tool in the model is not a declaration (prior odds 1 over +/- 300 mm), and the
    JSON says so (it once stated "0.01 mm, a presetter" for it, which the evidence did not
    use); a machine file that states ``[tool] offset_sigma_mm`` declares even a zero tool:
    the evidence then uses the declared prior (log odds log(0.01 / 0.99))."""
    from abbe.diagnose.evidence import candidate_prior, tool_is_declared
    tool = by_key()["tool_offset"]
    for sigma, declared in ((None, False), (0.05, True)):
        res, opts, table = _diagnose_machine(monkeypatch, (0.0, 0.0, 0.0), sigma)
        assert res.declared["tool_offset_declared"] is declared
        assert tool_is_declared(table.tool_offset_mm, opts) is declared
        pr = candidate_prior(tool, [0, 1, 2], np.zeros(3), 100.0, opts)
        assert pr["declared"] is declared
        if declared:
            assert res.declared["tool_offset_sigma_mm"] == 0.05
            assert pr["prior_log_odds"] == math.log(0.01 / 0.99)
            assert np.allclose(np.diag(pr["declared_cov"]), 0.05 ** 2)
        else:
            assert res.declared["tool_offset_sigma_mm"] is None
            assert res.declared["tool_offset_sigma_source"].startswith("not declared")
            assert pr["prior_log_odds"] == 0.0 and pr["declared_cov"] is None


def test_an_undecided_scale_puts_the_equal_share_into_the_table() -> None:
    """One XY circle sees only kx - ky: a scale of X is "scale_x or scale_y". The table
    holds what both explanations agree on, half of each (not all of the first name), the
    checks are still reproduced, and the JSON says what stays unknown."""
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    from abbe.diagnose.checks import BallbarCheck
    from abbe.diagnose.selection import diagnose
    from cases.hidden_effects import hidden_case
    case = hidden_case(101, ("scale_x",), step_deg=3.0)
    circles = [c for c in case.checks if isinstance(c, BallbarCheck)]
    res = diagnose(case.model, circles,
                   DiagnoseOptions(candidates=["scale_x", "scale_y", "squareness_xy", "backlash_x"]))
    (e,) = res.effects
    true = case.expected["scale_x"]
    assert e.undecided is not None and {a["key"] for a in e.undecided["alternatives"]} == \
        {"scale_x", "scale_y"}
    held = e.undecided["table_holds"]
    assert abs(held["scale_x"] - true / 2) <= 0.1 * abs(true / 2)
    assert abs(held["scale_y"] + true / 2) <= 0.1 * abs(true / 2)
    assert "scale_x and scale_y" in e.undecided["unknown"]
    # the table's own terms: half of the slope on X, the opposite half on Y (T1 coefficient,
    # um = ppm x half travel / 1000)
    for axis, term, share in (("X", "dx", held["scale_x"]), ("Y", "dy", held["scale_y"])):
        lo, hi = res.base_table.axes[axis].travel_mm
        d = res.table.axes[axis].coef[term][1] - res.base_table.axes[axis].coef[term][1]
        assert abs(d - share * (hi - lo) / 2 * 1e-3) < 0.02 * abs(d), (axis, d, share)
    assert res.gap["after"].rms_um < 0.5 * res.gap["before"].rms_um
    j = res.to_json()
    assert j["state"] == "undecided" and j["effects"][0]["undecided"]["table_holds"] == held
