"""The decision rules of issue 24 one by one (abbe.diagnose.selection): the held-out gain
fraction, the contribution against the noise, one thermal drift entry, a declared tool
offset changed only with strong evidence and a plausible value, and the gap that may
never grow. End to end, the independent suite (test_diagnose_independent.py and
bench/bench_diagnose.py) measures them."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from abbe.diagnose.candidates import Cand, Selected
from abbe.diagnose.effects import by_key
from abbe.diagnose.results import DiagnoseOptions, GapStats
from abbe.diagnose.selection import _gap_grew, _parsimony

OPTS = DiagnoseOptions()


def _eng(tool_mm=(0.0, 0.0, 0.0), z_heights=(0.0,)):
    from abbe.diagnose.checks import BallbarCheck
    checks = [BallbarCheck.__new__(BallbarCheck) for _ in z_heights]
    for c, z in zip(checks, z_heights):
        c.center_mm = (0.0, 0.0, z)
    return SimpleNamespace(table=SimpleNamespace(tool_offset_mm=tool_mm),
                           prob=SimpleNamespace(checks=checks))


def _st(gain: float, without: float, contrib: float = 1.0, coef=(0.0,)) -> dict:
    return {"heldout": {"gain": gain, "rss_without": without, "split": "x"},
            "contrib_rms_um": contrib, "coef": np.asarray(coef, dtype=float)}


def _cand(key: str, idx=(0,)) -> Cand:
    return Cand(spec=by_key()[key], cols=np.zeros((1, len(idx))), param_idx=list(idx))


def test_held_out_gain_below_the_fraction_is_not_named() -> None:
    c = _cand("servo_mismatch_xy")
    ok, why = _parsimony(_st(12.0, 100.0), c, [], _eng(), 0.1, OPTS)   # 12 %: issue 24
    assert not ok and "held-out gain 12.0 %" in why
    ok, _ = _parsimony(_st(40.0, 100.0), c, [], _eng(), 0.1, OPTS)
    assert ok


def test_contribution_below_half_the_noise_is_not_named() -> None:
    c = _cand("backlash_y")
    ok, why = _parsimony(_st(50.0, 100.0, contrib=0.2), c, [], _eng(), 0.6, OPTS)
    assert not ok and "below 0.5 x the noise" in why
    ok, _ = _parsimony(_st(50.0, 100.0, contrib=0.35), c, [], _eng(), 0.6, OPTS)
    assert ok


def test_one_thermal_drift_one_entry() -> None:
    first = Selected(_cand("thermal_drift_x"), {})
    ok, why = _parsimony(_st(80.0, 100.0), _cand("thermal_drift_y"), [first], _eng(), 0.1, OPTS)
    assert not ok and "already named (thermal_drift_x)" in why
    ok, _ = _parsimony(_st(80.0, 100.0), _cand("thermal_drift_y"), [], _eng(), 0.1, OPTS)
    assert ok


def test_declared_tool_offset_needs_strong_evidence_and_a_plausible_value() -> None:
    c = _cand("tool_offset", idx=(2,))
    # 15.7 mm with a 4 % held-out gain beside a squareness (issue 24): not named
    ok, why = _parsimony(_st(4.0, 100.0, coef=(15.7,)), c, [], _eng(), 0.1, OPTS)
    assert not ok
    # strong gain but one Z height: still needs the strong margin, and says why
    ok, why = _parsimony(_st(30.0, 100.0, coef=(120.0,)), c, [], _eng(), 0.1, OPTS)
    assert not ok and "one Z height" in why and "50 %" in why
    # 306 mm: implausible whatever the evidence
    ok, why = _parsimony(_st(95.0, 100.0, coef=(306.0,)), c, [], _eng(z_heights=(0.0, -100.0)),
                         0.1, OPTS)
    assert not ok and "implausible tool offset 306 mm" in why
    # declared 150 mm + found 200 mm = 350 mm: implausible; declared 0 + 120 mm, strong: named
    ok, _ = _parsimony(_st(95.0, 100.0, coef=(200.0,)), c, [], _eng((0.0, 0.0, 150.0)), 0.1, OPTS)
    assert not ok
    ok, _ = _parsimony(_st(90.0, 100.0, coef=(120.0,)), c, [], _eng(z_heights=(0.0, -100.0)),
                       0.1, OPTS)
    assert ok


def test_the_gap_never_grows() -> None:
    b = GapStats(3.21, 9.0, 100)
    fin = {"gap_after": GapStats(12.65, 30.0, 100), "ho_before": GapStats(3.21, 9.0, 100),
           "ho_after": GapStats(3.63, 9.0, 100)}
    assert _gap_grew(b, fin)                                     # issue 24's case
    fin = {"gap_after": GapStats(1.0, 3.0, 100), "ho_before": GapStats(3.21, 9.0, 100),
           "ho_after": GapStats(3.63, 9.0, 100)}
    assert _gap_grew(b, fin)                                     # held-out alone grew
    fin = {"gap_after": GapStats(1.0, 3.0, 100), "ho_before": GapStats(3.21, 9.0, 100),
           "ho_after": GapStats(1.2, 4.0, 100)}
    assert not _gap_grew(b, fin)
    fin = {"gap_after": GapStats(3.21, 9.0, 100), "ho_before": None, "ho_after": None}
    assert not _gap_grew(b, fin)                                 # unchanged: not grown
