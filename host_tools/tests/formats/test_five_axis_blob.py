"""Five-axis tables (format 1.2, abbe.formats.five_axis_blob): round trip, the
golden files regenerate, the 3-axis reader refuses them, refusals of bad models, and
differential fuzzing against the C loader (abbe_five_model_load): random mutations
(CRC fixed up) get the same status from both readers, and an accepted table evaluates
in C to the Python reference of what the Python reader decoded."""

from __future__ import annotations

import ctypes as C
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from fuzz_budget import DERANDOMIZE, examples

from abbe.formats import golden_five
from abbe.formats.blob import read_blob
from abbe.formats.five_axis_blob import five_reference, read_five_blob, write_five_blob
from abbe.model import clib
from abbe.model.five_axis import LOCATION_ERRORS, FiveAxisErrors, TrunnionGeometry
from abbe.model.table import TableError
from textnum import differences

REPO = Path(__file__).resolve().parents[3]
GOLDEN = REPO / "tests" / "golden"
_TABLES = golden_five.golden_tables()


def test_regenerated_files_match(tmp_path: Path) -> None:
    golden_five.write(tmp_path)
    for name in ("golden_five.h", "golden_five.c"):
        assert differences((GOLDEN / name).read_text(), (tmp_path / name).read_text()) == [], name


def test_round_trip_is_the_quantised_model() -> None:
    for gf in _TABLES:
        t = gf.table
        assert t.kind == gf.geom.kind
        assert np.allclose(t.rot_point_mm, gf.geom.rot_point_mm, atol=1e-6)
        assert np.allclose(t.offset_mm, gf.geom.offset_mm, atol=1e-6)
        assert write_five_blob(t.geometry(), t.errors) == gf.blob  # quantised values are fixed points
        # and the reference of the decoded table is the original's within the quantisation
        pos = np.array([[100.0, -50.0, -200.0], [-300.0, 250.0, 10.0]])
        ang = np.array([[30.0, 200.0], [-75.0, -33.3]])
        from abbe.model.five_axis import tool_error_linear
        p0, r0 = tool_error_linear(gf.geom, golden_five.golden_tables()[_TABLES.index(gf)].table.errors, pos, ang)
        p1, r1 = five_reference(t, pos, ang)
        assert np.allclose(p0, p1) and np.allclose(r0, r1)


def test_three_axis_reader_refuses_and_five_reader_needs_rotary() -> None:
    with pytest.raises(TableError) as exc:
        read_blob(_TABLES[0].blob)
    assert exc.value.status == "ABBE_E_VERSION_MINOR"
    from abbe.formats.blob import write_blob
    from abbe.model.examples import paper_table
    with pytest.raises(TableError) as exc:
        read_five_blob(write_blob(paper_table()))
    assert exc.value.status == "ABBE_E_FLAGS"


def _geom(kind: str = "xyzac-trt", offset=(0.0, 20.0, 10.0)) -> TrunnionGeometry:
    return TrunnionGeometry(kind, (10.0, 20.0, -30.0), offset, 50.0, {"A": (-90, 90), "B": (-90, 90),
                                                                        "C": (-360, 360)})


@pytest.mark.parametrize("geom, errs, status", [
    (_geom(offset=(5.0, 20.0, 10.0)), FiveAxisErrors(), "ABBE_E_FLAGS"),  # offset along A
    (_geom("xyzbc-trt", (5.0, 1.0, 10.0)), FiveAxisErrors(), "ABBE_E_FLAGS"),  # offset along B
    (_geom(), FiveAxisErrors(location={"EA0A": 5000.0}), "ABBE_E_RANGE"),  # > 3906 urad
    (_geom(), FiveAxisErrors(location={"EX0C": float("nan")}), "ABBE_E_NONFINITE"),
    (_geom(), FiveAxisErrors(motions={("C", "X"): np.zeros(18)}), "ABBE_E_COUNT"),  # 9 harmonics
    (_geom(), FiveAxisErrors(motions={("C", "A"): np.full(4, 2000.0)}), "ABBE_E_RANGE"),
])
def test_writer_refuses(geom, errs, status) -> None:
    with pytest.raises(TableError) as exc:
        write_five_blob(geom, errs)
    assert exc.value.status == status


# ------------------------------------------------------------------ C differential

def _lib():
    lib = clib.load_library()
    fn = lib.abbe_five_model_load
    fn.argtypes = [C.c_void_p, C.c_void_p, C.c_size_t]
    fn.restype = C.c_int
    return lib


class _In(C.Structure):
    _fields_ = [("pos", C.c_float * 3), ("ang", C.c_float * 2), ("dir", C.c_float * 3), ("temp", C.c_float * 3)]


class _Out(C.Structure):
    _fields_ = [("err", C.c_float * 3), ("rot", C.c_float * 3), ("flags", C.c_uint32)]


