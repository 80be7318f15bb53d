"""The golden export files of examples/vmc500 (reviewed by eye once, kept): every
target regenerated from the kept models must match them (numbers to their printed
precision; see golden_compare.py for the tolerance and how to regenerate)."""

from __future__ import annotations

import pytest
from golden_compare import GOLDEN, MODELS, compare_dir, export_all

from abbe.formats.export import TARGETS


@pytest.mark.parametrize("model", MODELS)
def test_exports_match_the_golden_files(tmp_path, model) -> None:
    want = GOLDEN / model
    assert sorted(p.name for p in want.iterdir() if p.is_dir()) == sorted(TARGETS)
    export_all(want, tmp_path)
    errs = []
    for t in TARGETS:
        errs += compare_dir(tmp_path / t, want / t)
    assert not errs, "\n".join(errs)


def test_the_comparison_can_fail(tmp_path) -> None:
    from golden_compare import compare_json, compare_text
    assert compare_text("X 1.0002", "X 1.0000", "f")  # beyond one unit of the 4th decimal
    assert not compare_text("X 1.0001", "X 1.0000", "f")
    assert compare_text("X 1.0", "Y 1.0", "f")
    assert compare_json({"a": 1.001}, {"a": 1.0}, "r")
    assert not compare_json({"a": 1.0001}, {"a": 1.0}, "r")
