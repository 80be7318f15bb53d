"""abbe.formats.blob: blob writer/reader, every validation status, JSON, generated C, CLI."""

from __future__ import annotations

import json
import math
import re
import shutil
import struct
import subprocess
import zlib
from pathlib import Path

import numpy as np
import pytest
from table_helpers import (  # noqa: F401  (shared with model/test_clib.py)
    A_BQ8,
    A_COUNT,
    A_DEG,
    A_EXP,
    A_FOFF,
    A_H0,
    A_H1,
    A_MASK,
    A_O0,
    A_O1,
    A_OFF,
    A_P0,
    A_P1,
    A_QOFF,
    A_RES,
    A_REV_ROWS,
    A_TAKEUP,
    A_TMAX,
    A_TMIN,
    A_TREF,
    H_ASIZE,
    H_FEAT,
    H_HSIZE,
    H_REF,
    H_RES,
    H_SQ,
    H_TOOL,
    H_TOTAL,
    _patch_column,
    _patch_values,
    axis_off,
    crafted_cases,
    crafted_reversal_cases,
    patch,
    reversal_table,
    small_table,
    tiny_table,
)
from textnum import differences

from abbe import cli
from abbe.cli.example_table import write_example
from abbe.errors import AbbeInputError
from abbe.formats.blob import quantization_error, quantize, read_blob, write_blob
from abbe.formats.c_source import write_c
from abbe.formats.table_json import table_from_json, table_to_json
from abbe.model.examples import paper_table
from abbe.model.table import AXES, TERMS, AxisTable, FourierBlock, Table, TableError, basis_matrix

REPO = Path(__file__).resolve().parents[3]


# --------------------------------------------------------------------------- round trips


def assert_tables_equal(a: Table, b: Table) -> None:
    assert a.reference_mm == b.reference_mm
    assert a.tool_offset_mm == b.tool_offset_mm
    assert a.squareness_urad == b.squareness_urad
    for ax in AXES:
        p, q = a.axes[ax], b.axes[ax]
        assert p.travel_mm == q.travel_mm
        assert p.trend_degree == q.trend_degree
        assert p.blocks == q.blocks
        assert sorted(p.coef) == sorted(q.coef)
        for t in p.coef:
            np.testing.assert_array_equal(p.coef[t], q.coef[t])
        for f in ("backlash_um", "backlash_takeup_mm", "thermal_expansion_ppm_per_k",
                  "thermal_offset_um_per_k", "thermal_tref_c", "reversal_cheb_um"):
            assert getattr(p, f) == getattr(q, f), f


@pytest.mark.parametrize("make", [small_table, tiny_table, paper_table, reversal_table])
def test_blob_round_trip(make) -> None:
    t = make()
    blob = write_blob(t)
    back = read_blob(blob)
    assert_tables_equal(back, quantize(t))
    assert write_blob(back) == blob          # quantized values are fixed points
    assert read_blob(blob + b"\xff" * 13).axes["X"].travel_mm == back.axes["X"].travel_mm


def test_layout_matches_spec() -> None:
    t = small_table()
    blob = write_blob(t)
    assert blob[:4] == b"ABBE"
    assert struct.unpack_from("<HHIIII", blob, 4) == (1, 0, len(blob), 64, 64, 0xF)
    assert struct.unpack_from("<3i", blob, H_REF) == (100_000_000, -100_000_000, -50_000_000)
    assert struct.unpack_from("<3i", blob, H_TOOL) == (0, 0, 100_000_000)
    assert struct.unpack_from("<i", blob, H_SQ)[0] == round(20e-6 * 2**36)
    x = axis_off(0)
    assert struct.unpack_from("<iiBBBB", blob, x) == (0, 300_000_000, 0b100001, 1, 1, 0)
    assert struct.unpack_from("<i", blob, x + A_BQ8)[0] == 4000 * 256
    # 12 ppm/K is 13 510 799 in the spec; 11.5 ppm/K scales with it
    assert struct.unpack_from("<i", blob, x + A_EXP)[0] == round(11.5e-9 * 2**50)
    assert struct.unpack_from("<i", blob, x + A_OFF)[0] == round(0.5 * 65536)
    assert struct.unpack_from("<i", blob, x + A_TREF)[0] == 20000
    qoff, foff, count = struct.unpack_from("<III", blob, x + A_QOFF)
    assert (qoff, count) == (256, 8) and foff % 4 == 0 and foff >= qoff + 32
    q = np.frombuffer(blob, "<i4", count, qoff).reshape(4, 2)     # row-major rows x terms
    np.testing.assert_array_equal(q[:, 0], np.array([1.5, -2.25, 0.75, 0.5]) * 256000)
    np.testing.assert_array_equal(q[:, 1], np.rint(np.array([10.0, 5.0, -3.0, 1.0])
                                                   * 2**36 / 1e6))
    f = np.frombuffer(blob, "<f4", count, foff).reshape(4, 2)
    # the float32 twin: each int32 converted (round to nearest even), same units
    np.testing.assert_array_equal(f, q.astype(np.float32))
    z = axis_off(2)
    assert struct.unpack_from("<BBBB", blob, z + A_MASK) == (0, 255, 0, 0)
    assert struct.unpack_from("<III", blob, z + A_QOFF) == (0, 0, 0)
    assert struct.unpack_from("<I", blob, len(blob) - 4)[0] == zlib.crc32(blob[:-4])
    assert len(write_blob(tiny_table())) == 260


