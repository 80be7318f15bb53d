"""Hand-built tables and byte-level blob patches shared by the table tests
(formats/test_table.py) and the C library tests (model/test_clib.py): byte offsets
of docs/table-format.md, small tables with every feature, crafted bad blobs."""

from __future__ import annotations

import math
import struct
import zlib

import numpy as np

from abbe.formats.blob import write_blob
from abbe.model.table import AxisTable, FourierBlock, Table

# Byte offsets (docs/table-format.md).
H_TOTAL, H_HSIZE, H_ASIZE, H_FEAT, H_REF, H_TOOL, H_SQ, H_RES = 8, 12, 16, 20, 24, 36, 48, 60
A_TMIN, A_TMAX, A_MASK, A_DEG, A_H0, A_H1 = 0, 4, 8, 9, 10, 11
A_P0, A_P1, A_O0, A_O1, A_BQ8, A_TAKEUP = 12, 16, 20, 24, 28, 32
A_EXP, A_OFF, A_TREF, A_QOFF, A_FOFF, A_COUNT, A_RES = 36, 40, 44, 48, 52, 56, 60
A_REV_ROWS = 60  # format 1.1: u8 reversal_rows, bytes 61..63 reserved


def axis_off(j: int) -> int:
    return 64 + 64 * j


# --------------------------------------------------------------------------- tables


def small_table() -> Table:
    """A small table with every feature: X has 2 terms, Y one, Z none."""
    x = AxisTable(travel_mm=(0.0, 300.0), trend_degree=1,
                  blocks=(FourierBlock(300.0, 0.0, 1), None),
                  coef={"dx": np.array([1.5, -2.25, 0.75, 0.5]),
                        "ez": np.array([10.0, 5.0, -3.0, 1.0])},
                  backlash_um=4.0, backlash_takeup_mm=0.1,
                  thermal_expansion_ppm_per_k=11.5, thermal_offset_um_per_k=0.5,
                  thermal_tref_c=20.0)
    y = AxisTable(travel_mm=(-200.0, 0.0), trend_degree=None,
                  blocks=(None, FourierBlock(10.0, 0.5, 1)),
                  coef={"dy": np.array([0.3, -0.2])}, backlash_um=0.0,
                  backlash_takeup_mm=0.05)
    z = AxisTable(travel_mm=(-100.0, 0.0), backlash_takeup_mm=0.05)
    return Table(axes={"X": x, "Y": y, "Z": z}, reference_mm=(100.0, -100.0, -50.0),
                 tool_offset_mm=(0.0, 0.0, 100.0), squareness_urad=(20.0, -10.0, 5.0))


def reversal_table() -> Table:
    """Format 1.1: :func:`small_table` with reversal blocks on X (degree 2, after its
    4 x 2 matrix) and Z (degree 7, an axis without terms: the block is its whole array)."""
    t = small_table()
    t.axes["X"].reversal_cheb_um = (2.0, -6.5, 1.25)
    t.axes["Z"].reversal_cheb_um = (0.5, 1.0, -0.75, 0.25, 0.0, -0.125, 0.0625, 0.03125)
    return t


def tiny_table() -> Table:
    """The smallest table: no terms anywhere (total_size 260)."""
    return Table(axes={"X": AxisTable((0.0, 1.0)), "Y": AxisTable((0.0, 1.0)),
                       "Z": AxisTable((0.0, 1.0))}, reference_mm=(0.0, 0.0, 0.0))


def patch(blob: bytes, offset: int, fmt: str, value, fix_crc: bool = True) -> bytes:
    """Overwrite a field and (by default) recompute the CRC, so that only the
    intended check can fail."""
    b = bytearray(blob)
    struct.pack_into("<" + fmt, b, offset, value)
    if fix_crc:
        total = struct.unpack_from("<I", b, 8)[0]
        if 8 <= total <= len(b):
            struct.pack_into("<I", b, total - 4, zlib.crc32(bytes(b[:total - 4])))
    return bytes(b)


