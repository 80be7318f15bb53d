"""model.json's metrics against the schema docs/formats.md states ("Metrics"):

per term, model (chosen, paper_fourier3, paper_poly7) and kind (in_sample, held_out) a
block of emax_U, r2, sse_U2, rmse_U, each a finite number or null; a block with a null
has exactly one more key, ``why_null`` (non-empty text); one without has exactly the four
numbers; no NaN / Infinity anywhere in the file. The case that gave nulls without a
word: the paper's Fourier on an 11-target line, whose held-out folds (8-9 targets)
cannot resolve 3 harmonics."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from abbe.cli.entry import main
from cases.synthetic_laser import make_dataset

MODELS = ("chosen", "paper_fourier3", "paper_poly7")
KINDS = ("in_sample", "held_out")


def _no_constants(name: str):
    raise AssertionError(f"model.json holds {name}: not JSON numbers")


def validate_metrics(metrics: dict, unit: str, where: str) -> list[str]:
    """Schema check of one term's ``metrics``; returns the blocks that have nulls."""
    assert set(metrics) == set(MODELS), where
    nulls = []
    for model in MODELS:
        assert set(metrics[model]) == set(KINDS), (where, model)
        for kind in KINDS:
            b = metrics[model][kind]
            values = {f"emax_{unit}", "r2", f"sse_{unit}2", f"rmse_{unit}"}
            for k in values:
                v = b[k]
                assert v is None or (isinstance(v, float | int) and not isinstance(v, bool)
                                     and math.isfinite(v)), (where, model, kind, k, v)
            has_null = any(b[k] is None for k in values)
            if has_null:
                assert set(b) == values | {"why_null"}, (where, model, kind, sorted(b))
                assert isinstance(b["why_null"], str) and b["why_null"].strip(), (where, model, kind)
                nulls.append(f"{where}.{model}.{kind}")
            else:
                assert set(b) == values, (where, model, kind, sorted(b))
    return nulls


@pytest.fixture(scope="module")
def eleven(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("fit11")
    syn = make_dataset(tmp / "d", n_targets={"X": 11, "Y": 21, "Z": 16}, n_runs=3,
                       wave_period_mm=130.0, seed=3)
    out = tmp / "out"
    assert main(["fit", str(syn.machine), "-o", str(out), "--no-clib-check", "--no-report", "-q"]) == 0
    return json.loads((out / "model.json").read_text(), parse_constant=_no_constants)


def test_every_metrics_block_follows_the_documented_schema(eleven) -> None:
    nulls = []
    for a, ax in eleven["axes"].items():
        for t, tj in ax["terms"].items():
            nulls += validate_metrics(tj["metrics"], tj["unit"], f"{a}.{t}")
    # the paper's Fourier on the 11-target line: its held-out folds cannot be fitted
    assert {n for n in nulls if n.startswith("X.")} == {
        f"X.{t}.paper_fourier3.held_out" for t in ("dx", "dy", "dz", "ex", "ey", "ez")}
    why = eleven["axes"]["X"]["terms"]["dx"]["metrics"]["paper_fourier3"]["held_out"]["why_null"]
    assert "of 11 targets have no held-out prediction" in why and "3rd-order Fourier" in why
    assert "why_null" in eleven["metrics_note"]


def test_the_schema_check_can_fail() -> None:
    good = {m: {k: {"emax_um": 1.0, "r2": 0.5, "sse_um2": 2.0, "rmse_um": 0.1} for k in KINDS}
            for m in MODELS}
    assert validate_metrics(good, "um", "t") == []
    bad = json.loads(json.dumps(good))
    bad["paper_fourier3"]["held_out"]["r2"] = None  # a null without why_null
    with pytest.raises(AssertionError):
        validate_metrics(bad, "um", "t")
    with pytest.raises(AssertionError):
        json.loads('{"r2": NaN}', parse_constant=_no_constants)
