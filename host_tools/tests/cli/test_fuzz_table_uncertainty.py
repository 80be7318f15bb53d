"""Fuzzing of the reader ``abbe table uncertainty`` uses (a fit's model.json: the table block
and the ``uncertainty`` block's covariances; ``abbe.cli.table_uncertainty._load`` and
``abbe.analysis.fit.uncertainty.terms_from_json``), in the style of
tests/formats/test_fuzz_readers.py: seeded, bounded (hypothesis, derandomized), part of CI.

Byte mutation (fuzzing.mutate) and JSON-structure mutation (a node of the document replaced
by a hostile value): the command either answers (exit 0, finite numbers) or refuses with
exit 2 and one line naming the file -- never another exception. A covariance made
asymmetric, negative on its diagonal, or holding a non-finite number must be refused.
"""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from fuzz_budget import DERANDOMIZE, examples

from abbe.cli.entry import main
from abbe.cli.table_uncertainty import _load
from abbe.analysis.fit.uncertainty import terms_from_json
from abbe.errors import AbbeInputError
from cases.synthetic_laser import make_dataset
from fuzzing.mutate import mutate

#: Kept small: each case reads a model.json of ~130 kB (the CI budget of issue 37's tests).
FUZZ = settings(max_examples=examples(40), derandomize=DERANDOMIZE, database=None, deadline=None,
                suppress_health_check=list(HealthCheck))

#: Values a node may be replaced by (JSON has no NaN: Python's json writes it as ``NaN``,
#: which a strict reader must refuse; the others have the wrong type, shape or size).
HOSTILE_VALUES: list[Any] = [float("nan"), float("inf"), -1e308, 1e308, "1.0", None, True,
                             [], {}, [[1.0]], [[1.0, 2.0], [3.0, 4.0]], -1.0, 0, "X",
                             [float("nan")] * 3, {"X": {}}]


@pytest.fixture(scope="module")
def model_json(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("fuzz_tu")
    syn = make_dataset(tmp / "d", n_targets={"X": 11, "Y": 9, "Z": 7}, n_runs=2,
                       wave_period_mm=130.0, seed=8)
    out = tmp / "out"
    assert main(["fit", str(syn.machine), "-o", str(out), "--no-clib-check", "--no-report",
                 "-q"]) == 0
    return out / "model.json"


def _read(p: Path) -> None:
    """The reader of ``abbe table uncertainty``: the model.json, then its covariances."""
    table, d, name = _load(p)
    terms_from_json(d["uncertainty"], table, name)


def _run_command(p: Path, capsys) -> None:
    """The whole command on the file: exit 0 with finite numbers, or exit 2 naming it."""
    rc = main(["table", "uncertainty", str(p), "100", "-50", "-40", "--json", "-"])
    cap = capsys.readouterr()
    assert rc in (0, 2), (rc, cap.err[-400:])
    if rc == 2:
        msg = cap.err.strip()
        assert p.name in msg and msg.count("\n") == 0, msg[:400]
    else:
        d = json.loads(cap.out)
        for pt in d["points"]:
            assert all(math.isfinite(v) for v in pt["error_um"] + pt["U_um"]), pt


def test_the_seed_is_read(model_json: Path, capsys) -> None:
    _read(model_json)
    _run_command(model_json, capsys)


def test_mutated_bytes_are_read_or_refused(model_json: Path) -> None:
    seed = model_json.read_bytes()

    @FUZZ
    @given(st.data())
    def run(data):
        pick = lambda n: data.draw(st.integers(0, max(n - 1, 0)))  # noqa: E731
        blob, _ = mutate(seed, pick, data.draw(st.integers(1, 4)))
        with tempfile.TemporaryDirectory() as d:
            p = Path(d) / "model.json"
            p.write_bytes(blob)
            try:
                _read(p)
            except AbbeInputError as e:
                assert e.file is not None and "\n" not in str(e), str(e)

    run()


def _nodes(doc: Any, path: tuple = ()) -> list[tuple]:
    """Every path into the document's table and uncertainty blocks (dict keys, list indices)."""
    out = [path] if path else []
    if isinstance(doc, dict):
        for k, v in doc.items():
            if path or k in ("table", "uncertainty"):
                out += _nodes(v, path + (k,))
    elif isinstance(doc, list) and len(doc) <= 64:
        for i, v in enumerate(doc):
            out += _nodes(v, path + (i,))
    return out


def _set(doc: Any, path: tuple, value: Any) -> None:
    for k in path[:-1]:
        doc = doc[k]
    doc[path[-1]] = value


def test_hostile_json_nodes_are_refused_or_answered(model_json: Path, capsys) -> None:
    base = json.loads(model_json.read_text())
    paths = _nodes(base)
    # the covariances themselves are the reader's own checks: weight them
    cov = [p for p in paths if any(isinstance(k, str) and k.startswith("covariance_") for k in p)]
    assert cov, "the seed carries no covariance: the fixture is not a fit with uncertainty"

    @FUZZ
    @given(st.sampled_from(paths + cov * 3), st.sampled_from(HOSTILE_VALUES))
    def run(path, value):
        doc = json.loads(model_json.read_text())
        _set(doc, path, value)
        with tempfile.TemporaryDirectory() as d:
            p = Path(d) / "model.json"
            p.write_text(json.dumps(doc))
            _run_command(p, capsys)

    run()


@pytest.mark.parametrize("how", ["asymmetric", "negative variance", "nan"])
def test_a_broken_covariance_is_refused(model_json: Path, tmp_path: Path, capsys, how) -> None:
    doc = json.loads(model_json.read_text())
    ax = next(iter(doc["uncertainty"]["axes"].values()))
    td = next(iter(ax["terms"].values()))
    key = next(k for k in td if k.startswith("covariance_"))
    m = td[key]
    assert len(m) >= 2
    if how == "asymmetric":
        m[0][1] = m[0][1] + 10.0 * max(abs(m[0][0]), 1.0)
    elif how == "negative variance":
        m[1][1] = -abs(m[1][1]) - 1.0
    else:
        m[1][0] = float("nan")
    p = tmp_path / "model.json"
    p.write_text(json.dumps(doc))
    assert main(["table", "uncertainty", str(p), "0", "0", "0"]) == 2
    err = capsys.readouterr().err
    assert "model.json" in err and "covariance" in err, err