def _c_load(blob: bytes):
    lib = _lib()
    buf = C.create_string_buffer(bytes(blob), len(blob))  # malloc'd: 8-aligned
    model = C.create_string_buffer(1 << 15)
    st_ = lib.abbe_five_model_load(model, buf, len(blob))
    return clib.status_name(st_), (lib, model, buf)


# mutation targets: header, the rotary header and both rotary records (every field)
_FIELDS = [(6, 2), (8, 4), (20, 4), (256, 1), (257, 1), (260, 4), (272, 4), (276, 4), (284, 4), (300, 4)] + [
    (320 + 64 * r + off, size) for r in range(2)
    for off, size in ((0, 4), (4, 4), (8, 4), (12, 4), (16, 4), (20, 1), (21, 1), (22, 1), (24, 4), (28, 4),
                      (32, 4), (40, 1), (63, 1))]


def _fix_crc(b: bytearray) -> None:
    total = struct.unpack_from("<I", b, 8)[0]
    if 260 <= total <= len(b) and total % 4 == 0:
        struct.pack_into("<I", b, total - 4, zlib.crc32(bytes(b[:total - 4])))


@st.composite
def mutated(draw) -> bytes:
    b = bytearray(draw(st.sampled_from([gf.blob for gf in _TABLES])))
    for _ in range(draw(st.integers(0, 2))):  # a rotary coefficient and its twin together
        r = draw(st.integers(0, 1))
        qoff, foff, count = struct.unpack_from("<III", b, 320 + 64 * r + 24)
        if count:
            i = draw(st.integers(0, count - 1))
            v = draw(st.sampled_from([0, 1, -1, (1 << 28) + 1, -(1 << 31), (1 << 31) - 1, 2_560_000]))
            struct.pack_into("<i", b, qoff + 4 * i, v)
            struct.pack_into("<f", b, foff + 4 * i, float(np.float32(v)))
    for _ in range(draw(st.integers(0, 3))):
        if draw(st.booleans()):
            off, size = draw(st.sampled_from(_FIELDS))
            value = draw(st.sampled_from([draw(st.integers(-3, 300)), 0, 1, 2, 3, 9, 255, 1 << 30, 1 << 31,
                                          (1 << 32) - 1]))
            b[off:off + size] = (value % (1 << (8 * size))).to_bytes(size, "little")
        else:
            off = draw(st.integers(256, len(b) - 5))
            b[off] = draw(st.integers(0, 255))
    _fix_crc(b)
    return bytes(b)


pytestmark_c = pytest.mark.skipif(not clib.available(), reason="C library not built")


@pytestmark_c
@settings(max_examples=examples(300), deadline=None, derandomize=DERANDOMIZE, suppress_health_check=[HealthCheck.too_slow])
@given(mutated())
def test_python_reader_and_c_loader_agree(blob: bytes) -> None:
    msg = ""
    try:
        table = read_five_blob(blob)
        py = "ABBE_OK"
    except TableError as exc:
        table, py, msg = None, exc.status, str(exc)
    c, handle = _c_load(blob)
    if not struct.unpack_from("<I", blob, 20)[0] & 0x20 and c == "ABBE_OK":
        # no rotary section: C's five-axis loader reads a 3-axis table (no rotary
        # errors); the Python five-axis reader refuses it by design (every check of the
        # header and the linear axes passed first)
        assert py == "ABBE_E_FLAGS" and "no rotary section" in msg, msg
        return
    assert py == c, f"Python {py}, C {c}"
    if table is None:
        return
    lib, model, _buf = handle
    pos = np.array([[120.0, -40.0, -180.0], [-200.0, 300.0, 50.0]], dtype=np.float32)
    ang = np.array([[25.0, 130.0], [-60.0, -400.0]], dtype=np.float32)
    p_ref, r_ref = five_reference(table, pos.astype(np.float64), ang.astype(np.float64))
    for i in range(len(pos)):
        inp, out = _In(), _Out()
        inp.pos[:] = [float(v) for v in pos[i]]
        inp.ang[:] = [float(v) for v in ang[i]]
        assert lib.abbe_five_error_eval_f32(model, C.byref(inp), C.byref(out)) == 0
        scale = 1.0 + float(np.max(np.abs(p_ref[i])))
        # mutated tables may hold errors of millimetres: f32 relative precision then
        assert np.allclose(out.err[:], p_ref[i], atol=2e-3 + 2e-6 * scale), (out.err[:], p_ref[i])
        assert np.allclose(out.rot[:], r_ref[i], atol=2e-3 + 2e-6 * (1.0 + float(np.max(np.abs(r_ref[i])))))


@pytestmark_c
def test_the_golden_tables_load_in_c() -> None:
    for gf in _TABLES:
        assert _c_load(gf.blob)[0] == "ABBE_OK", gf.name


def test_location_names_cover_both_kinds() -> None:
    for gf in _TABLES:
        names = {n for axis in gf.geom.rotaries for n in LOCATION_ERRORS[axis]}
        assert names <= set(gf.table.errors.location)
