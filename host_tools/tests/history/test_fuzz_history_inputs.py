"""Fuzzing of what ``abbe history add`` reads (abbe.history.ingest.read_campaign: the JSON
of abbe ballbar / iso230-2, the fit and diagnose folders), seeded and bounded (part of
CI; a long run by hand with ``ABBE_FUZZ_SCALE``, tests/fuzz_budget.py).

Bytes mutated (fuzzing.mutate) and JSON nodes replaced by hostile values: the reader
either returns a campaign whose every stored number is finite, or raises AbbeInputError
in one line -- never another exception. Nothing is written to a database here: the
reader is the part that sees untrusted bytes.
"""

from __future__ import annotations

import json
import math
import shutil
import tempfile
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from abbe.errors import AbbeInputError
from abbe.history.ingest import read_campaign
from fuzz_budget import DERANDOMIZE, examples
from fuzzing.mutate import mutate

#: Values a JSON node may be replaced by (Python's json writes NaN / Infinity, which a
#: strict reader must refuse; the others have the wrong type, size or shape).
HOSTILE_VALUES: list[Any] = [float("nan"), float("inf"), -float("inf"), 1e308, -1e308, 10 ** 400,
                             "1.0", "", None, True, [], {}, [[1.0]], -1.0, 0, "X",
                             [float("nan")] * 3, {"X": {}}, "\udcff", "a" * 5000]


def fuzz(n: int) -> settings:
    return settings(max_examples=examples(n), derandomize=DERANDOMIZE, database=None,
                    deadline=None, suppress_health_check=list(HealthCheck))


#: (what, the file mutated relative to the input, the input: a file or a folder, --axis)
CASES = {
    "ballbar": ("ballbar.json", "ballbar.json", {}),
    "iso230-2": ("iso_x.json", "iso_x.json", {"": "X"}),
    "fit": ("fit/model.json", "fit", {}),
    "diagnose": ("diagnose/diagnose.json", "diagnose", {}),
}


def _read(root: Path, case: str) -> None:
    _, arg, axes = CASES[case]
    try:
        c = read_campaign([str(root / arg)], dict(axes), "vmc500")
    except AbbeInputError as e:
        assert "\n" not in str(e), str(e)
        assert "np.float64" not in str(e), str(e)
        return
    for r in c.results:
        assert isinstance(r.value, float) and math.isfinite(r.value), r
        for v in (r.ci_low, r.ci_high, r.feed_mm_min):
            assert v is None or math.isfinite(v), r
    assert all(math.isfinite(t) for _, t in c.temperatures), c.temperatures


@pytest.fixture(scope="module")
def work(outputs, tmp_path_factory) -> Path:
    """A copy of the outputs (the fuzz writes into it), without the large figures."""
    d = tmp_path_factory.mktemp("hist_fuzz") / "out"
    shutil.copytree(outputs, d, ignore=shutil.ignore_patterns("*.png", "*.svg", "*.html"))
    return d


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_seed_is_read(work, case):
    _, arg, axes = CASES[case]
    assert read_campaign([str(work / arg)], dict(axes), "vmc500").results


def _with(work: Path, case: str, blob: bytes, tmp: Path) -> Path:
    """A copy of the input ``case`` under ``tmp`` whose mutated file holds ``blob``."""
    rel, arg, _ = CASES[case]
    src = work / arg
    if src.is_dir():
        shutil.copytree(src, tmp / arg)
    else:
        (tmp / arg).parent.mkdir(parents=True, exist_ok=True)
    (tmp / rel).write_bytes(blob)
    return tmp


@pytest.mark.parametrize("case", sorted(CASES))
def test_mutated_bytes_are_read_or_refused(work, case):
    seed = (work / CASES[case][0]).read_bytes()

    @fuzz(30)
    @given(st.data())
    def run(data):
        pick = lambda n: data.draw(st.integers(0, max(n - 1, 0)))  # noqa: E731
        blob, _ = mutate(seed, pick, data.draw(st.integers(1, 4)))
        with tempfile.TemporaryDirectory() as d:
            _read(_with(work, case, blob, Path(d)), case)

    run()


def _nodes(doc: Any, path: tuple = ()) -> list[tuple]:
    out = [path] if path else []
    if isinstance(doc, dict):
        for k, v in doc.items():
            out += _nodes(v, path + (k,))
    elif isinstance(doc, list) and len(doc) <= 64:
        for i, v in enumerate(doc):
            out += _nodes(v, path + (i,))
    return out


@pytest.mark.parametrize("case", sorted(CASES))
def test_hostile_json_nodes_are_refused_or_stored_finite(work, case):
    base = json.loads((work / CASES[case][0]).read_text())
    paths = _nodes(base)

    @fuzz(40)
    @given(st.sampled_from(paths), st.sampled_from(HOSTILE_VALUES))
    def run(path, value):
        doc = json.loads((work / CASES[case][0]).read_text())
        node = doc
        for k in path[:-1]:
            node = node[k]
        node[path[-1]] = value
        blob = json.dumps(doc).encode("utf-8", errors="surrogatepass")
        with tempfile.TemporaryDirectory() as d:
            _read(_with(work, case, blob, Path(d)), case)

    run()