def test_layout_1_1_matches_spec() -> None:
    """Format 1.1: minor 1 and feature REVERSAL only for a table with a reversal block,
    the block's rows in byte 60 and after the matrix in both arrays (2^-8 nm)."""
    assert struct.unpack_from("<H", write_blob(small_table()), 6)[0] == 0
    blob = write_blob(reversal_table())
    assert struct.unpack_from("<HHIIII", blob, 4) == (1, 1, len(blob), 64, 64, 0x1F)
    x, y, z = axis_off(0), axis_off(1), axis_off(2)
    assert struct.unpack_from("<BBBB", blob, x + A_REV_ROWS) == (3, 0, 0, 0)
    assert struct.unpack_from("<I", blob, y + A_REV_ROWS)[0] == 0
    assert struct.unpack_from("<BBBB", blob, z + A_REV_ROWS) == (8, 0, 0, 0)
    qoff, foff, count = struct.unpack_from("<III", blob, x + A_QOFF)
    assert count == 4 * 2 + 3
    q = np.frombuffer(blob, "<i4", count, qoff)
    np.testing.assert_array_equal(q[8:], np.array([2.0, -6.5, 1.25]) * 256000)
    np.testing.assert_array_equal(np.frombuffer(blob, "<f4", count, foff), q.astype(np.float32))
    qz, fz, cz = struct.unpack_from("<III", blob, z + A_QOFF)
    assert cz == 8 and fz + 32 == len(blob) - 4        # Z's block is the last array
    np.testing.assert_array_equal(np.frombuffer(blob, "<i4", 8, qz),
                                  np.rint(np.array(reversal_table().axes["Z"].reversal_cheb_um)
                                          * 256000))
    # a 1.0 table is written byte for byte as before format 1.1 existed
    assert write_blob(paper_table()) == (REPO / "examples" / "paper_table" / "model.bin").read_bytes()


def test_reversal_reference_semantics() -> None:
    """R(p) = backlash_um + sum_k c_k T_k(u(p clamped)); the own term gets s R / 2; a
    one-coefficient block is a change of backlash_um."""
    from abbe.model.reference import reversal_values, spatial_error
    from abbe.model.table import reversal_matrix
    t = read_blob(write_blob(reversal_table()))
    p = np.array([-50.0, 0.0, 75.0, 150.0, 300.0, 400.0])
    u = (2 * np.clip(p, 0.0, 300.0) - 300.0) / 300.0
    want = 4.0 + 2.0 - 6.5 * u + 1.25 * (2 * u * u - 1)
    np.testing.assert_allclose(reversal_values(t, "X", p), want, atol=1e-12)
    np.testing.assert_allclose(reversal_matrix(t.axes["X"], p)[:, 2], 2 * u * u - 1, atol=1e-12)
    assert reversal_matrix(t.axes["Y"], p).shape == (6, 0)
    np.testing.assert_array_equal(reversal_values(t, "Y", p), 0.0)
    pos = np.tile(np.array(t.reference_mm), (p.size, 1))
    pos[:, 0] = p
    s = np.zeros_like(pos)
    s[:, 0] = 1.0
    d = spatial_error(t, pos, s) - spatial_error(t, pos, -s)
    np.testing.assert_allclose(d[:, 0], -want, atol=1e-12)       # dX = -d_x(x): -s R / 2
    c = small_table()
    c.axes["X"].reversal_cheb_um = (1.5,)
    b = small_table()
    b.axes["X"].backlash_um += 1.5
    np.testing.assert_allclose(spatial_error(c, pos, s), spatial_error(b, pos, s), atol=1e-12)
    assert c.axes["X"].has_reversal() and not tiny_table().axes["X"].has_reversal()
    z = tiny_table()
    z.axes["X"].reversal_cheb_um = (0.0, 0.0)
    assert not z.axes["X"].has_reversal() and z.features() == 0x14


