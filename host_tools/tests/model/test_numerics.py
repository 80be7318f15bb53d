"""The a-priori error bounds of docs/numerics.md, checked against the C library."""

from __future__ import annotations

import numpy as np
import pytest

from abbe.formats import blob as table
from abbe.formats import golden
from abbe.model.numerics import error_bound
from abbe.model.reference import spatial_error


def _tables() -> list[tuple[str, table.Table]]:
    return [(g.name, table.quantize(g.table)) for g in golden.golden_tables()]


def test_fixed_point_bound_within_2nm_for_every_golden_table() -> None:
    for name, t in _tables():
        assert max(error_bound(t).q_nm) < 2.0, name


def test_f32_bound_within_2nm_for_the_paper_sized_table() -> None:
    t = table.quantize(golden.paper_table())
    assert max(error_bound(t).f32_nm) < 2.0


def test_bound_grows_with_the_table() -> None:
    """A bound that cannot fail is no bound: scaling every coefficient scales it."""
    t = table.quantize(golden.paper_table())
    base = max(error_bound(t).f32_nm)
    for axis in t.axes.values():
        for term in axis.coef:
            axis.coef[term] = axis.coef[term] * 10.0
    assert max(error_bound(t).f32_nm) > 5 * base


def test_c_library_within_bound() -> None:
    clib = pytest.importorskip("abbe.model.clib")
    try:
        probe = clib.CModel(table.write_blob(table.quantize(golden.paper_table())))
    except (OSError, FileNotFoundError) as exc:  # library not built
        pytest.skip(f"C library not available: {exc}")
    del probe
    rng = np.random.default_rng(11)
    for name, t in _tables():
        cm = clib.CModel(table.write_blob(t))
        lo = np.array([t.axes[a].travel_mm[0] for a in table.AXES])
        hi = np.array([t.axes[a].travel_mm[1] for a in table.AXES])
        pos = lo + (hi - lo) * rng.random((3000, 3))
        pos_f = pos.astype(np.float32).astype(float)
        err_f, _ = cm.error_f32(pos_f)
        pos_nm = np.round(pos * 1e6).astype(np.int64)
        err_q, _ = cm.error_q(pos_nm)
        b = error_bound(t)
        got_f = np.abs(err_f - spatial_error(t, pos_f)).max(axis=0) * 1e3
        got_q = np.abs(err_q / 1e3 - spatial_error(t, pos_nm / 1e6)).max(axis=0) * 1e3
        assert np.all(got_f <= np.asarray(b.f32_nm)), (name, got_f, b.f32_nm)
        assert np.all(got_q <= np.asarray(b.q_nm)), (name, got_q, b.q_nm)
        assert got_q.max() < 2.0 and got_f.max() < 2.0, name