def crafted_cases() -> list[tuple[str, str, bytes]]:
    """(case name, expected status, blob): one case per check of the spec.

    Shared with test_clib.py, which checks that the C loader agrees.
    """
    good = write_blob(small_table())
    total = len(good)
    x, y, z = axis_off(0), axis_off(1), axis_off(2)
    qoff_x = struct.unpack_from("<I", good, x + A_QOFF)[0]
    foff_x = struct.unpack_from("<I", good, x + A_FOFF)[0]
    count_x = struct.unpack_from("<I", good, x + A_COUNT)[0]
    cases: list[tuple[str, str, bytes]] = [
        ("short header", "ABBE_E_TRUNCATED", good[:63]),
        ("shorter than total_size", "ABBE_E_TRUNCATED", good[:-1]),
        ("magic", "ABBE_E_MAGIC", patch(good, 0, "4s", b"ABBF")),
        ("major 2", "ABBE_E_VERSION_MAJOR", patch(good, 4, "H", 2)),
        ("major 0", "ABBE_E_VERSION_MAJOR", patch(good, 4, "H", 0)),
        ("newer minor", "ABBE_E_VERSION_MINOR", patch(good, 6, "H", 2)),
        ("header_size", "ABBE_E_SIZE", patch(good, H_HSIZE, "I", 60)),
        ("axis_record_size", "ABBE_E_SIZE", patch(good, H_ASIZE, "I", 68)),
        ("total_size < 260", "ABBE_E_SIZE", patch(good, H_TOTAL, "I", 256, fix_crc=False)),
        ("total_size not multiple of 4", "ABBE_E_SIZE",
         patch(good, H_TOTAL, "I", total - 2, fix_crc=False)),
        ("CRC", "ABBE_E_CRC", patch(good, foff_x, "B", good[foff_x] ^ 0x01, fix_crc=False)),
        ("CRC field", "ABBE_E_CRC", patch(good, total - 4, "I",
                                          struct.unpack_from("<I", good, total - 4)[0] ^ 1,
                                          fix_crc=False)),
        ("unknown feature bit (REVERSAL in 1.0)", "ABBE_E_FLAGS", patch(good, H_FEAT, "I", 0x1F)),
        ("header reserved", "ABBE_E_FLAGS", patch(good, H_RES, "I", 1)),
        ("axis reserved", "ABBE_E_FLAGS", patch(good, z + A_RES, "I", 7)),
        ("axis reserved byte 63", "ABBE_E_FLAGS", patch(good, z + A_RES + 3, "B", 1)),
        ("tool offset without feature", "ABBE_E_FLAGS", patch(good, H_FEAT, "I", 0xF & ~0x2)),
        ("squareness without feature", "ABBE_E_FLAGS", patch(good, H_FEAT, "I", 0xF & ~0x1)),
        ("backlash without feature", "ABBE_E_FLAGS", patch(good, H_FEAT, "I", 0xF & ~0x4)),
        ("thermal without feature", "ABBE_E_FLAGS", patch(good, H_FEAT, "I", 0xF & ~0x8)),
        ("term_mask bit 6", "ABBE_E_COUNT", patch(good, z + A_MASK, "B", 0x40)),
        ("term_mask bit 7", "ABBE_E_COUNT", patch(good, z + A_MASK, "B", 0x80)),
        ("trend degree 8", "ABBE_E_COUNT", patch(good, x + A_DEG, "B", 8)),
        ("trend degree 254", "ABBE_E_COUNT", patch(good, x + A_DEG, "B", 254)),
        ("harmonics 9", "ABBE_E_COUNT", patch(good, y + A_H1, "B", 9)),
        ("coef_count + 1", "ABBE_E_COUNT", patch(good, x + A_COUNT, "I", count_x + 1)),
        ("coef_count huge", "ABBE_E_COUNT", patch(good, x + A_COUNT, "I", 0xFFFFFFFF)),
        ("offset below 256", "ABBE_E_OFFSET", patch(good, x + A_QOFF, "I", 252)),
        ("offset misaligned", "ABBE_E_OFFSET", patch(good, x + A_QOFF, "I", qoff_x + 2)),
        ("array past the CRC", "ABBE_E_OFFSET",
         patch(good, x + A_FOFF, "I", total - 4 * count_x)),
        ("offset huge", "ABBE_E_OFFSET", patch(good, x + A_FOFF, "I", 0xFFFFFFFC)),
        ("offset with count 0", "ABBE_E_OFFSET", patch(good, z + A_QOFF, "I", 256)),
        ("f32 offset with count 0", "ABBE_E_OFFSET", patch(good, z + A_FOFF, "I", 256)),
        ("NaN coefficient", "ABBE_E_NONFINITE", patch(good, foff_x + 4, "f", math.nan)),
        ("Inf coefficient", "ABBE_E_NONFINITE", patch(good, foff_x, "f", -math.inf)),
        ("float32 twin off by one ulp", "ABBE_E_MISMATCH",
         patch(good, foff_x + 8, "I", struct.unpack_from("<I", good, foff_x + 8)[0] ^ 1)),
        ("float32 twin huge but finite", "ABBE_E_MISMATCH", patch(good, foff_x + 12, "f", 1.06e37)),
        ("period 0", "ABBE_E_PERIOD", patch(good, x + A_P0, "i", 0)),
        ("period negative", "ABBE_E_PERIOD", patch(good, y + A_P1, "i", -10_000_000)),
        ("period of unused block", "ABBE_E_PERIOD", patch(good, x + A_P1, "i", 1000)),
        ("origin of unused block", "ABBE_E_PERIOD", patch(good, y + A_O0, "i", -5)),
        ("travel min == max", "ABBE_E_TRAVEL", patch(good, x + A_TMAX, "i", 0)),
        ("travel min > max", "ABBE_E_TRAVEL", patch(good, z + A_TMIN, "i", 1)),
        ("linear coefficient sum", "ABBE_E_RANGE",
         _patch_column(good, qoff_x, n_terms=2, col=0, values=[(1 << 31) - 1] * 3 + [0])),
        ("angular coefficient sum", "ABBE_E_RANGE",
         _patch_column(good, qoff_x, n_terms=2, col=1, values=[(1 << 27), (1 << 27), 1, 0])),
        ("squareness over 2^28", "ABBE_E_RANGE", patch(good, H_SQ + 4, "i", -(1 << 28) - 1)),
        ("backlash take-up 0 with a reversal", "ABBE_E_RANGE", patch(good, x + A_TAKEUP, "i", 0)),
        ("backlash take-up negative", "ABBE_E_RANGE", patch(good, y + A_TAKEUP, "i", -1)),
    ]
    return cases + crafted_reversal_cases()