def test_spec_example_encodings() -> None:
    """12 ppm/K = 13 510 799 and 1 um/K = 65 536 as the spec states."""
    t = tiny_table()
    for a in AXES:
        t.axes[a].thermal_expansion_ppm_per_k = 12.0
        t.axes[a].thermal_offset_um_per_k = 1.0
    blob = write_blob(t)
    assert struct.unpack_from("<ii", blob, axis_off(1) + A_EXP) == (13_510_799, 65_536)


def test_crc_known_value() -> None:
    assert zlib.crc32(b"123456789") == 0xCBF43926


def test_features_follow_values() -> None:
    t = tiny_table()
    assert t.features() == 0 and struct.unpack_from("<I", write_blob(t), H_FEAT)[0] == 0
    t.squareness_urad = (0.0, 0.0, 1.0)
    t.axes["Z"].thermal_tref_c = 21.0
    assert t.features() == 0x9
    assert struct.unpack_from("<I", write_blob(t), H_FEAT)[0] == 0x9
    # a value that rounds to zero does not switch a feature on
    t2 = tiny_table()
    t2.tool_offset_mm = (1e-8, 0.0, 0.0)
    assert struct.unpack_from("<I", write_blob(t2), H_FEAT)[0] == 0


# --------------------------------------------------------------------------- validation


@pytest.mark.parametrize("name,status,blob", crafted_cases(), ids=[c[0] for c in crafted_cases()])
def test_every_validation_status(name: str, status: str, blob: bytes) -> None:
    with pytest.raises(TableError) as exc:
        read_blob(blob, source="crafted.bin")
    assert exc.value.status == status, f"{name}: {exc.value}"
    assert exc.value.file == "crafted.bin"
    assert "crafted.bin" in str(exc.value) and status in str(exc.value)


def test_crafted_cases_touch_one_thing() -> None:
    """The unpatched blobs are valid, so each case fails for its own reason."""
    read_blob(write_blob(small_table()))
    read_blob(write_blob(reversal_table()))


@pytest.mark.parametrize("make", [small_table, reversal_table])
def test_truncated_at_every_byte(make) -> None:
    blob = write_blob(make())
    for n in range(len(blob)):
        with pytest.raises(TableError) as exc:
            read_blob(blob[:n])
        assert exc.value.status == "ABBE_E_TRUNCATED", n


def test_truncated_at_every_byte_tiny() -> None:
    blob = write_blob(tiny_table())
    assert len(blob) == 260
    for n in range(len(blob)):
        with pytest.raises(TableError) as exc:
            read_blob(blob[:n])
        assert exc.value.status == "ABBE_E_TRUNCATED"


def test_no_blob_is_arg() -> None:
    with pytest.raises(TableError) as exc:
        read_blob(None)  # type: ignore[arg-type]
    assert exc.value.status == "ABBE_E_ARG"


def test_check_order_first_failure_wins() -> None:
    good = write_blob(small_table())
    # bad magic and bad CRC: magic comes first
    b = patch(patch(good, 100, "B", good[100] ^ 0xFF, fix_crc=False), 0, "4s", b"XBBE",
              fix_crc=False)
    with pytest.raises(TableError, match="ABBE_E_MAGIC"):
        read_blob(b)
    # newer minor and wrong header size: version first
    b = patch(patch(good, 6, "H", 3), H_HSIZE, "I", 1)
    with pytest.raises(TableError, match="ABBE_E_VERSION_MINOR"):
        read_blob(b)
    # NaN and travel: NaN first; period and travel: period first
    foff = struct.unpack_from("<I", good, axis_off(0) + A_FOFF)[0]
    b = patch(patch(good, foff, "f", math.nan), axis_off(0) + A_TMAX, "i", -1)
    with pytest.raises(TableError, match="ABBE_E_NONFINITE"):
        read_blob(b)
    b = patch(patch(good, axis_off(0) + A_P0, "i", 0), axis_off(0) + A_TMAX, "i", -1)
    with pytest.raises(TableError, match="ABBE_E_PERIOD"):
        read_blob(b)
    # a bad CRC hides everything behind it
    b = patch(good, axis_off(0) + A_DEG, "B", 9, fix_crc=False)
    with pytest.raises(TableError, match="ABBE_E_CRC"):
        read_blob(b)


