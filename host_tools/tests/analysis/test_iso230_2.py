"""ISO 230-2 evaluation: the real ESS file (notes §3), hand-made data, the CLI."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from abbe.analysis.iso230_2 import evaluate
from abbe.cli.entry import main
from abbe.formats.deviations import PositioningData
from abbe.formats.positioning import load_positioning

from fit_helpers import ESS_DAT, write_lines
from real_data import needs_real_data

NOTES = {"B_um": 33.6, "R_um": 55.2, "E_um": 122.8, "A_um": 135.3, "M_um": 93.7}

needs_ess = needs_real_data(ESS_DAT)


@needs_ess
def test_ess_file_matches_notes_within_0p1_um() -> None:
    res = evaluate(load_positioning(ESS_DAT))
    assert res.n_runs == 5 and res.targets_mm.size == 9
    for k, v in NOTES.items():
        assert abs(getattr(res, k) - v) <= 0.1, (k, getattr(res, k), v)


@needs_ess
def test_cli_json_top_level_keys(capsys) -> None:
    assert main(["iso230-2", str(ESS_DAT), "--json", "-"]) == 0
    d = json.loads(capsys.readouterr().out)
    for k, v in NOTES.items():
        assert abs(d[k] - v) <= 0.1
    assert len(d["targets"]) == 9
    t0 = d["targets"][0]
    assert t0["target_mm"] == -20.0
    assert t0["reversal_um"] == pytest.approx(t0["mean_up_um"] - t0["mean_down_um"])


@needs_ess
def test_cli_text(capsys) -> None:
    assert main(["iso230-2", str(ESS_DAT)]) == 0
    out = capsys.readouterr().out
    assert "B (reversal)" in out and "33.6 um" in out and "122.8 um" in out


def test_hand_computed_values() -> None:
    # Two targets, three runs; values chosen so every statistic is easy by hand.
    up = np.array([[1.0, 3.0], [2.0, 3.0], [3.0, 3.0]])     # x_up = 2, 3; s_up = 1, 0
    dn = np.array([[0.0, 1.0], [0.0, 1.0], [0.0, 1.0]])     # x_dn = 0, 1; s_dn = 0, 0
    r = evaluate(PositioningData("hand", np.array([0.0, 10.0]), up, dn))
    np.testing.assert_allclose(r.reversal_um, [2.0, 2.0])
    assert r.B_um == pytest.approx(2.0)
    # R_i = max(2*1 + 0 + 2, 4*1, 0) = 4; R_2 = max(0 + 0 + 2, 0, 0) = 2
    np.testing.assert_allclose(r.repeatability_um, [4.0, 2.0])
    assert r.R_um == pytest.approx(4.0)
    assert r.E_um == pytest.approx(3.0 - 0.0)
    assert r.M_um == pytest.approx(2.0 - 1.0)           # mid = 1, 2
    assert r.A_um == pytest.approx((2.0 + 2.0) - 0.0)    # max(x+2s) = 4, min(x-2s) = 0
    assert r.unidirectional["up"]["E_um"] == pytest.approx(1.0)


def test_csv_linear_data(tmp_path: Path, capsys) -> None:
    rows = ["run,direction,target_mm,linear_um"]
    for run, off in ((1, 0.0), (2, 1.0), (3, 2.0)):
        rows += [f"{run},+,0,{1 + off}", f"{run},+,10,{3 + off}",
                 f"{run},-,10,{1 + off}", f"{run},-,0,{0 + off}"]
    p = write_lines(tmp_path / "lin.csv", rows)
    d = load_positioning(p)
    np.testing.assert_allclose(d.up_um[:, 1], [3.0, 4.0, 5.0])
    r = evaluate(d)
    assert r.B_um == pytest.approx(2.0)          # (2 - 1) and (4 - 2): max 2
    assert r.R_um == pytest.approx(2 + 2 + 2.0)  # s = 1 in both directions
    assert main(["iso230-2", str(p), "--json", "-"]) == 0
    assert json.loads(capsys.readouterr().out)["B_um"] == pytest.approx(2.0)


def test_cli_bad_file_exits_2(tmp_path: Path, capsys) -> None:
    p = write_lines(tmp_path / "bad.csv", ["run,direction,target_mm,linear_um", "1,+,0,abc"])
    assert main(["iso230-2", str(p)]) == 2
    err = capsys.readouterr().err
    assert f"{p}:2: field 'linear_um'" in err


def test_one_run_is_rejected(tmp_path: Path) -> None:
    from abbe.errors import AbbeInputError
    p = write_lines(tmp_path / "one.csv", ["run,direction,target_mm,linear_um",
                                           "1,+,0,1", "1,+,10,2", "1,-,10,3", "1,-,0,4"])
    with pytest.raises(AbbeInputError) as ei:
        evaluate(load_positioning(p))
    assert ei.value.file == str(p) and ei.value.field == "run"
