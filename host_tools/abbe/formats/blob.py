"""The binary table blob (format 1.1, docs/table-format.md): writer, reader, quantisation.

The writer writes format 1.0 (version_minor 0) for a table without reversal
blocks, byte for byte what earlier versions wrote, so drives with a 1.0 library
keep accepting it, and 1.1 only for a table that uses them; the reader reads both.

The binary layout, the integer encodings and the validation order are specified
in ``docs/table-format.md``; this module is the host-side writer and reader of
that format. :func:`read_blob` applies every check of the C loader, in its order,
and raises :class:`abbe.model.table.TableError` with the same status name.

Integer encodings in the blob (rounded to nearest on writing):

=====================  ===========================================
positions, periods     nm (int32)
linear coefficients    2^-8 nm (int32)
angular coefficients   2^-36 rad (int32), squareness likewise
backlash reversal      2^-8 nm, reversal block coefficients likewise
thermal expansion      2^-50 per mK  (12 ppm/K = 13 510 799)
thermal offset         2^-16 nm per mK (1 um/K = 65 536)
temperature            m°C
=====================  ===========================================
"""

from __future__ import annotations

import math
import struct
import zlib
from dataclasses import dataclass, replace
from typing import Any, Callable

import numpy as np

from abbe.model.table import (
    AXES,
    FEATURE_ALL,
    FEATURE_BACKLASH,
    FEATURE_REVERSAL,
    FEATURE_SQUARENESS,
    FEATURE_THERMAL,
    FEATURE_TOOL_OFFSET,
    FEATURES_1_0,
    LINEAR_TERMS,
    MAX_DEGREE,
    MAX_HARMONICS,
    MAX_REVERSAL_ROWS,
    NO_TREND,
    TERMS,
    AxisTable,
    FourierBlock,
    Table,
    TableError,
    basis_matrix,
)

#: The format this module reads (older minors too); the writer writes minor 0 or 1 (module docstring).
FORMAT_MAJOR, FORMAT_MINOR = 1, 1
MAGIC = b"ABBE"
HEADER_SIZE = 64
AXIS_RECORD_SIZE = 64
COEF_START = HEADER_SIZE + 3 * AXIS_RECORD_SIZE  # 256
MIN_TOTAL_SIZE = COEF_START + 4  # 260
LIN_FRAC_BITS = 8   # linear coefficients: 2^-8 nm
ANG_FRAC_BITS = 36  # angular coefficients and squareness: 2^-36 rad
LIN_SUM_CAP = 1 << 32   # sum |int32 coef| of a linear term (16.7 mm)
ANG_SUM_CAP = 1 << 28   # sum |int32 coef| of an angular term (3906 urad)
SQUARENESS_CAP = 1 << 28
REVERSAL_SUM_CAP = 1 << 31  # |backlash| + sum |reversal coef|, 2^-8 nm (8.39 mm)
INT32_MIN, INT32_MAX = -(1 << 31), (1 << 31) - 1
# Unit factors: float value in table units -> integer units.
_UM_TO_Q8 = 1000.0 * (1 << LIN_FRAC_BITS)          # um -> 2^-8 nm
_URAD_TO_Q36_NUM = float(1 << ANG_FRAC_BITS)       # urad * 2^36 / 1e6 -> 2^-36 rad


def coef_sum_cap(term: str) -> float:
    """The table's cap on sum |coefficients| of ``term``, in its unit (um for linear
    terms: 16777 um; urad for angular terms: 3906 urad)."""
    if term in LINEAR_TERMS:
        return LIN_SUM_CAP / _UM_TO_Q8
    return ANG_SUM_CAP * 1e6 / _URAD_TO_Q36_NUM
_PPM_K_TO_Q50_NUM = float(1 << 50)                 # ppm/K * 2^50 / 1e9 -> 2^-50 per mK
_UM_K_TO_Q16 = float(1 << 16)                      # um/K == nm/mK -> 2^-16 nm per mK
#: Format 1.2: a five-axis table's rotary section (feature bit 5), read and written by
#: :mod:`abbe.formats.five_axis_blob` only; :func:`read_blob` refuses it by its minor, as
#: the C library's 3-axis loader does.
ROTARY_MINOR = 2
FEATURE_ROTARY = 0x20
ROTARY_DATA_START = COEF_START + 64 + 2 * 64  # 448: header, tilt and table axis records
#: Format 1.3: the thermal block (feature bit 6), read and written by
#: :mod:`abbe.formats.thermal_blob` only; :func:`read_blob` refuses it by its minor, as
#: the C library's abbe_model_load does (abbe_thermal_load reads it).
THERMAL_MINOR = 3
#: Five-axis tables of the kinds 3-5 (:mod:`abbe.formats.chain_blob`): the five-axis
#: reader's newest minor (it refuses 1.3).
CHAIN_MINOR = 4
FEATURE_THERMAL_DYN = 0x40
_HEADER_FMT = "<4sHHIIII3i3i3iI"
_AXIS_FMT = "<iiBBBB2i2iiiiiiIIII"
assert struct.calcsize(_HEADER_FMT) == HEADER_SIZE
assert struct.calcsize(_AXIS_FMT) == AXIS_RECORD_SIZE


