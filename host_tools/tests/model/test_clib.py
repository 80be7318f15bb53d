"""The C library (through abbe.model.clib) against the float64 reference and the Python reader.

Skipped when the shared library is not built (cmake --build build), or point
ABBE_LIB at a libabbe.so.
"""

from __future__ import annotations

import zlib

import numpy as np
import pytest

from abbe.formats import golden
from abbe.formats.blob import read_blob, write_blob
from abbe.model import clib
from abbe.model.examples import paper_table
from abbe.model.reference import out_of_travel, spatial_error, term_values
from abbe.model.table import AXES, TERMS, AxisTable, FourierBlock, Table, TableError

if not clib.available():
    pytest.skip(f"C library not built: {clib.library_path()} missing (build with cmake, or set "
                "ABBE_LIB)", allow_module_level=True)

from table_helpers import crafted_cases, small_table

TOL_NM = golden.TOL_PM / 1000.0


@pytest.fixture(scope="module")
def golden_sets() -> list[tuple[golden.GoldenTable, golden.Points, golden.Terms]]:
    rng = np.random.default_rng(golden.SEED + 1)     # the same draws as the committed files
    out = []
    for gt in golden.golden_tables():
        out.append((gt, golden.make_points(rng, gt), golden.make_terms(rng, gt)))
    return out


def test_crc32_known_value() -> None:
    assert clib.crc32(b"123456789") == 0xCBF43926
    assert clib.crc32(b"56789", clib.crc32(b"1234")) == 0xCBF43926


def test_models_load_with_python_crc(golden_sets) -> None:
    for gt, _, _ in golden_sets:
        m = clib.CModel(gt.blob)
        assert m.crc == zlib.crc32(gt.blob[:-4]) == int.from_bytes(gt.blob[-4:], "little")
        assert m.features == gt.table.features()
        assert m.size == len(gt.blob)


def test_error_f32_and_q_match_reference_on_golden_tables(golden_sets) -> None:
    worst = {}
    for gt, p, _ in golden_sets:
        m = clib.CModel(gt.blob)
        ef, ff = m.error_f32(p.pos_f32, p.dir_f32, p.temp_f32)
        eq, fq = m.error_q(p.pos_nm, p.dir_q30, p.temp_mdegc)
        d_f = np.abs(ef * 1e3 - p.expect_f32_pm / 1e3).max()
        d_q = np.abs(eq - p.expect_q_pm / 1e3).max()
        worst[gt.name] = (d_f, d_q)
        assert d_f <= TOL_NM, (gt.name, d_f)
        assert d_q <= TOL_NM, (gt.name, d_q)
        np.testing.assert_array_equal(ff & clib.FLAG_OUT_OF_TRAVEL, p.flags)
        np.testing.assert_array_equal(fq & clib.FLAG_OUT_OF_TRAVEL, p.flags)
        assert not np.any(fq & clib.FLAG_SATURATED)
    print("worst |C - reference| nm (f32, q):", worst)


def test_terms_match_reference_on_golden_tables(golden_sets) -> None:
    for gt, _, tr in golden_sets:
        m = clib.CModel(gt.blob)
        for a, k, pf, pn, ef, eq in zip(tr.axis, tr.term, tr.pos_f32, tr.pos_nm,
                                        tr.expect_f32, tr.expect_q):
            if k == golden.REVERSAL_TERM:                        # the total reversal, pm
                vf = m.reversal_f32(int(a), [pf])[0] * 1e6
                vq = m.reversal_q(int(a), [pn])[0]
                name = "reversal"
            else:
                vf = m.term_f32(int(a), int(k), [pf])[0] * 1e6      # um / urad -> pico
                vq = m.term_q(int(a), int(k), [pn])[0]
                name = TERMS[k]
            assert abs(vf - ef) <= golden.TOL_PM, (gt.name, AXES[a], name, vf, ef)
            assert abs(vq - eq) <= golden.TOL_PM, (gt.name, AXES[a], name, vq, eq)


