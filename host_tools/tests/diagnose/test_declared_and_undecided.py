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
from abbe.diagnose.selection import _parsimony, declared_tool_log_evidence

OPTS = DiagnoseOptions()


def _eng(tool_mm, z_heights=(0.0, -100.0)):
    from abbe.diagnose.checks import BallbarCheck
    checks = [BallbarCheck.__new__(BallbarCheck) for _ in z_heights]
    for c, z in zip(checks, z_heights):
        c.center_mm = (0.0, 0.0, z)
    return SimpleNamespace(table=SimpleNamespace(tool_offset_mm=tool_mm, reference_mm=(0.0, 0.0, 0.0)),
                           prob=SimpleNamespace(checks=checks))


def _st(gain, without, contrib, coef, drss):
    return {"heldout": {"gain": gain, "rss_without": without, "split": "x"},
            "contrib_rms_um": contrib, "coef": np.asarray(coef, dtype=float), "drss": drss}


def _cand(key, idx=(0,)):
    return Cand(spec=by_key()[key], cols=np.zeros((1, len(idx))), param_idx=list(idx))


def test_a_near_noise_change_of_a_declared_tool_offset_is_lack_of_fit() -> None:
    # issue 36's case: 15.7 mm on a declared tool, 0.16 um RMS, a held-out gain of 60 %
    # of the excess (which the old 50 % rule passed): the model's own angular
    # uncertainty (0.5 urad x ~120 mm = 0.06 um) explains as much -> not named
    c = _cand("tool_offset", idx=(2,))
    ok, why = _parsimony(_st(60.0, 100.0, 0.16, (15.7,), 200.0), c, [], _eng((0.0, 0.0, 100.0)),
                         0.12, OPTS)
    assert not ok and "log evidence ratio" in why and "lack of fit" in why


def test_a_blunder_on_a_declared_tool_offset_is_named() -> None:
    c = _cand("tool_offset", idx=(2,))
    ok, why = _parsimony(_st(90.0, 100.0, 1.5, (120.0,), 5000.0), c, [], _eng((0.0, 0.0, 100.0)),
                         0.12, OPTS)
    assert ok, why


def test_a_change_within_the_presetter_uncertainty_is_no_change() -> None:
    ev = declared_tool_log_evidence(1e6, np.array([0.02]), 1.0, np.array([0, 0, 100.0]), 100.0, OPTS)
    assert ev["log_evidence"] == -math.inf


def test_evidence_grows_with_the_signature_and_falls_with_model_uncertainty() -> None:
    base = declared_tool_log_evidence(500.0, np.array([30.0]), 0.4, np.zeros(3), 150.0, OPTS)
    bigger = declared_tool_log_evidence(2000.0, np.array([60.0]), 0.8, np.zeros(3), 150.0, OPTS)
    worse_model = declared_tool_log_evidence(
        500.0, np.array([30.0]), 0.4, np.zeros(3), 150.0,
        DiagnoseOptions(model_angle_sigma_urad=2.0))
    assert bigger["log_evidence"] > base["log_evidence"] > worse_model["log_evidence"]


def test_two_explanations_that_reproduce_each_other_are_undecided() -> None:
    amb = [{"key": "scale_y", "id": "scale", "r2": 0.999, "value": [-12.1], "unit": ["ppm"],
            "separating_test": "laser_Y"},
           {"key": "straightness_xy", "id": "straightness", "r2": 0.93, "value": [2.0],
            "unit": ["um"], "separating_test": "laser_X"}]
    u = _undecided("scale_x", 12.0, "ppm", amb, OPTS.undecided_r2)
    assert u is not None
    assert [a["key"] for a in u["alternatives"]] == ["scale_x", "scale_y"]
    assert u["alternatives"][1]["value"] == -12.1 and "laser_Y" in u["statement"]
    e = EffectResult(id="scale", key="scale_x", value=12.0, unit="ppm", ci95=(11.0, 13.0),
                     params=[], compensable=True, where="table", physics="", remedy="",
                     evidence={}, ambiguous_with=amb, undecided=u)
    d = e.to_json()
    assert d["state"] == "undecided" and d["undecided_between"] == ["scale_x", "scale_y"]
    # an ambiguity below the threshold (0.93) leaves the name decided
    assert _undecided("squareness_xy", 20.0, "urad", amb[1:], OPTS.undecided_r2) is None
