"""The golden export files of examples/vmc500 (reviewed by eye once, kept): every
target regenerated from the kept models must match them (numbers to their printed
precision; see golden_compare.py for the tolerance and how to regenerate)."""

from __future__ import annotations

import pytest
from golden_compare import GOLDEN, MODELS, compare_dir, export_all

from abbe.exports import TARGETS


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


def test_the_kept_fit_model_is_what_abbe_fit_gives(tmp_path) -> None:
    """The golden fit model is `abbe fit examples/vmc500/machine.toml` (within 0.01 um over
    the work volume). If the fit changed on purpose, regenerate the golden files
    (golden_compare.py --write after copying the new model.bin) and review them."""
    import numpy as np

    from abbe.cli.entry import main
    from abbe.formats.model_file import load_table
    from abbe.model.reference import spatial_error
    from golden_compare import MACHINE
    assert main(["fit", str(MACHINE), "-o", str(tmp_path / "fit"), "--no-clib-check",
                 "--no-report", "-q"]) == 0
    a = load_table(tmp_path / "fit" / "model.bin")
    b = load_table(GOLDEN / "vmc500-fit" / "model.bin")
    P = np.random.default_rng(2).random((3000, 3)) * [500.0, -400.0, -300.0]
    assert np.max(np.abs(spatial_error(a, P) - spatial_error(b, P))) < 0.01