def test_error_names_the_field() -> None:
    good = write_blob(small_table())
    with pytest.raises(TableError) as exc:
        read_blob(patch(good, axis_off(1) + A_P1, "i", 0), source="m.bin")
    assert exc.value.field == "axes.Y.period_nm[1]"
    assert str(exc.value).startswith("m.bin: field 'axes.Y.period_nm[1]': ")


# --------------------------------------------------------------------------- writer refusals


def _writer_error(t: Table) -> TableError:
    with pytest.raises(TableError) as exc:
        write_blob(t)
    return exc.value


def test_writer_refuses_unrepresentable_values() -> None:
    t = small_table()
    t.axes["X"].travel_mm = (0.0, 2200.0)
    e = _writer_error(t)
    assert (e.status, e.field) == ("ABBE_E_RANGE", "axes.X.travel_mm")

    t = small_table()
    t.axes["X"].coef["dx"] = np.array([1.0, math.nan, 0.0, 0.0])
    e = _writer_error(t)
    assert (e.status, e.field) == ("ABBE_E_NONFINITE", "axes.X.coef.dx")

    t = small_table()
    t.axes["X"].coef["dx"] = np.zeros(3)
    assert _writer_error(t).status == "ABBE_E_COUNT"

    t = small_table()
    t.axes["X"].trend_degree = 8
    assert _writer_error(t).field == "axes.X.trend_degree"

    t = small_table()
    t.axes["X"].blocks = (FourierBlock(300.0, 0.0, 9), None)
    assert _writer_error(t).status == "ABBE_E_COUNT"

    t = small_table()
    t.axes["Y"].blocks = (None, FourierBlock(0.0, 0.0, 1))
    assert _writer_error(t).status == "ABBE_E_PERIOD"

    t = small_table()
    t.axes["Z"].travel_mm = (0.0, 0.0)
    assert _writer_error(t).status == "ABBE_E_TRAVEL"

    t = small_table()
    t.axes["X"].backlash_takeup_mm = 0.0        # X has backlash: it needs a take-up distance
    e = _writer_error(t)
    assert (e.status, e.field) == ("ABBE_E_RANGE", "axes.X.backlash_takeup_mm")

    t = small_table()
    t.axes["Z"].backlash_takeup_mm = 0.0        # Z has no backlash: 0 is allowed
    assert read_blob(write_blob(t)).axes["Z"].backlash_takeup_mm == 0.0

    t = small_table()
    t.squareness_urad = (0.0, 3907.0, 0.0)
    assert _writer_error(t).status == "ABBE_E_RANGE"

    t = small_table()
    t.axes["X"].coef["ez"] = np.array([3000.0, 1000.0, 0.0, 0.0])   # sum over 3906 urad
    e = _writer_error(t)
    assert (e.status, e.field) == ("ABBE_E_RANGE", "axes.X.coef.ez")

    t = small_table()
    t.axes["X"].coef["dx"] = np.array([9000.0, 9000.0, 0.0, 0.0])   # 18 mm over 16.7 mm
    assert _writer_error(t).status == "ABBE_E_RANGE"

    t = small_table()
    t.axes["X"].coef["bogus"] = np.zeros(4)
    assert _writer_error(t).status == "ABBE_E_COUNT"


@pytest.mark.parametrize("value,status", [
    ((), "ABBE_E_COUNT"),
    (tuple([1.0] * 9), "ABBE_E_COUNT"),
    ((1.0, math.nan), "ABBE_E_NONFINITE"),
    ((1.0, math.inf), "ABBE_E_NONFINITE"),
    ((9000.0,), "ABBE_E_RANGE"),                     # 2^-8 nm: beyond int32
    ((4195.0, -4195.0), "ABBE_E_RANGE"),             # with backlash 4 um: over 8.389 mm
    (("a",), "ABBE_E_COUNT"),
])
def test_writer_refuses_bad_reversal_blocks(value, status) -> None:
    t = small_table()
    t.axes["X"].reversal_cheb_um = value
    e = _writer_error(t)
    assert (e.status, e.field) == (status, "axes.X.reversal_cheb_um")


