"""Five-axis tables of the other kinematic kinds (format 1.4, docs/table-format.md
"Other kinematic kinds"): head-head (kind 3, 5axiskins), head-table (kind 4, maxkins)
and the dual rotary table (kind 5, xyzab-tdr), written from a kinematic chain
(:class:`abbe.model.chain.KinematicChain`) and its errors.

The layout is the trunnions' rotary section (:mod:`abbe.formats.five_axis_blob`) at
version_minor 4, with per kind which axis each record holds and what rot_point and
offset mean; format 1.4 adds per record a direction byte (offset 22: 0 turns about +
its machine axis, 1 about -) and in the rotary header at offset 40 the point the
five-axis squareness' lever starts at (i32[3] nm: the chain's ``reference_mm``).

:func:`read_chain_blob` decodes such a table back to a chain and its (quantised)
errors: the float64 reference of the C evaluation is then
:func:`abbe.model.chain.tool_error_linear` of what it returns. It is a decoder, not a
validator: ``abbe_five_model_load`` is the one that checks a 1.4 table.
"""

from __future__ import annotations

import struct
import zlib

import numpy as np

from abbe.formats import blob as _blob
from abbe.formats.five_axis_blob import (
    _RA_FMT,
    _RH_FMT,
    GEOMETRY_CAP_NM,
    HH_LEVER_L1_CAP_NM,
    _int32,
    _motion_matrix,
    _Q8_PER_UM,
    _Q36_PER_URAD,
    EMPTY_LINEAR_TRAVEL_MM,
)
from abbe.model.chain import ChainAxis, KinematicChain
from abbe.model.five_axis import LOCATION_ERRORS, MOTION_COMPONENTS, FiveAxisErrors
from abbe.model.table import AXES, AxisTable, Table, TableError

#: The format minor of the kinds 3-5.
CHAIN_MINOR = 4
#: kind byte -> (name, record 0's axis, record 1's axis, rotary axes on the workpiece side)
CHAIN_KINDS: dict[int, tuple[str, str, str, tuple[str, ...]]] = {
    3: ("xyzbc-hh", "C", "B", ()),
    4: ("xyzbc-ht", "B", "C", ("C",)),
    5: ("xyzab-tdr", "B", "A", ("A", "B")),
}


def chain_kind(chain: KinematicChain) -> int:
    """The kind byte of a chain (3, 4 or 5), TableError if the chain is none of them."""
    if chain.tool_side == ("C", "B"):
        return 3
    if chain.workpiece_side == ("C",) and chain.tool_side == ("B",):
        return 4
    if chain.workpiece_side == ("A", "B"):
        return 5
    raise TableError(f"chain {chain.name!r} (workpiece side {chain.workpiece_side}, tool side "
                     f"{chain.tool_side}) is not a kind of format 1.4: head-head C then B, "
                     "head-table C / B or dual rotary table A on B", status="ABBE_E_FLAGS",
                     field="rotary.kind")


def _geometry(chain: KinematicChain, kind: int) -> tuple[np.ndarray, np.ndarray]:
    """(rot_point, offset) mm of the table's header for ``kind``."""
    if kind == 3:
        return chain.pivot("C"), chain.pivot("B") - chain.pivot("C")
    if kind == 4:
        return chain.pivot("C"), chain.pivot("B")
    return chain.pivot("B"), chain.pivot("A") - chain.pivot("B")


def write_chain_blob(chain: KinematicChain, errs: FiveAxisErrors) -> bytes:
    """Serialise a kind 3-5 chain and its errors to a format 1.4 table (values rounded
    to their encodings; TableError if one cannot be represented)."""
    kind = chain_kind(chain)
    _, a0, a1, _ = CHAIN_KINDS[kind]
    lin = errs.linear if errs.linear is not None else Table(
        axes={a: AxisTable(travel_mm=EMPTY_LINEAR_TRAVEL_MM) for a in AXES},
        reference_mm=tuple(float(v) for v in chain.reference_mm))  # type: ignore[arg-type]
    ti = _blob._encode(lin)
    ti.features |= _blob.FEATURE_ROTARY
    rp_mm, off_mm = _geometry(chain, kind)
    rp = [_int32(v * 1e6, f"rotary.rot_point_mm[{i}]", "nm") for i, v in enumerate(rp_mm)]
    off = [_int32(v * 1e6, f"rotary.offset_mm[{i}]", "nm") for i, v in enumerate(off_mm)]
    ref = [_int32(v * 1e6, f"rotary.square_ref_mm[{i}]", "nm") for i, v in enumerate(chain.reference_mm)]
    if max(abs(v) for v in rp + off + ref) > GEOMETRY_CAP_NM:
        raise TableError("rotation point / offset / reference beyond 1073 mm", status="ABBE_E_RANGE",
                         field="rotary.geometry")
    if kind == 3 and sum(abs(o) + abs(r + o) for r, o in zip(rp, off)) > HH_LEVER_L1_CAP_NM:
        raise TableError("head-head: |offset|_1 + |rot_point + offset|_1 beyond 2^32 - 2^10 nm (4294 mm), "
                         "the fixed-point lever's range", status="ABBE_E_RANGE", field="rotary.geometry")
    sq = [_int32(v * _Q36_PER_URAD, f"rotary.squareness_urad[{i}]", "2^-36 rad")
          for i, v in enumerate(errs.squareness)]
    records, arrays = [], []
    for axis in (a0, a1):
        names = LOCATION_ERRORS[axis]
        loc = [float(errs.location.get(n, 0.0)) for n in names]
        lin_q = [_int32(v * _Q8_PER_UM, f"rotary.{axis}.{n}", "2^-8 nm") for v, n in zip(loc[:2], names)]
        ang = [_int32(v * _Q36_PER_URAD, f"rotary.{axis}.{n}", "2^-36 rad")
               for v, n in zip(loc[2:], names[2:])]
        if max(abs(v) for v in sq + ang) > _blob.SQUARENESS_CAP:
            raise TableError("an angle beyond 2^28 x 2^-36 rad (3906 urad)", status="ABBE_E_RANGE",
                             field=f"rotary.{axis}")
        mask, h, mat = _motion_matrix(errs, axis)
        sign = b"\x01\x00" if chain.axis(axis).direction == -1 else b"\x00\x00"
        records.append((lin_q, ang, mask, h, sign))
        arrays.append(mat.reshape(-1))

    def section(offsets: list[tuple[int, int]]) -> bytes:
        res = struct.pack("<3i12x", *ref)
        out = bytearray(struct.pack(_RH_FMT, kind, b"", *rp, *off, *sq, res))
        for (lq, ang, mask, h, sign), (qo, fo), arr in zip(records, offsets, arrays):
            out += struct.pack(_RA_FMT, *lq, *ang, mask, h, sign, qo, fo, arr.size, b"")
        return bytes(out)

    return _blob._write(ti, CHAIN_MINOR, _blob.ROTARY_DATA_START, section, arrays)


