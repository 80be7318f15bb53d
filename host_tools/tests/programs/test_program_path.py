"""The shared judging of recorded program paths (cases/program_path.py, used by the
LinuxCNC and grblHAL proofs): a path replayed here from the program's steps passes, and
each defect the interpreters' proofs look for makes it fail."""

from __future__ import annotations

import numpy as np
import pytest

from abbe.programs.dialects import render
from abbe.programs.plan import Dwell, Move, line_program
from cases.program_path import PathCheckFailed, check_positioning, params_of

TRAVEL = {"X": [0.0, 500.0], "Y": [-400.0, 0.0], "Z": [-300.0, 0.0]}
LINE = [0.0, -200.0, -250.0]
DT = 0.002  # s, the LinuxCNC proof's polling


def _program(sequence: str):
    return line_program("positioning", "X", LINE, [500.0, -200.0, -250.0], TRAVEL,
                        feed=6000.0, dwell_s=0.3, overrun_mm=5.0, runs=2, sequence=sequence)


def _replay(prog, dwell_scale: float = 1.0, gaps: bool = False) -> dict:
    """The path at the feed (no acceleration), every DT; with ``gaps`` no samples from the
    arrival at a dwell to its end (grblHAL's Simulator), one at the end."""
    t, pts, now = [0.0], [np.array(LINE)], 0.0
    for st in prog.steps:
        if isinstance(st, Move):
            a, b = pts[-1], np.array(st.pos)
            dur = np.linalg.norm(b - a) / (st.feed / 60.0)
            n = max(1, int(np.ceil(dur / DT)))
            for k in range(1, n + 1):
                t.append(now + dur * k / n)
                pts.append(a + (b - a) * k / n)
            now += dur
        elif isinstance(st, Dwell):
            now += st.seconds * dwell_scale
            here = pts[-1].copy()
            if gaps:  # nor at the arrival: the planner ran dry before it
                t.pop()
                pts.pop()
            else:
                for tk in np.arange(t[-1] + DT, now, DT):
                    t.append(float(tk))
                    pts.append(here)
            t.append(now)
            pts.append(here)
    return {"program": "p", "t_s": np.array(t), "pos_mm": np.array(pts), "stops": [],
            "seconds": now}


@pytest.mark.parametrize("sequence", ["linear", "pendulum"])
def test_replayed_path_passes(sequence):
    prog = _program(sequence)
    prm = params_of(render(prog, "linuxcnc"))
    f = check_positioning(_replay(prog), prm, TRAVEL, LINE)
    assert f["n"] == len(prog.captures) == 2 * 2 * prog.targets_mm.size
    assert [(c["target"], c["dir"], c["run"]) for c in f["captures"]] == prog.captures
    assert f["dwell_s"]["min"] == pytest.approx(0.3, abs=DT)


def test_gaps_bracketed_with_kinematics():
    prog = _program("linear")
    prm = params_of(render(prog, "grblhal"))
    rec = _replay(prog, gaps=True)
    with pytest.raises(PathCheckFailed, match="dwells on the line"):
        check_positioning(rec, prm, TRAVEL, LINE)  # no sample while standing: no run
    rec["kinematics"] = {"accel_mm_s2": 1e9, "feed_mm_min": 6000.0}
    assert check_positioning(rec, prm, TRAVEL, LINE, tol_mm=0.002)["n"] == len(prog.captures)


def test_wrong_dwell_fails():
    prog = _program("linear")
    prm = params_of(render(prog, "linuxcnc"))
    with pytest.raises(PathCheckFailed, match="dwell of"):
        check_positioning(_replay(prog, dwell_scale=3.0), prm, TRAVEL, LINE)
    with pytest.raises(PathCheckFailed, match="dwells on the line"):
        check_positioning(_replay(prog, dwell_scale=0.2), prm, TRAVEL, LINE)


def test_wrong_side_order_travel_fail():
    prog = _program("pendulum")
    prm = params_of(render(prog, "linuxcnc"))
    rec = _replay(prog)
    flip = dict(prm, sequence="linear")  # the same stops, expected in another order
    with pytest.raises(PathCheckFailed, match="expected target|approached"):
        check_positioning(rec, flip, TRAVEL, LINE)
    shifted = dict(prm, targets_mm=" ".join(f"{v + 0.01:.3f}" for v in prog.targets_mm))
    with pytest.raises(PathCheckFailed, match="expected target"):
        check_positioning(rec, shifted, TRAVEL, LINE)
    small = dict(TRAVEL, X=[0.0, 400.0])
    with pytest.raises(PathCheckFailed, match="leaves the X travel"):
        check_positioning(rec, prm, small, LINE)
