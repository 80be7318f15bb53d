"""Issue 36: a backlash whose take-up differs with the direction of the reversal
(docs/diagnose-validation.md, "A per-direction take-up").

The team's suite seed 1356483448 ``backlash_asym`` (case seed 72714230: linear take-up
0.478 mm after a reversal to + motion, 1.277 mm after one to - motion, B 5.786 um) was
diagnosed ``backlash_x`` plus a false ``tool_offset`` of 265.7 mm: the model's one take-up
left a mirrored residual after each reversal that the tool's columns partly took. The
backlash entry now has an optional per-direction take-up pair, chosen by the evidence; the
table keeps one take-up (the pair's mean).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def test_pair_state_is_the_one_take_up_state_when_equal_and_per_direction_otherwise() -> None:
    from abbe.diagnose.backlash_pair import pair_state, table_takeup_mm
    from abbe.model.backlash import direction_state
    p = np.concatenate([np.linspace(0.0, 3.0, 31), np.linspace(3.0, 0.0, 31)[1:],
                        np.linspace(0.0, 2.0, 21)[1:]])
    assert np.allclose(pair_state(p, 0.8, 0.8), direction_state(p, 0.8))
    s = pair_state(p, 0.5, 2.0, s0=-1.0)
    # to + motion from -1: +1 after 0.5 mm; after the reversal at 3 mm: -1 after 2.0 mm
    assert s[5] == 1.0 and abs(s[4] - 0.6) < 1e-12
    assert abs(s[40]) < 1e-12 and abs(s[49] + 0.9) < 1e-12 and s[50] == -1.0
    # and back to + motion from 0 mm: +1 again after 0.5 mm
    assert abs(s[62] + 0.2) < 1e-12 and s[65] == 1.0
    assert table_takeup_mm((0.5, 2.0)) == 1.25


def test_an_asymmetric_take_up_is_named_as_the_backlash_alone(tmp_path: Path) -> None:
    from cases.independent.suite import CaseDef, build, run, score
    b = build(CaseDef("backlash_asym", 72714230, ("backlash_asym",)), tmp_path / "case")
    res = run(b)
    s = score(b, res)
    # main: ['backlash_x', 'tool_offset'] (t_y 262.7 mm, log K 16.65)
    assert s["named"] == ["backlash_x"], s["named"]
    assert s["values"]["backlash_x"]["ok"], s["values"]
    e = next(e for e in res.to_json()["effects"] if e["key"] == "backlash_x")
    sc, ci = e["scan"], e["scan_ci95"]
    # the generator's take-ups: 0.478 mm to + motion, 1.277 mm to - motion
    assert ci["takeup_plus_mm"][0] < 0.478 < ci["takeup_plus_mm"][1], (sc, ci)
    assert ci["takeup_minus_mm"][0] < 1.277 < ci["takeup_minus_mm"][1], (sc, ci)
    # the table holds one take-up: the pair's mean
    assert abs(sc["takeup_mm"] - 0.5 * (sc["takeup_plus_mm"] + sc["takeup_minus_mm"])) < 1e-5
    assert abs(res.table.axes["X"].backlash_takeup_mm - sc["takeup_mm"]) < 1e-5