def test_writer_reversal_block_needs_a_takeup() -> None:
    t = small_table()
    t.axes["Z"].backlash_takeup_mm = 0.0
    t.axes["Z"].reversal_cheb_um = (0.0, 1.0)      # backlash_um 0, but a block
    e = _writer_error(t)
    assert (e.status, e.field) == ("ABBE_E_RANGE", "axes.Z.backlash_takeup_mm")
    t.axes["Z"].backlash_takeup_mm = 0.2
    assert read_blob(write_blob(t)).axes["Z"].reversal_cheb_um == (0.0, 1.0)


def test_zero_harmonic_block_is_dropped() -> None:
    t = small_table()
    t.axes["Y"].blocks = (FourierBlock(100.0, 0.0, 0), FourierBlock(10.0, 0.5, 1))
    back = read_blob(write_blob(t))
    assert back.axes["Y"].blocks[0] is None


# --------------------------------------------------------------------------- basis / quantization


def test_basis_matrix_semantics() -> None:
    ax = AxisTable(travel_mm=(-100.0, 300.0), trend_degree=3,
                   blocks=(FourierBlock(400.0, -100.0, 2), FourierBlock(7.0, 1.0, 1)))
    assert ax.row_names() == ["T0", "T1", "T2", "T3", "sin1(b0)", "cos1(b0)", "sin2(b0)",
                              "cos2(b0)", "sin1(b1)", "cos1(b1)"]
    p = np.array([-100.0, 0.0, 123.4, 300.0])
    B = basis_matrix(ax, p)
    assert B.shape == (4, ax.n_basis()) == (4, 10)
    u = (2 * p - 200.0) / 400.0
    th = np.arccos(u)                       # T_k(cos th) = cos(k th)
    for k in range(4):
        np.testing.assert_allclose(B[:, k], np.cos(k * th), atol=1e-12)
    phi0 = 2 * np.pi * (p + 100.0) / 400.0
    phi1 = 2 * np.pi * (p - 1.0) / 7.0
    np.testing.assert_allclose(B[:, 4:8], np.stack([np.sin(phi0), np.cos(phi0),
                                                    np.sin(2 * phi0), np.cos(2 * phi0)], 1),
                               atol=1e-12)
    np.testing.assert_allclose(B[:, 8:], np.stack([np.sin(phi1), np.cos(phi1)], 1), atol=1e-12)
    # clamped: outside the travel the ends hold
    np.testing.assert_array_equal(basis_matrix(ax, [-500.0, 1e4]), basis_matrix(ax, [-100, 300]))
    assert basis_matrix(AxisTable((0.0, 1.0)), [0.5]).shape == (1, 0)


def test_quantization_error() -> None:
    t = paper_table()
    err = quantization_error(t)
    assert set(err) == {(a, k) for a in AXES for k in TERMS}
    lin = max(v for (a, k), v in err.items() if k.startswith("d"))
    ang = max(v for (a, k), v in err.items() if k.startswith("e"))
    # 8 rows, each off by <= half a step: 2^-9 nm (linear), 2^-37 rad (angular)
    assert 0 < lin <= 8 * 2**-9 * 1e-3
    assert 0 < ang <= 8 * 2**-37 * 1e6
    assert all(v == 0.0 for v in quantization_error(quantize(t)).values())
    # a period that is not a whole number of nm shows up
    t2 = small_table()
    t2.axes["Y"].blocks = (None, FourierBlock(10.0000004, 0.5, 1))
    t2.axes["Y"].coef["dy"] = np.array([100.0, 0.0])
    # phase error at the far end: 2 pi (200.5 mm / 10 mm) * 0.4 nm / 10 mm, times 100 um
    expect = 100.0 * 2 * np.pi * 200.5 / 10.0 * 0.4e-6 / 10.0
    assert quantization_error(t2)[("Y", "dy")] == pytest.approx(expect, rel=0.02)


# --------------------------------------------------------------------------- JSON