@dataclass
class _AxisInts:
    travel_nm: tuple[int, int]
    term_mask: int
    trend_degree: int  # 255 = none
    harmonics: tuple[int, int]
    period_nm: tuple[int, int]
    origin_nm: tuple[int, int]
    backlash_q8: int
    takeup_nm: int
    expansion_q50: int
    offset_q16: int
    tref_mdegc: int
    coef_q: np.ndarray  # (n_basis, n_terms) int64 holding int32 values
    reversal_q8: np.ndarray  # (rows,) int64 holding int32 values; rows 0 = no reversal block


@dataclass
class _TableInts:
    features: int
    reference_nm: tuple[int, int, int]
    tool_nm: tuple[int, int, int]
    squareness_q36: tuple[int, int, int]
    axes: list[_AxisInts]


def _finite(value: float, where: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise TableError(f"not a number: {value!r}", status="ABBE_E_RANGE", field=where) from None
    if not math.isfinite(v):
        raise TableError(f"value is {v}", status="ABBE_E_NONFINITE", field=where)
    return v


def _to_int32(x: float, where: str, unit: str) -> int:
    r = round(x)  # nearest (ties to even), Python int
    if r < INT32_MIN or r > INT32_MAX:
        raise TableError(f"{x:.6g} {unit} does not fit in int32", status="ABBE_E_RANGE",
                         field=where)
    return int(r)


def _nm(mm: float, where: str) -> int:
    return _to_int32(_finite(mm, where) * 1e6, where, "nm")


def _encode(table: Table) -> _TableInts:
    """Convert a table to the integers the blob holds; raise TableError if impossible."""
    if set(table.axes) != set(AXES):
        raise TableError(f"axes must be exactly {AXES}, got {sorted(table.axes)}",
                         status="ABBE_E_COUNT", field="axes")
    ref = tuple(_nm(v, f"reference_mm[{i}]") for i, v in enumerate(table.reference_mm))
    tool = tuple(_nm(v, f"tool_offset_mm[{i}]") for i, v in enumerate(table.tool_offset_mm))
    sq = []
    for i, v in enumerate(table.squareness_urad):
        where = f"squareness_urad[{i}]"
        q = _to_int32(_finite(v, where) * _URAD_TO_Q36_NUM / 1e6, where, "2^-36 rad")
        if abs(q) > SQUARENESS_CAP:
            raise TableError(f"|squareness| {v} urad exceeds 2^28 * 2^-36 rad (3906 urad)",
                             status="ABBE_E_RANGE", field=where)
        sq.append(q)
    axes = [_encode_axis(table.axes[a], a) for a in AXES]
    features = 0
    if any(sq):
        features |= FEATURE_SQUARENESS
    if any(tool):
        features |= FEATURE_TOOL_OFFSET
    if any(ax.backlash_q8 or ax.takeup_nm or ax.reversal_q8.size for ax in axes):
        features |= FEATURE_BACKLASH
        for a, ax in zip(AXES, axes):
            if ax.takeup_nm < 0 or (ax.takeup_nm == 0 and (ax.backlash_q8 != 0 or ax.reversal_q8.size)):
                raise TableError(
                    "backlash take-up must be > 0 where the backlash or a reversal block is non-zero",
                    status="ABBE_E_RANGE", field=f"axes.{a}.backlash_takeup_mm")
    if any(ax.reversal_q8.size for ax in axes):
        features |= FEATURE_REVERSAL
    if any(ax.expansion_q50 or ax.offset_q16 or ax.tref_mdegc for ax in axes):
        features |= FEATURE_THERMAL
    return _TableInts(features, ref, tool, tuple(sq), axes)  # type: ignore[arg-type]


def _encode_axis(ax: AxisTable, a: str) -> _AxisInts:
    pre = f"axes.{a}."
    if len(ax.travel_mm) != 2:
        raise TableError("travel_mm must be (min, max)", status="ABBE_E_TRAVEL",
                         field=pre + "travel_mm")
    tmin, tmax = (_nm(v, pre + "travel_mm") for v in ax.travel_mm)
    if tmin >= tmax:
        raise TableError(f"travel min {ax.travel_mm[0]} mm must be below max "
                         f"{ax.travel_mm[1]} mm (in whole nm)", status="ABBE_E_TRAVEL",
                         field=pre + "travel_mm")
    if ax.trend_degree is None:
        deg = NO_TREND
    else:
        deg = int(ax.trend_degree)
        if not 0 <= deg <= MAX_DEGREE:
            raise TableError(f"trend degree {deg} not in 0..{MAX_DEGREE}",
                             status="ABBE_E_COUNT", field=pre + "trend_degree")
    harm, period, origin = [0, 0], [0, 0], [0, 0]
    for b, blk in enumerate(ax.blocks):
        if blk is None or int(blk.harmonics) == 0:
            continue
        h = int(blk.harmonics)
        if not 1 <= h <= MAX_HARMONICS:
            raise TableError(f"harmonics {h} not in 0..{MAX_HARMONICS}", status="ABBE_E_COUNT",
                             field=pre + f"blocks[{b}].harmonics")
        per = _nm(blk.period_mm, pre + f"blocks[{b}].period_mm")
        if per <= 0:
            raise TableError(f"period {blk.period_mm} mm must be > 0 (in whole nm)",
                             status="ABBE_E_PERIOD", field=pre + f"blocks[{b}].period_mm")
        harm[b], period[b] = h, per
        origin[b] = _nm(blk.origin_mm, pre + f"blocks[{b}].origin_mm")
    unknown = set(ax.coef) - set(TERMS)
    if unknown:
        raise TableError(f"unknown term(s) {sorted(unknown)}; terms are {TERMS}",
                         status="ABBE_E_COUNT", field=pre + "coef")
    ax_n = replace(ax, blocks=tuple(  # type: ignore[arg-type]
        None if (blk is None or int(blk.harmonics) == 0) else blk for blk in ax.blocks))
    nb = ax_n.n_basis()
    present = ax_n.present_terms()
    mask = 0
    cols = []
    for t in present:
        where = pre + f"coef.{t}"
        c = np.asarray(ax.coef[t], dtype=np.float64).reshape(-1)
        if c.size != nb:
            raise TableError(f"{c.size} coefficients, the axis has {nb} basis rows",
                             status="ABBE_E_COUNT", field=where)
        if not np.all(np.isfinite(c)):
            raise TableError("coefficient is NaN or infinite", status="ABBE_E_NONFINITE",
                             field=where)
        if t in LINEAR_TERMS:
            q = np.rint(c * _UM_TO_Q8)
            cap, unit = LIN_SUM_CAP, "2^-8 nm"
        else:
            q = np.rint(c * _URAD_TO_Q36_NUM / 1e6)
            cap, unit = ANG_SUM_CAP, "2^-36 rad"
        if np.any(np.abs(q) > INT32_MAX):
            raise TableError(f"coefficient does not fit in int32 {unit}",
                             status="ABBE_E_RANGE", field=where)
        q = q.astype(np.int64)
        if int(np.abs(q).sum()) > cap:
            u = "um" if t in LINEAR_TERMS else "urad"
            lim, tot = coef_sum_cap(t), float(np.abs(c).sum())
            raise TableError(f"sum of |coefficients| {tot:.6g} {u} exceeds the fixed-point cap "
                             f"({lim:.0f} {u}) by {tot - lim:.6g} {u}: the error of this term is "
                             "larger than the table holds; check the channel's unit and sign "
                             "mapping and the set-up, or correct this error mechanically first",
                             status="ABBE_E_RANGE", field=where)
        mask |= 1 << TERMS.index(t)
        cols.append(q)
    coef_q = np.stack(cols, axis=1) if cols else np.zeros((nb, 0), dtype=np.int64)
    b_q8 = _to_int32(_finite(ax.backlash_um, pre + "backlash_um") * _UM_TO_Q8,
                     pre + "backlash_um", "2^-8 nm")
    takeup = _nm(ax.backlash_takeup_mm, pre + "backlash_takeup_mm")
    if takeup < 0:
        raise TableError("backlash take-up must be > 0", status="ABBE_E_RANGE",
                         field=pre + "backlash_takeup_mm")
    exp_q50 = _to_int32(_finite(ax.thermal_expansion_ppm_per_k,
                                pre + "thermal_expansion_ppm_per_k") * _PPM_K_TO_Q50_NUM / 1e9,
                        pre + "thermal_expansion_ppm_per_k", "2^-50 per mK")
    off_q16 = _to_int32(_finite(ax.thermal_offset_um_per_k, pre + "thermal_offset_um_per_k")
                        * _UM_K_TO_Q16, pre + "thermal_offset_um_per_k", "2^-16 nm per mK")
    tref = _to_int32(_finite(ax.thermal_tref_c, pre + "thermal_tref_c") * 1000.0,
                     pre + "thermal_tref_c", "mdegC")
    rev_q8 = _encode_reversal(ax, b_q8, pre)
    return _AxisInts((tmin, tmax), mask, deg, (harm[0], harm[1]), (period[0], period[1]),
                     (origin[0], origin[1]), b_q8, takeup, exp_q50, off_q16, tref, coef_q, rev_q8)


def _encode_reversal(ax: AxisTable, b_q8: int, pre: str) -> np.ndarray:
    """The reversal block's coefficients in 2^-8 nm (empty without a block)."""
    where = pre + "reversal_cheb_um"
    if ax.reversal_cheb_um is None:
        return np.zeros(0, dtype=np.int64)
    try:
        c = np.asarray(ax.reversal_cheb_um, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise TableError("expected a sequence of numbers (um) or None", status="ABBE_E_COUNT",
                         field=where) from None
    if not 1 <= c.size <= MAX_REVERSAL_ROWS:
        raise TableError(f"{c.size} coefficients: a reversal block has 1..{MAX_REVERSAL_ROWS} "
                         "(degree 0..7), or is None", status="ABBE_E_COUNT", field=where)
    if not np.all(np.isfinite(c)):
        raise TableError("coefficient is NaN or infinite", status="ABBE_E_NONFINITE", field=where)
    q = np.rint(c * _UM_TO_Q8)
    if np.any(np.abs(q) > INT32_MAX):
        raise TableError("coefficient does not fit in int32 2^-8 nm", status="ABBE_E_RANGE",
                         field=where)
    q = q.astype(np.int64)
    if abs(b_q8) + int(np.abs(q).sum()) > REVERSAL_SUM_CAP:
        raise TableError("|backlash_um| + sum of |reversal coefficients| exceeds the fixed-point "
                         "cap (8.39 mm)", status="ABBE_E_RANGE", field=where)
    return q


def _lin_from_q8(q: Any) -> Any:
    return np.asarray(q, dtype=np.float64) / _UM_TO_Q8


def _ang_from_q36(q: Any) -> Any:
    # q * 1e6 is exact in float64 for |q| < 2^31, the division by 2^36 too.
    return np.asarray(q, dtype=np.float64) * 1e6 / _URAD_TO_Q36_NUM


def _decode(ti: _TableInts) -> Table:
    axes: dict[str, AxisTable] = {}
    for a, ai in zip(AXES, ti.axes):
        blocks: list[FourierBlock | None] = []
        for b in range(2):
            if ai.harmonics[b] > 0:
                blocks.append(FourierBlock(ai.period_nm[b] / 1e6, ai.origin_nm[b] / 1e6,
                                           int(ai.harmonics[b])))
            else:
                blocks.append(None)
        coef: dict[str, np.ndarray] = {}
        col = 0
        for t_i, t in enumerate(TERMS):
            if ai.term_mask & (1 << t_i):
                q = ai.coef_q[:, col]
                coef[t] = (_lin_from_q8(q) if t in LINEAR_TERMS else _ang_from_q36(q))
                col += 1
        rev = (None if ai.reversal_q8.size == 0
               else tuple(float(v) for v in _lin_from_q8(ai.reversal_q8)))
        axes[a] = AxisTable(
            travel_mm=(ai.travel_nm[0] / 1e6, ai.travel_nm[1] / 1e6),
            trend_degree=None if ai.trend_degree == NO_TREND else int(ai.trend_degree),
            blocks=(blocks[0], blocks[1]),
            coef=coef,
            backlash_um=float(_lin_from_q8(ai.backlash_q8)),
            backlash_takeup_mm=ai.takeup_nm / 1e6,
            thermal_expansion_ppm_per_k=ai.expansion_q50 * 1e9 / _PPM_K_TO_Q50_NUM,
            thermal_offset_um_per_k=ai.offset_q16 / _UM_K_TO_Q16,
            thermal_tref_c=ai.tref_mdegc / 1000.0,
            reversal_cheb_um=rev,
        )
    return Table(
        axes=axes,
        reference_mm=tuple(v / 1e6 for v in ti.reference_nm),  # type: ignore[arg-type]
        tool_offset_mm=tuple(v / 1e6 for v in ti.tool_nm),  # type: ignore[arg-type]
        squareness_urad=tuple(float(_ang_from_q36(v)) for v in ti.squareness_q36),  # type: ignore[arg-type]
    )


def quantize(table: Table) -> Table:
    """The exact values the blob of ``table`` holds, converted back to table units.

    Raises TableError (status as the C loader would report it) if a value cannot
    be represented. A Fourier block with 0 harmonics becomes ``None``.
    """
    return _decode(_encode(table))


def quantization_error(table: Table, samples: int = 2001) -> dict[tuple[str, str], float]:
    """Worst-case |term(table) - term(quantize(table))| over each axis' travel.

    Sampled on ``samples`` evenly spaced positions plus the travel ends; um for
    linear terms, urad for angular terms, keyed by (axis, term) for present terms.
    (A reversal block's rounding, at most its row count x 2^-9 nm, is not listed.)
    """
    qt = quantize(table)
    out: dict[tuple[str, str], float] = {}
    for a in AXES:
        ax, qax = table.axes[a], qt.axes[a]
        lo, hi = ax.travel_mm
        # Sample densely enough to resolve the shortest period present.
        n = samples
        for blk in ax.blocks:
            if blk is not None and blk.harmonics:
                n = max(n, int(16 * blk.harmonics * (hi - lo) / blk.period_mm) + 1)
        n = min(n, 400_001)
        p = np.linspace(lo, hi, n)
        b0, b1 = basis_matrix(ax, p), basis_matrix(qax, p)
        for t in ax.present_terms():
            c0 = np.asarray(ax.coef[t], dtype=np.float64)
            out[(a, t)] = float(np.max(np.abs(b0 @ c0 - b1 @ qax.coef[t])))
    return out


def write_blob(table: Table) -> bytes:
    """Serialise ``table`` to the blob (docs/table-format.md): format 1.0, or 1.1
    if an axis has a reversal block.

    Values are rounded to the nearest integer of their encoding; TableError if one
    cannot be represented. Same table -> same bytes.
    """
    ti = _encode(table)
    return _write(ti, 1 if ti.features & FEATURE_REVERSAL else 0, COEF_START, None, [])


def _write(ti: _TableInts, minor: int, data_start: int,
           section: Callable[[list[tuple[int, int]]], bytes] | None,
           extra: list[np.ndarray]) -> bytes:
    """The blob of ``ti`` at ``minor``: the linear axes' arrays from ``data_start``,
    then the ``extra`` int32 arrays, each followed by its float32 twin, and
    ``section(offsets of the extra arrays)`` (a five-axis table's rotary section,
    :mod:`abbe.formats.five_axis_blob`) at byte 256."""
    counts = [ai.coef_q.size + ai.reversal_q8.size for ai in ti.axes] + [a.size for a in extra]
    offsets = []
    pos = data_start
    for n in counts:
        if n:
            offsets.append((pos, pos + 4 * n))
            pos += 8 * n
        else:
            offsets.append((0, 0))
    total = pos + 4
    out = bytearray(total)
    struct.pack_into(_HEADER_FMT, out, 0, MAGIC, FORMAT_MAJOR, minor, total,
                     HEADER_SIZE, AXIS_RECORD_SIZE, ti.features, *ti.reference_nm,
                     *ti.tool_nm, *ti.squareness_q36, 0)
    arrays = [np.concatenate([ai.coef_q.reshape(-1), ai.reversal_q8]) for ai in ti.axes] + extra
    for i, (ai, (qoff, foff), n) in enumerate(zip(ti.axes, offsets, counts)):
        struct.pack_into(_AXIS_FMT, out, HEADER_SIZE + i * AXIS_RECORD_SIZE,
                         ai.travel_nm[0], ai.travel_nm[1], ai.term_mask, ai.trend_degree,
                         ai.harmonics[0], ai.harmonics[1], *ai.period_nm, *ai.origin_nm,
                         ai.backlash_q8, ai.takeup_nm, ai.expansion_q50, ai.offset_q16,
                         ai.tref_mdegc, qoff, foff, n, ai.reversal_q8.size)
    for q, (qoff, foff), n in zip(arrays, offsets, counts):
        if n:
            # row-major: c[row * n_terms + column], then the reversal block's rows
            out[qoff:qoff + 4 * n] = np.asarray(q, dtype=np.int64).astype("<i4").tobytes()
            # the float32 twin: each int32 converted, round to nearest even, same units
            out[foff:foff + 4 * n] = np.asarray(q, dtype=np.int64).astype(np.float32).astype(
                "<f4").tobytes()
    if section is not None:
        sec = section(offsets[len(ti.axes):])
        if len(sec) != data_start - COEF_START:
            raise ValueError("the rotary section must fill 256 .. data_start")
        out[COEF_START:data_start] = sec
    struct.pack_into("<I", out, total - 4, zlib.crc32(bytes(out[:total - 4])) & 0xFFFFFFFF)
    return bytes(out)


def blob_crc(data: bytes) -> int:
    """The CRC-32 stored in a (valid) blob: identifies the model."""
    total = struct.unpack_from("<I", data, 8)[0]
    return struct.unpack_from("<I", data, total - 4)[0]


def read_blob_file(path: Any) -> tuple[bytes, Table]:
    """A blob file (bounded read, :mod:`abbe.formats.text`) and its decoded table."""
    from abbe.formats.limits import BLOB_MAX_BYTES
    from abbe.formats.text import read_bytes
    data = read_bytes(path, what="table blob", max_bytes=BLOB_MAX_BYTES)
    return data, read_blob(data, source=str(path))


def read_blob(data: bytes, source: str = "<blob>") -> Table:
    """Validate a blob with every check of the spec, in its order, and decode it.

    ``data`` may be longer than the table (extra bytes ignored). Raises
    TableError with the C status name of the first failed check.
    """
    return _decode(_read_ints(data, source))


def _read_ints(data: bytes, source: str, rotary: bool = False,
               thermal: bool = False) -> _TableInts:
    """The checks of the header and the linear axes. rotary: the five-axis
    reader's call (:mod:`abbe.formats.five_axis_blob`): format 1.2 and its ROTARY
    bit are read, and with ROTARY the linear arrays start after the rotary section.
    thermal: the format 1.3 reader's call (:mod:`abbe.formats.thermal_blob`): minor 3
    and its THERMAL_DYN bit are read, the header's reserved word is then the thermal
    block's offset (checked by that reader)."""
    def err(status: str, msg: str, fld: str | None = None) -> TableError:
        return TableError(msg, status=status, file=source, field=fld)

    if data is None or not isinstance(data, (bytes, bytearray, memoryview)):
        raise err("ABBE_E_ARG", "no blob")
    data = bytes(data)
    n = len(data)
    if n < HEADER_SIZE:
        raise err("ABBE_E_TRUNCATED", f"{n} bytes, shorter than the 64-byte header")
    (magic, major, minor, total, hsize, asize, features, *rest) = struct.unpack_from(
        _HEADER_FMT, data, 0)
    ref, tool, sq, reserved = tuple(rest[0:3]), tuple(rest[3:6]), tuple(rest[6:9]), rest[9]
    if n < total:
        raise err("ABBE_E_TRUNCATED", f"{n} bytes, the table declares {total}", "total_size")
    if magic != MAGIC:
        raise err("ABBE_E_MAGIC", f"magic {magic!r} is not b'ABBE': not an abbe table", "magic")
    if major != FORMAT_MAJOR:
        raise err("ABBE_E_VERSION_MAJOR", f"table format {major}.{minor}, this reader reads "
                  f"{FORMAT_MAJOR}.x", "version_major")
    # the five-axis reader reads 1.4 (kinds 3-5) but not 1.3 (the 3-axis thermal block)
    if minor > (THERMAL_MINOR if thermal else CHAIN_MINOR if rotary else FORMAT_MINOR) or \
            (rotary and not thermal and minor == THERMAL_MINOR):
        raise err("ABBE_E_VERSION_MINOR", f"table format {major}.{minor} is newer than "
                  f"{FORMAT_MAJOR}.{FORMAT_MINOR}", "version_minor")
    if hsize != HEADER_SIZE:
        raise err("ABBE_E_SIZE", f"header_size {hsize} != {HEADER_SIZE}", "header_size")
    if asize != AXIS_RECORD_SIZE:
        raise err("ABBE_E_SIZE", f"axis_record_size {asize} != {AXIS_RECORD_SIZE}",
                  "axis_record_size")
    if total < MIN_TOTAL_SIZE or total % 4:
        raise err("ABBE_E_SIZE", f"total_size {total} must be >= {MIN_TOTAL_SIZE} and a "
                  "multiple of 4", "total_size")
    if rotary and features & FEATURE_ROTARY and total < ROTARY_DATA_START + 4:
        raise err("ABBE_E_SIZE", f"total_size {total} < {ROTARY_DATA_START + 4}: no room for "
                  "the rotary section", "total_size")
    crc_stored = struct.unpack_from("<I", data, total - 4)[0]
    crc = zlib.crc32(data[:total - 4]) & 0xFFFFFFFF
    if crc != crc_stored:
        raise err("ABBE_E_CRC", f"CRC-32 0x{crc:08X} != stored 0x{crc_stored:08X}: "
                  "table damaged", "crc")
    recs = [struct.unpack_from(_AXIS_FMT, data, HEADER_SIZE + i * AXIS_RECORD_SIZE)
            for i in range(3)]
    # record fields
    (TMIN, TMAX, MASK, DEG, H0, H1, P0, P1, O0, O1, BQ8, TAKEUP, EXP, OFF, TREF,
     QOFF, FOFF, COUNT, RES) = range(19)

    # FLAGS
    known = FEATURES_1_0 if minor == 0 else FEATURE_ALL
    if rotary and minor >= ROTARY_MINOR:
        known |= FEATURE_ROTARY
    if thermal and minor >= THERMAL_MINOR:
        known |= FEATURE_THERMAL_DYN
        if features & FEATURE_THERMAL_DYN:
            reserved = 0  # the thermal block's offset
    if features & ~known:
        raise err("ABBE_E_FLAGS", f"unknown feature bits 0x{features & ~known:X} for table "
                  f"format {major}.{minor}", "features")
    if reserved:
        raise err("ABBE_E_FLAGS", "reserved header field is not 0", "reserved")
    if not features & FEATURE_TOOL_OFFSET and any(tool):
        raise err("ABBE_E_FLAGS", "tool offset set but feature TOOL_OFFSET off",
                  "tool_offset_nm")
    if not features & FEATURE_SQUARENESS and any(sq):
        raise err("ABBE_E_FLAGS", "squareness set but feature SQUARENESS off",
                  "squareness_q36")
    if features & FEATURE_REVERSAL and not features & FEATURE_BACKLASH:
        raise err("ABBE_E_FLAGS", "feature REVERSAL needs BACKLASH (its take-up and direction "
                  "state)", "features")
    for a, r in zip(AXES, recs):
        if r[RES] >> 8:
            raise err("ABBE_E_FLAGS", "reserved axis bytes 61..63 are not 0", f"axes.{a}.reserved")
        if r[RES] and not features & FEATURE_REVERSAL:
            raise err("ABBE_E_FLAGS", "reversal_rows set but feature REVERSAL off"
                      + (" (format 1.0: reserved)" if minor == 0 else ""),
                      f"axes.{a}.reversal_rows")
        if not features & FEATURE_BACKLASH and (r[BQ8] or r[TAKEUP]):
            raise err("ABBE_E_FLAGS", "backlash set but feature BACKLASH off",
                      f"axes.{a}.backlash")
        if not features & FEATURE_THERMAL and (r[EXP] or r[OFF] or r[TREF]):
            raise err("ABBE_E_FLAGS", "thermal field set but feature THERMAL off",
                      f"axes.{a}.thermal")
    data_start = ROTARY_DATA_START if rotary and features & FEATURE_ROTARY else COEF_START
    # COUNT
    shapes = []
    for a, r in zip(AXES, recs):
        if r[MASK] & 0xC0:
            raise err("ABBE_E_COUNT", f"term_mask 0x{r[MASK]:02X} has bits 6/7 set",
                      f"axes.{a}.term_mask")
        if r[DEG] > MAX_DEGREE and r[DEG] != NO_TREND:
            raise err("ABBE_E_COUNT", f"trend_degree {r[DEG]} not in 0..7 or 255",
                      f"axes.{a}.trend_degree")
        for b, h in enumerate((r[H0], r[H1])):
            if h > MAX_HARMONICS:
                raise err("ABBE_E_COUNT", f"harmonics {h} > {MAX_HARMONICS}",
                          f"axes.{a}.harmonics[{b}]")
        rows = r[RES] & 0xFF
        if rows > MAX_REVERSAL_ROWS:
            raise err("ABBE_E_COUNT", f"reversal_rows {rows} > {MAX_REVERSAL_ROWS}",
                      f"axes.{a}.reversal_rows")
        n_terms = bin(r[MASK]).count("1")
        n_basis = (0 if r[DEG] == NO_TREND else r[DEG] + 1) + 2 * r[H0] + 2 * r[H1]
        if r[COUNT] != n_basis * n_terms + rows:
            raise err("ABBE_E_COUNT", f"coef_count {r[COUNT]} != n_basis {n_basis} x n_terms "
                      f"{n_terms} + reversal_rows {rows}", f"axes.{a}.coef_count")
        shapes.append((n_basis, n_terms, rows))
    # OFFSET
    for a, r in zip(AXES, recs):
        cnt = r[COUNT]
        for idx, name in ((QOFF, "coef_q_offset"), (FOFF, "coef_f32_offset")):
            off = r[idx]
            if cnt == 0:
                if off != 0:
                    raise err("ABBE_E_OFFSET", f"{name} {off} != 0 with coef_count 0",
                              f"axes.{a}.{name}")
                continue
            if off < data_start or off + 4 * cnt > total - 4 or off % 4:
                raise err("ABBE_E_OFFSET", f"{name} {off} (+{4 * cnt} bytes) not a 4-aligned "
                          f"range inside [{data_start}, {total - 4})", f"axes.{a}.{name}")
    # NONFINITE
    for a, r in zip(AXES, recs):
        if r[COUNT]:
            f = np.frombuffer(data, dtype="<f4", count=r[COUNT], offset=r[FOFF])
            if not np.all(np.isfinite(f)):
                raise err("ABBE_E_NONFINITE", "float32 coefficient is NaN or infinite",
                          f"axes.{a}.coef_f32")
    # MISMATCH: the float32 array must be the int32 array converted, bit for bit
    for a, r in zip(AXES, recs):
        if r[COUNT]:
            q = np.frombuffer(data, dtype="<i4", count=r[COUNT], offset=r[QOFF])
            f = np.frombuffer(data, dtype="<u4", count=r[COUNT], offset=r[FOFF])
            bad = np.flatnonzero(q.astype(np.float32).view("<u4") != f)
            if bad.size:
                raise err("ABBE_E_MISMATCH", f"float32 coefficient {int(bad[0])} is not its int32 "
                          "value converted", f"axes.{a}.coef_f32")
    # PERIOD
    for a, r in zip(AXES, recs):
        for b, (h, per, org) in enumerate(((r[H0], r[P0], r[O0]), (r[H1], r[P1], r[O1]))):
            if h > 0 and per <= 0:
                raise err("ABBE_E_PERIOD", f"period {per} nm of a used block must be > 0",
                          f"axes.{a}.period_nm[{b}]")
            if h == 0 and (per != 0 or org != 0):
                raise err("ABBE_E_PERIOD", "period/origin set for an unused block",
                          f"axes.{a}.period_nm[{b}]")
    # TRAVEL
    for a, r in zip(AXES, recs):
        if r[TMIN] >= r[TMAX]:
            raise err("ABBE_E_TRAVEL", f"travel_min {r[TMIN]} nm >= travel_max {r[TMAX]} nm",
                      f"axes.{a}.travel_nm")
    # RANGE
    coefs, revs = [], []
    for a, r, (nb, nt, rows) in zip(AXES, recs, shapes):
        if r[COUNT]:
            allq = np.frombuffer(data, dtype="<i4", count=r[COUNT], offset=r[QOFF]).astype(np.int64)
        else:
            allq = np.zeros(0, dtype=np.int64)
        q = allq[:nb * nt].reshape(nb, nt)
        rev = allq[nb * nt:]
        col = 0
        for t_i, t in enumerate(TERMS):
            if r[MASK] & (1 << t_i):
                cap = LIN_SUM_CAP if t in LINEAR_TERMS else ANG_SUM_CAP
                if int(np.abs(q[:, col]).sum()) > cap:
                    raise err("ABBE_E_RANGE", "sum of |coefficients| over the fixed-point cap",
                              f"axes.{a}.coef.{t}")
                col += 1
        if abs(r[BQ8]) + int(np.abs(rev).sum()) > REVERSAL_SUM_CAP:
            raise err("ABBE_E_RANGE", "|backlash| + sum of |reversal coefficients| over 2^31 "
                      "(8.39 mm)", f"axes.{a}.reversal_q8")
        coefs.append(q)
        revs.append(rev)
    for i, s in enumerate(sq):
        if abs(s) > SQUARENESS_CAP:
            raise err("ABBE_E_RANGE", f"|squareness| {s} > 2^28", f"squareness_q36[{i}]")
    if features & FEATURE_BACKLASH:
        for a, r in zip(AXES, recs):
            if r[TAKEUP] < 0 or (r[TAKEUP] == 0 and (r[BQ8] != 0 or r[RES] & 0xFF)):
                raise err("ABBE_E_RANGE", "backlash take-up must be > 0 where the backlash or a "
                          "reversal block is non-zero", f"axes.{a}.backlash_takeup_nm")
    axes = [
        _AxisInts((r[TMIN], r[TMAX]), r[MASK], r[DEG], (r[H0], r[H1]), (r[P0], r[P1]),
                  (r[O0], r[O1]), r[BQ8], r[TAKEUP], r[EXP], r[OFF], r[TREF], q, rev)
        for r, q, rev in zip(recs, coefs, revs)
    ]
    return _TableInts(features, ref, tool, sq, axes)  # type: ignore[arg-type]


def blob_features(data: bytes) -> int:
    """Feature bits of a blob (validated)."""
    return _read_ints(data, "<blob>").features
