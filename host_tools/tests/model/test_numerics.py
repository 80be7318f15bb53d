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


def test_reversal_block_widens_the_bound() -> None:
    """The reversal block enters the bound: a larger block, a larger bound."""
    t = table.quantize(golden.reversal_table())
    base = table.quantize(golden.backlash_table())
    assert max(error_bound(t).q_nm) > max(error_bound(base).q_nm)
    assert max(error_bound(t).f32_nm) > max(error_bound(base).f32_nm)
    t.axes["Y"].reversal_cheb_um = tuple(10.0 * c for c in t.axes["Y"].reversal_cheb_um)
    assert error_bound(t).f32_nm[1] > error_bound(table.quantize(golden.reversal_table())).f32_nm[1]


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
        # direction states in [-1, 1]: the backlash and the reversal blocks take part
        dirs = rng.uniform(-1.0, 1.0, (3000, 3))
        dir_f = dirs.astype(np.float32).astype(float)
        dir_q30 = np.rint(dirs * 2**30).astype(np.int64)
        err_f, _ = cm.error_f32(pos_f, dir_f)
        pos_nm = np.round(pos * 1e6).astype(np.int64)
        err_q, _ = cm.error_q(pos_nm, dir_q30)
        b = error_bound(t)
        got_f = np.abs(err_f - spatial_error(t, pos_f, dir_f)).max(axis=0) * 1e3
        got_q = np.abs(err_q / 1e3 - spatial_error(t, pos_nm / 1e6, dir_q30 / 2.0**30)).max(axis=0) * 1e3
        print(f"{name}: q bound {max(b.q_nm):.2f} measured {got_q.max():.2f} nm, "
              f"f32 bound {max(b.f32_nm):.3f} measured {got_f.max():.3f} nm")
        assert np.all(got_f <= np.asarray(b.f32_nm)), (name, got_f, b.f32_nm)
        assert np.all(got_q <= np.asarray(b.q_nm)), (name, got_q, b.q_nm)
        assert got_q.max() < 2.0 and got_f.max() < 2.0, name
