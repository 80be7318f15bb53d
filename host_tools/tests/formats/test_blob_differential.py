"""Differential fuzzing of the table readers: random mutations of format 1.0 and 1.1
blobs (CRC fixed up, so the checks behind it are reached) get the same answer from
the Python reader (abbe.formats.blob.read_blob) and the C loader (abbe_model_load
through abbe.model.clib): both accept, or both refuse with the same status; an
accepted table evaluates to the same reversal in both."""

from __future__ import annotations

import struct
import zlib

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from fuzz_budget import DERANDOMIZE, examples

from abbe.formats import golden
from abbe.formats.blob import read_blob, write_blob
from abbe.model import clib
from abbe.model.table import AXES, TableError

pytestmark = pytest.mark.skipif(not clib.available(), reason="C library not built")

_SEEDS = {name: write_blob(t) for name, t in (
    ("backlash", golden.backlash_table()), ("reversal", golden.reversal_table()),
    ("reversal_sparse", golden.reversal_sparse_table(np.random.default_rng(5))))}

# the fields a mutation is aimed at (offset, size): header, the axis records' counts,
# backlash, reversal rows and reserved bytes, coefficient offsets and counts
_FIELDS = [(4, 2), (6, 2), (8, 4), (20, 4), (60, 4)] + [
    (64 + 64 * j + off, size) for j in range(3)
    for off, size in ((8, 1), (9, 1), (10, 1), (11, 1), (28, 4), (32, 4), (48, 4), (52, 4),
                      (56, 4), (60, 1), (61, 1), (62, 1), (63, 1))]


def _fix_crc(b: bytearray) -> None:
    total = struct.unpack_from("<I", b, 8)[0]
    if 260 <= total <= len(b) and total % 4 == 0:
        struct.pack_into("<I", b, total - 4, zlib.crc32(bytes(b[:total - 4])))


@st.composite
def mutated(draw) -> bytes:
    name = draw(st.sampled_from(sorted(_SEEDS)))
    b = bytearray(_SEEDS[name])
    # a coefficient and its float32 twin together (past the twin check: the range caps,
    # the reversal rows' values, the evaluation)
    for _ in range(draw(st.integers(0, 2))):
        j = draw(st.integers(0, 2))
        qoff, foff, count = struct.unpack_from("<III", b, 64 + 64 * j + 48)
        if count == 0:
            continue
        i = draw(st.integers(0, count - 1))
        v = draw(st.sampled_from([0, 1, -1, 1 << 27, (1 << 28) + 1, (1 << 30), -(1 << 31),
                                  (1 << 31) - 1, 2_560_000, -25_600_000]))
        struct.pack_into("<i", b, qoff + 4 * i, v)
        struct.pack_into("<f", b, foff + 4 * i, float(np.float32(v)))
    for _ in range(draw(st.integers(0, 3))):
        if draw(st.booleans()):
            off, size = draw(st.sampled_from(_FIELDS))
            small = draw(st.integers(-3, 300))
            value = draw(st.sampled_from([small, 0, 1, 8, 9, 255, 1 << 31, (1 << 32) - 1]))
            b[off:off + size] = (value % (1 << (8 * size))).to_bytes(size, "little")
        else:  # anywhere in the coefficient arrays: values, twins, the reversal rows
            off = draw(st.integers(256, len(b) - 5))
            b[off] = draw(st.integers(0, 255))
    _fix_crc(b)
    return bytes(b)


def _c_status(blob: bytes) -> tuple[str, clib.CModel | None]:
    try:
        return "ABBE_OK", clib.CModel(blob)
    except TableError as exc:
        return exc.status, None


@settings(max_examples=examples(400), deadline=None, derandomize=DERANDOMIZE,
          suppress_health_check=[HealthCheck.too_slow])
@given(mutated())
def test_python_reader_and_c_loader_agree(blob: bytes) -> None:
    try:
        table = read_blob(blob)
        py = "ABBE_OK"
    except TableError as exc:
        table, py = None, exc.status
    c, model = _c_status(blob)
    assert py == c, f"Python {py}, C {c}"
    if table is None or model is None:
        return
    for a in AXES:
        lo, hi = table.axes[a].travel_mm
        p = np.linspace(lo, hi, 5)
        r_py = table.axes[a].reversal_um(p)
        assert np.all(np.isfinite(r_py))
        r_c = model.reversal_f32(a, p)
        assert np.allclose(r_c, table.axes[a].reversal_um(p.astype(np.float32)),
                           rtol=1e-5, atol=1e-3), a


def test_the_seeds_load_in_both() -> None:
    for name, blob in _SEEDS.items():
        assert _c_status(blob)[0] == "ABBE_OK", name
        read_blob(blob)