def crafted_reversal_cases() -> list[tuple[str, str, bytes]]:
    """The checks of format 1.1's reversal blocks, on :func:`reversal_table`'s blob."""
    good = write_blob(reversal_table())
    x, y, z = axis_off(0), axis_off(1), axis_off(2)
    qoff_x, foff_x, count_x = struct.unpack_from("<III", good, x + A_QOFF)
    qoff_z, foff_z, count_z = struct.unpack_from("<III", good, z + A_QOFF)
    assert (count_x, count_z) == (8 + 3, 8)
    rev_x = foff_x + 4 * 8   # X's block follows its 4 x 2 matrix
    return [
        ("1.1 table labelled 1.0", "ABBE_E_FLAGS", patch(good, 6, "H", 0)),
        ("1.1 minor 2", "ABBE_E_VERSION_MINOR", patch(good, 6, "H", 2)),
        ("1.1 unknown feature bit", "ABBE_E_FLAGS", patch(good, H_FEAT, "I", 0x3F)),
        ("REVERSAL without BACKLASH", "ABBE_E_FLAGS", patch(good, H_FEAT, "I", 0x1F & ~0x4)),
        ("reversal rows without REVERSAL", "ABBE_E_FLAGS", patch(good, H_FEAT, "I", 0xF)),
        ("1.1 axis reserved byte 61", "ABBE_E_FLAGS", patch(good, x + A_REV_ROWS + 1, "B", 1)),
        ("reversal rows 9", "ABBE_E_COUNT", patch(good, z + A_REV_ROWS, "B", 9)),
        ("reversal rows beside coef_count", "ABBE_E_COUNT", patch(good, x + A_REV_ROWS, "B", 2)),
        ("reversal rows on an axis without them", "ABBE_E_COUNT", patch(good, y + A_REV_ROWS, "B", 1)),
        ("reversal block past the CRC", "ABBE_E_OFFSET",
         patch(good, z + A_FOFF, "I", len(good) - 4 * count_z)),
        ("NaN reversal coefficient", "ABBE_E_NONFINITE", patch(good, rev_x + 4, "f", math.nan)),
        ("Inf reversal coefficient", "ABBE_E_NONFINITE", patch(good, foff_z + 28, "f", math.inf)),
        ("reversal twin off by one ulp", "ABBE_E_MISMATCH",
         patch(good, rev_x + 8, "I", struct.unpack_from("<I", good, rev_x + 8)[0] ^ 1)),
        ("reversal twin of another value", "ABBE_E_MISMATCH", patch(good, foff_z, "f", 0.0)),
        ("take-up 0 with a reversal block", "ABBE_E_RANGE", patch(good, z + A_TAKEUP, "i", 0)),
        ("backlash + reversal over 2^31", "ABBE_E_RANGE", patch(good, z + A_BQ8, "i", -(1 << 31))),
        ("reversal coefficients over 2^31", "ABBE_E_RANGE",
         _patch_values(good, qoff_x + 4 * 8, foff_x + 4 * 8, [(1 << 30), (1 << 30), 0])),
    ]


def _patch_values(blob: bytes, qoff: int, foff: int, values: list[int]) -> bytes:
    """Set consecutive int32 coefficients and their float32 twins."""
    for k, v in enumerate(values):
        blob = patch(blob, qoff + 4 * k, "i", v)
        blob = patch(blob, foff + 4 * k, "f", float(np.float32(v)))
    return blob


def _patch_column(blob: bytes, qoff: int, n_terms: int, col: int, values: list[int]) -> bytes:
    """Set column ``col`` of the X coefficient matrix, int32 and its float32 twin,
    so that only the range check can fail."""
    foff = struct.unpack_from("<I", blob, axis_off(0) + A_FOFF)[0]
    for row, v in enumerate(values):
        blob = patch(blob, qoff + 4 * (row * n_terms + col), "i", v)
        blob = patch(blob, foff + 4 * (row * n_terms + col), "f", float(np.float32(v)))
    return blob