def test_random_positions_paper_table() -> None:
    t_blob = write_blob(paper_table())
    t = read_blob(t_blob)
    m = clib.CModel(t_blob)
    rng = np.random.default_rng(11)
    pos = rng.uniform([-50, -450, -350], [550, 50, 50], size=(300, 3))
    pos32 = pos.astype(np.float32).astype(np.float64)
    ef, ff = m.error_f32(pos32)
    np.testing.assert_allclose(ef, spatial_error(t, pos32), atol=TOL_NM * 1e-3, rtol=0)
    np.testing.assert_array_equal(ff & 1, out_of_travel(t, pos32).astype(int))
    pnm = np.rint(pos * 1e6).astype(np.int64)
    eq, _ = m.error_q(pnm)
    np.testing.assert_allclose(eq / 1e3, spatial_error(t, pnm / 1e6), atol=TOL_NM * 1e-3, rtol=0)
    for a in AXES:
        x = rng.uniform(-600, 600, 20).astype(np.float32)
        for k in TERMS:
            np.testing.assert_allclose(m.term_f32(a, k, x), term_values(t, a, k, x),
                                       atol=TOL_NM * 1e-3, rtol=0)


# Basis shapes: (trend degree, harmonics of block 0, of block 1) of X; Y and Z take
# the next two shapes in the list, so the three axes of a table always differ
# (the x86-64 kernels run some steps for the three axes at once, to the largest count).
_SHAPES = [(None, 1, 0), (0, 0, 0), (1, 3, 0), (2, 0, 2), (3, 8, 0), (4, 1, 1), (5, 2, 8),
           (6, 0, 0), (7, 8, 8), (1, 0, 5), (None, 4, 3), (0, 7, 0)]


@pytest.mark.parametrize("first", range(len(_SHAPES)))
def test_basis_shapes_every_kernel_set(first: int) -> None:
    """Every trend degree 0..7 (and none), 0..8 harmonics in either block, all six terms:
    the f32 kernels this CPU has (x86-64: SSE2 and x86-64-v3) and q against float64."""
    rng = np.random.default_rng(1000 + first)
    axes = {}
    for j, a in enumerate(AXES):
        degree, h0, h1 = _SHAPES[(first + j) % len(_SHAPES)]
        lo = float(rng.uniform(-400, 0))
        blocks = (FourierBlock(float(rng.uniform(20, 400)), float(rng.uniform(-50, 50)), h0) if h0 else None,
                  FourierBlock(float(rng.uniform(2, 20)), float(rng.uniform(-5, 5)), h1) if h1 else None)
        ax = AxisTable(travel_mm=(lo, lo + float(rng.uniform(100, 800))), trend_degree=degree, blocks=blocks)
        n = ax.n_basis()
        ax.coef = {k: rng.normal(0.0, 2.0 if k.startswith("d") else 5.0, n) for k in TERMS}
        axes[a] = ax
    t = Table(axes=axes, reference_mm=(10.0, -20.0, 30.0), tool_offset_mm=(5.0, -3.0, 120.0),
              squareness_urad=(12.0, -7.0, 4.0))
    m = clib.CModel(write_blob(t))
    pos = np.column_stack([rng.uniform(*axes[a].travel_mm, 200) for a in AXES]).astype(np.float32)
    pos = pos.astype(np.float64)
    want = spatial_error(t, pos)
    detected = m._model.simd
    for simd in sorted({0, detected}):                 # x86-64: 0 = SSE2, 1 = x86-64-v3
        m._model.simd = simd
        ef, _ = m.error_f32(pos)
        np.testing.assert_allclose(ef, want, atol=TOL_NM * 1e-3, rtol=0, err_msg=f"kernels {simd}")
    m._model.simd = detected
    eq, _ = m.error_q(np.rint(pos * 1e6).astype(np.int64))
    np.testing.assert_allclose(eq / 1e3, want, atol=TOL_NM * 1e-3, rtol=0)


