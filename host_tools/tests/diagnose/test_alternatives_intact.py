"""Issue 36, twelfth round: a candidate's alternatives (parameter subsets, grid values) stay
intact from one selection step to the next (docs/effects.md §3, "the alternatives are
re-judged at every step").

The pool's candidate was the first alternative itself, and each step set its parameter
subset in place from the choice of that step: what step 1 chose (before anything was
named) overwrote the first alternative for good. The team's independent suite, seed
665122612, ``tool_offset+scale_x`` (case seed 603233182; true tool (55.4, 0, 87.9) mm,
norm 103.9, scale of X 37.57 ppm): at step 1 the unmodelled scale of X made the tool's
full change implausible (669 mm), t_z alone was chosen and the lateral components were
never tested again. Once the scale was named, the lateral change (t_x 55.8 mm) has log K
46.4 beside t_z; without it the tool came out 86.95 mm [80.1, 93.8] (t_z alone) and the
t_x times the yaw of Y it left was named as a scale of Y, -2.59 ppm with a bow of
0.55 um, not flagged. Now: tool 99.98 mm [86.9, 113.0], no scale of Y.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest


def test_a_tool_offsets_lateral_components_are_retested_after_step_one(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import abbe.diagnose.selection as sel
    from cases.independent.suite import CaseDef, build, run, score
    seen: list[list[list[int]]] = []
    orig = sel._tool_components

    def spy(eng: Any, c: Any, alts: list[Any], *rest: Any) -> None:
        seen.append([list(a.param_idx) for a in alts])
        orig(eng, c, alts, *rest)

    monkeypatch.setattr(sel, "_tool_components", spy)
    b = build(CaseDef("tool_offset+scale_x", 603233182, ("tool_offset", "scale_x")),
              tmp_path / "case")
    s = score(b, run(b))
    # the cause: every step sees the alternatives as built (was [[2], [2]] after step 1)
    assert len(seen) >= 2 and all(sorted(a) == [[0, 1, 2], [2]] for a in seen), seen
    assert not s["extra"], s["named"]                             # scale_y was named
    assert s["exact"], (s["expected"], s["named"])
    t = s["values"]["tool_offset"]
    assert t["ci95"][0] <= t["true"] <= t["ci95"][1], t          # 103.9 in [86.9, 113.0]
    assert s["values"]["scale_x"]["ok"], s["values"]