def test_json_round_trip_exact() -> None:
    for t in (small_table(), paper_table(), read_blob(write_blob(paper_table())), reversal_table()):
        d = json.loads(json.dumps(table_to_json(t)))
        assert_tables_equal(table_from_json(d, "t.json"), t)
    # the reversal block: key reversal_cheb_um (um), written only where there is one,
    # and version 1.1 then (the blob's format)
    d = table_to_json(reversal_table())
    assert d["version"] == "1.1" and d["axes"]["X"]["reversal_cheb_um"] == [2.0, -6.5, 1.25]
    assert "reversal_cheb_um" not in d["axes"]["Y"]
    assert table_to_json(small_table())["version"] == "1.0"
    assert "reversal_cheb_um" not in table_to_json(small_table())["axes"]["X"]
    d = table_to_json(small_table())
    assert d["axes"]["X"]["rows"] == ["T0", "T1", "sin1(b0)", "cos1(b0)"]
    assert set(d["axes"]["X"]["terms"]) == {"dx_um", "ez_urad"}
    assert d["squareness_urad"] == {"S_xy": 20.0, "S_xz": -10.0, "S_yz": 5.0}


@pytest.mark.parametrize("mutate,field", [
    (lambda d: d.pop("reference_mm"), "reference_mm"),
    (lambda d: d.__setitem__("format", "other"), "format"),
    (lambda d: d.__setitem__("version", "2.0"), "version"),
    (lambda d: d["axes"]["X"]["terms"].__setitem__("dx_um", [1.0]), "axes.X.terms.dx_um"),
    (lambda d: d["axes"]["X"]["terms"].__setitem__("dx_urad", [1.0] * 4), "axes.X.terms.dx_urad"),
    (lambda d: d["axes"]["X"]["terms"]["ez_urad"].__setitem__(2, "x"),
     "axes.X.terms.ez_urad[2]"),
    (lambda d: d["axes"]["X"].__setitem__("rows", ["T0"]), "axes.X.rows"),
    (lambda d: d["axes"]["Y"]["blocks"][1].__setitem__("harmonics", 9),
     "axes.Y.blocks[1].harmonics"),
    (lambda d: d["axes"]["Y"]["blocks"][1].__setitem__("period_mm", -1.0),
     "axes.Y.blocks[1].period_mm"),
    (lambda d: d["axes"]["Z"].__setitem__("trend_degree", 9), "axes.Z.trend_degree"),
    (lambda d: d["axes"].pop("Z"), "axes"),
    (lambda d: d["axes"]["Z"].__setitem__("travel_mm", [0.0]), "axes.Z.travel_mm"),
    (lambda d: d["squareness_urad"].__setitem__("S_zz", 1.0), "squareness_urad.S_zz"),
    (lambda d: d["axes"]["X"].__setitem__("backlash_um", None), "axes.X.backlash_um"),
    (lambda d: d.__setitem__("version", "1.2"), "version"),
    (lambda d: d["axes"]["X"].__setitem__("reversal_cheb_um", []), "axes.X.reversal_cheb_um"),
    (lambda d: d["axes"]["X"].__setitem__("reversal_cheb_um", [0.0] * 9), "axes.X.reversal_cheb_um"),
    (lambda d: d["axes"]["X"].__setitem__("reversal_cheb_um", 1.0), "axes.X.reversal_cheb_um"),
    (lambda d: d["axes"]["X"].__setitem__("reversal_cheb_um", [1.0, "NaN"]),
     "axes.X.reversal_cheb_um[1]"),
    (lambda d: d["axes"]["X"].__setitem__("reversal_cheb_um", [1.0, 1e8]),
     "axes.X.reversal_cheb_um[1]"),
    (lambda d: d["axes"]["X"].__setitem__("reversal_cheb", [1.0]), "axes.X.reversal_cheb"),
])


def test_json_bad_input_names_field(mutate, field) -> None:
    d = json.loads(json.dumps(table_to_json(small_table())))
    mutate(d)
    with pytest.raises(AbbeInputError) as exc:
        table_from_json(d, "bad.json")
    assert exc.value.file == "bad.json"
    assert exc.value.field == field


# --------------------------------------------------------------------------- generated C