def read_chain_blob(data: bytes) -> tuple[KinematicChain, FiveAxisErrors]:
    """Decode a format 1.4 table of kind 3-5 to its chain and quantised errors (no
    validation beyond the linear part's: see the module docstring)."""
    data = bytes(data)
    (kind, _r0, *rest) = struct.unpack_from(_RH_FMT, data, _blob.COEF_START)
    if kind not in CHAIN_KINDS:
        raise TableError(f"kind {kind} is not 3, 4 or 5", status="ABBE_E_FLAGS", field="rotary.kind")
    rp, off, sq, res = rest[0:3], rest[3:6], rest[6:9], rest[9]
    ref = struct.unpack_from("<3i", res, 0)
    name, a0, a1, wside = CHAIN_KINDS[kind]
    recs = [struct.unpack_from(_RA_FMT, data, _blob.COEF_START + 64 + 64 * r) for r in range(2)]
    # the linear axes: the 1.2 reader on a copy at minor 2 (its own checks, CRC renewed)
    copy = bytearray(data)
    struct.pack_into("<H", copy, 6, _blob.ROTARY_MINOR)
    total = struct.unpack_from("<I", copy, 8)[0]
    struct.pack_into("<I", copy, total - 4, zlib.crc32(bytes(copy[:total - 4])) & 0xFFFFFFFF)
    errs = FiveAxisErrors(squareness=tuple(v / _Q36_PER_URAD for v in sq))  # type: ignore[arg-type]
    errs.linear = _blob._decode(_blob._read_ints(bytes(copy), "<chain blob>", rotary=True))
    for axis, r in zip((a0, a1), recs):
        lin, ang, mask, h, count = r[0:2], r[2:5], r[5], r[6], r[10]
        names = LOCATION_ERRORS[axis]
        for n, v in zip(names, lin):
            errs.location[n] = v / _Q8_PER_UM
        for n, v in zip(names[2:], ang):
            errs.location[n] = v / _Q36_PER_URAD
        n_comp = bin(mask).count("1")
        mat = (np.frombuffer(data, "<i4", count, r[8]).astype(np.int64).reshape(2 * h, n_comp)
               if count else np.zeros((2 * h, n_comp), dtype=np.int64))
        col = 0
        for i, c in enumerate(MOTION_COMPONENTS):
            if mask >> i & 1:
                errs.motions[(axis, c)] = mat[:, col] / (_Q8_PER_UM if i < 3 else _Q36_PER_URAD)
                col += 1
    sign = {a0: -1 if recs[0][7][0] else 1, a1: -1 if recs[1][7][0] else 1}
    rp_mm = np.asarray(rp, dtype=np.float64) * 1e-6
    off_mm = np.asarray(off, dtype=np.float64) * 1e-6
    pivots = {3: {"C": rp_mm, "B": rp_mm + off_mm}, 4: {"C": rp_mm, "B": off_mm},
              5: {"B": rp_mm, "A": rp_mm + off_mm}}[kind]

    def ax(n: str) -> ChainAxis:
        return ChainAxis(n, sign[n], tuple(float(v) for v in pivots[n]))  # type: ignore[arg-type]

    lin_axes = tuple(ChainAxis(n, 1, (0.0, 0.0, 0.0), (0.0, 0.0)) for n in "XYZ")
    tool = tuple(n for n in (a0, a1) if n not in wside)
    order = tuple(ax(n) for n in wside) + lin_axes + tuple(ax(n) for n in tool)
    chain = KinematicChain(name, order, 0.0, tuple(v * 1e-6 for v in ref))  # type: ignore[arg-type]
    return chain, errs