def test_reversal_block_at_the_cap() -> None:
    """|B| + sum |r_k| at the loader's cap (8388 um of 8388.6): no overflow in the fixed
    point sums, both variants within the numerics bound, the direction state and the
    block's end values as the reference has them; abbe_reversal_eval_q saturates to
    int32 pm beyond 2147 um (documented), _f32 does not."""
    from abbe.model.numerics import error_bound
    from abbe.model.reference import reversal_values
    t = golden.reversal_sparse_table(np.random.default_rng(3))
    t.axes["Y"].backlash_um = -4000.0
    t.axes["Y"].reversal_cheb_um = (600.0, -1000.0, 800.0, -600.0, 500.0, -400.0, 300.0, -188.0)
    blob = write_blob(t)
    q = read_blob(blob)
    m = clib.CModel(blob)
    rng = np.random.default_rng(4)
    lo = np.array([q.axes[a].travel_mm[0] for a in AXES])
    hi = np.array([q.axes[a].travel_mm[1] for a in AXES])
    span = hi - lo
    pos = lo - 0.1 * span + 1.2 * span * rng.random((4000, 3))   # outside the travel too
    d = rng.uniform(-1.0, 1.0, (4000, 3))
    pn, dq = np.rint(pos * 1e6), np.rint(d * 2**30)
    eq, fq = m.error_q(pn, dq)
    assert not np.any(fq & clib.FLAG_SATURATED)
    b = error_bound(q)
    got_q = np.abs(eq / 1e3 - spatial_error(q, pn / 1e6, dq / 2**30)).max(axis=0) * 1e3
    assert np.all(got_q <= np.asarray(b.q_nm)) and got_q.max() < 2.0, got_q
    pf, df = pos.astype(np.float32).astype(float), d.astype(np.float32).astype(float)
    got_f = np.abs(m.error_f32(pf, df)[0] - spatial_error(q, pf, df)).max(axis=0) * 1e3
    assert np.all(got_f <= np.asarray(b.f32_nm)), (got_f, b.f32_nm)
    ends = np.array([-600.0, -10.0])
    r = reversal_values(q, "Y", ends)
    assert abs(r[1]) > 2147.0 > abs(r[0])
    np.testing.assert_allclose(m.reversal_f32("Y", ends), r, rtol=1e-6)
    assert list(m.reversal_q("Y", ends * 1e6)) == [round(r[0] * 1e6), -(1 << 31)]


@pytest.mark.parametrize("name,status,blob", crafted_cases(), ids=[c[0] for c in crafted_cases()])
def test_c_loader_agrees_with_python_reader(name: str, status: str, blob: bytes) -> None:
    with pytest.raises(TableError) as exc:
        clib.CModel(blob, source="crafted.bin")
    assert exc.value.status == status, f"{name}: C says {exc.value.status}"


def test_c_loader_truncated_at_every_byte() -> None:
    blob = write_blob(small_table())
    clib.CModel(blob + b"\0" * 8)                     # extra bytes are fine
    for n in range(len(blob)):
        with pytest.raises(TableError) as exc:
            clib.CModel(blob[:n])
        assert exc.value.status == "ABBE_E_TRUNCATED", n


def test_compensator_follows_the_model() -> None:
    blob = write_blob(paper_table())
    m = clib.CModel(blob)
    cfg = {"warn_nm": 100_000, "limit_nm": 200_000, "rate_nm_per_cycle": 1_000_000,
           "fade_cycles": 4, "stale_cycles": 3, "axis_sign": [1, -1, 1]}
    comp = clib.CCompensator(cfg, m)
    pos_mm = [400.0, -300.0, -100.0]
    pos_nm = [int(round(v * 1e6)) for v in pos_mm]
    err_nm, _ = m.error_q([pos_nm])
    want = -err_nm[0] * np.array([1, -1, 1])
    out = comp.step_q(pos_nm)
    assert out["state"] == "OFF" and not np.any(out["corr_nm"])
    comp.enable()
    for _ in range(10):
        out = comp.step_q(pos_nm)
    assert out["state"] == "ON"
    np.testing.assert_allclose(out["target_nm"], want, atol=1)
    np.testing.assert_allclose(out["corr_nm"], out["target_nm"], atol=1)
    out_f = comp.step_f32(pos_mm)
    np.testing.assert_allclose(out_f["corr_nm"], want, atol=2)
    # a damaged table is refused; the running model goes on
    bad = bytearray(blob)
    bad[300] ^= 1
    with pytest.raises(TableError) as exc:
        comp.load_model(bytes(bad))
    assert exc.value.status == "ABBE_E_CRC"
    assert comp.has_model()
    stats = comp.stats()
    assert stats["cycles"] == 12
    # a valid new model is swapped in at the next step
    comp.load_model(write_blob(small_table()))
    comp.step_q(pos_nm)
    assert comp.stats()["model_swaps"] >= 1


def test_missing_library_message(monkeypatch, tmp_path) -> None:
    monkeypatch.setenv("ABBE_LIB", str(tmp_path / "nope.so"))
    assert clib.library_path() == tmp_path / "nope.so"
    monkeypatch.setattr(clib.library, "_LIB", None)  # the cache of load_library
    with pytest.raises(clib.LibraryNotFound, match="nope.so"):
        clib.load_library()