def test_write_c(tmp_path: Path) -> None:
    blob = write_blob(paper_table())
    h, c = write_c(blob, tmp_path)
    assert (h.name, c.name) == ("abbe_model.h", "abbe_model.c")
    ht, ct = h.read_text(), c.read_text()
    assert "#if ABBE_TABLE_FORMAT_MAJOR != 1 || ABBE_TABLE_FORMAT_MINOR < 0" in ht
    assert "#error" in ht and "extern const uint8_t abbe_model_blob[];" in ht
    assert "extern const uint32_t abbe_model_blob_size;" in ht
    assert f"abbe_model_blob_size = {len(blob)}u;" in ct
    # the listing shows every coefficient of every term by row name
    t = read_blob(blob)
    assert ct.count("cos3(b0)") == 3
    assert f"{t.axes['Y'].coef['ex'][5]:16.6f}" in ct
    # the byte array is the blob
    hexes = [int(v, 16) for v in re.findall(r"0x([0-9A-F]{2}),", ct.split("= {", 1)[1])]
    assert bytes(hexes) == blob
    # deterministic
    h2, c2 = write_c(blob, tmp_path / "again")
    assert c2.read_bytes() == c.read_bytes() and h2.read_bytes() == h.read_bytes()
    with pytest.raises(TableError):
        write_c(blob[:-1] + bytes([blob[-1] ^ 1]), tmp_path / "bad")
    assert not (tmp_path / "bad" / "abbe_model.c").exists()


def test_write_c_reversal_block(tmp_path: Path) -> None:
    """A 1.1 table: the guard asks for a 1.1 library, the listing shows the block."""
    blob = write_blob(reversal_table())
    h, c = write_c(blob, tmp_path)
    ht, ct = h.read_text(), c.read_text()
    assert "#if ABBE_TABLE_FORMAT_MAJOR != 1 || ABBE_TABLE_FORMAT_MINOR < 1" in ht
    assert "generated for table format 1.1" in ht
    assert " * table format 1.1, " in ct and "REVERSAL" in ct
    assert "reversal block (degree 2, added to backlash_um), um: R0 2.000000, R1 -6.500000, " \
           "R2 1.250000" in ct
    assert "reversal block (degree 7" in ct and ct.count("reversal block") == 2


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_generated_c_compiles_and_version_guard(tmp_path: Path) -> None:
    blob = write_blob(small_table())
    write_c(blob, tmp_path)
    inc = REPO / "lib" / "include"
    main = tmp_path / "main.c"
    # firmware-style use: the generated array goes through the library's loader
    main.write_text('#include <stdio.h>\n#include "abbe/abbe.h"\n#include "abbe_model.h"\n'
                    "int main(void) { unsigned s = 0; uint32_t i; abbe_model_t m;\n"
                    "  int st = abbe_model_load(&m, abbe_model_blob, abbe_model_blob_size);\n"
                    "  for (i = 0; i < abbe_model_blob_size; i++) s += abbe_model_blob[i];\n"
                    '  printf("%d %u %u %u\\n", st, (unsigned)abbe_model_blob_size, s,\n'
                    "         (unsigned)(abbe_model_crc(&m) == ABBE_MODEL_BLOB_CRC32)); return 0; }\n")
    exe = tmp_path / "m"
    lib_sources = sorted(str(p) for p in (REPO / "lib" / "src").glob("*.c"))
    subprocess.run(["cc", "-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror", f"-I{inc}",
                    f"-I{tmp_path}", str(main), str(tmp_path / "abbe_model.c"), *lib_sources,
                    "-o", str(exe)], check=True, capture_output=True)
    out = subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout.split()
    assert [int(v) for v in out] == [0, len(blob), sum(blob), 1]
    # a library with another table major refuses the generated file
    fake = tmp_path / "fake" / "abbe"
    fake.mkdir(parents=True)
    (fake / "version.h").write_text("#define ABBE_TABLE_FORMAT_MAJOR 2\n"
                                    "#define ABBE_TABLE_FORMAT_MINOR 0\n")
    r = subprocess.run(["cc", "-std=c99", "-fsyntax-only", f"-I{tmp_path / 'fake'}",
                        f"-I{tmp_path}", str(tmp_path / "abbe_model.c")], capture_output=True,
                       text=True)
    assert r.returncode != 0 and "regenerate it" in r.stderr
    # a 1.1 table needs a 1.1 library: a 1.0 one (ABBE_NO_REVERSAL) refuses it at build time
    write_c(write_blob(reversal_table()), tmp_path / "r11")
    for defs, ok in (([], True), (["-DABBE_NO_REVERSAL=1"], False)):
        r = subprocess.run(["cc", "-std=c99", "-fsyntax-only", *defs, f"-I{inc}",
                            f"-I{tmp_path / 'r11'}", str(tmp_path / "r11" / "abbe_model.c")],
                           capture_output=True, text=True)
        assert (r.returncode == 0) == ok and (ok or "table format 1.1" in r.stderr), r.stderr


# --------------------------------------------------------------------------- example + CLI


def test_example_files_are_reproducible(tmp_path: Path) -> None:
    """The blob exactly; its JSON text exactly but for the last digit of a number
    (docs/formats.md, "Reproducibility")."""
    write_example(tmp_path)
    committed = REPO / "examples" / "paper_table"
    assert (tmp_path / "model.bin").read_bytes() == (committed / "model.bin").read_bytes()
    assert differences((committed / "model.json").read_text(),
                       (tmp_path / "model.json").read_text()) == []


def test_paper_table_shape() -> None:
    t = read_blob((REPO / "examples" / "paper_table" / "model.bin").read_bytes())
    assert t.reference_mm == (163.626, -212.772, -290.704)
    assert t.tool_offset_mm == (0.0, 0.0, 150.0)
    assert {a: t.axes[a].travel_mm for a in AXES} == {
        "X": (0.0, 500.0), "Y": (-400.0, 0.0), "Z": (-300.0, 0.0)}
    for a in AXES:
        ax = t.axes[a]
        assert ax.trend_degree == 1 and ax.blocks[0].harmonics == 3 and ax.blocks[1] is None
        assert ax.present_terms() == list(TERMS)


def test_cli_info_eval_json_cgen(tmp_path: Path, capsys) -> None:
    model = REPO / "examples" / "paper_table" / "model.bin"
    assert cli.main(["table", "info", str(model)]) == 0
    out = capsys.readouterr().out
    assert "SQUARENESS, TOOL_OFFSET" in out and f"{zlib.crc32(model.read_bytes()[:-4]):08X}" in out
    assert "axis Y: travel [-400, 0] mm; trend degree 1" in out

    assert cli.main(["table", "eval", str(model), "163.626", "-212.772", "-290.704",
                     "600", "0", "0"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 3
    ref_vals = [float(v) for v in lines[1].split("|")[1].split()]
    assert max(abs(v) for v in ref_vals) < 1e-4          # zero at the reference point
    assert "outside travel" in lines[2]

    assert cli.main(["table", "to-json", str(model), "-o", str(tmp_path / "m.json")]) == 0
    assert cli.main(["table", "from-json", str(tmp_path / "m.json"), "-o",
                     str(tmp_path / "m.bin")]) == 0
    assert (tmp_path / "m.bin").read_bytes() == model.read_bytes()
    capsys.readouterr()
    assert cli.main(["table", "cgen", str(model), "-o", str(tmp_path / "gen")]) == 0
    assert (tmp_path / "gen" / "abbe_model.c").exists()


def test_cli_bad_input(tmp_path: Path, capsys) -> None:
    bad = tmp_path / "bad.bin"
    bad.write_bytes(patch(write_blob(small_table()), axis_off(2) + A_TMIN, "i", 5))
    assert cli.main(["table", "info", str(bad)]) == 2
    err = capsys.readouterr().err
    assert f"{bad}: field 'axes.Z.travel_nm':" in err and "ABBE_E_TRAVEL" in err

    assert cli.main(["table", "eval", str(REPO / "examples/paper_table/model.bin"), "1", "2"]) == 2
    assert "field 'pos_mm'" in capsys.readouterr().err

    js = tmp_path / "bad.json"
    js.write_text('{\n  "format": "abbe-table",\n  oops\n}\n')
    out = tmp_path / "out.bin"
    assert cli.main(["table", "from-json", str(js), "-o", str(out)]) == 2
    assert f"{js}:3:" in capsys.readouterr().err and not out.exists()

    d = table_to_json(small_table())
    d["axes"]["X"]["terms"]["ez_urad"] = [5000.0, 0.0, 0.0, 0.0]   # over the angular cap
    js.write_text(json.dumps(d, indent=2))
    assert cli.main(["table", "from-json", str(js), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    line = next(i for i, ln in enumerate(js.read_text().splitlines(), 1) if '"ez_urad"' in ln)
    assert f"{js}:{line}: field 'axes.X.coef.ez':" in err and "ABBE_E_RANGE" in err
    assert not out.exists()
