"""Five-axis tables (format 1.2, docs/table-format.md "Rotary section"): writer, reader.

A five-axis table is a 3-axis table (the linear axes; :mod:`abbe.formats.blob`)
with feature bit 5 ROTARY and, at byte 256, the rotary section: the kinematics
kind and nominal geometry, the five-axis squareness, and per rotary axis (tilt,
then C) its ISO 230-1 location errors and the Fourier series of its six error
motions (period one turn). The C library reads it with ``abbe_five_model_load``;
:func:`read_five_blob` applies the same checks in the same order and raises
:class:`abbe.model.table.TableError` with the same status name.

Encodings: positions nm; linear errors and coefficients 2^-8 nm; angles and
angular coefficients 2^-36 rad (as the linear axes' tables).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any

import numpy as np

from abbe.formats import blob as _blob
from abbe.model.five_axis import (
    KINEMATICS,
    LOCATION_ERRORS,
    MOTION_COMPONENTS,
    FiveAxisErrors,
    TrunnionGeometry,
    tool_error_linear,
)
from abbe.model.table import AXES, AxisTable, Table, TableError

#: The rotary header's kind byte.
KIND_CODES: dict[str, int] = {"xyzac-trt": 1, "xyzbc-trt": 2}
#: Format 1.4's other kinds (abbe.formats.chain_blob writes them): kind byte -> (name,
#: the axes of records 0 and 1). read_five_blob checks and decodes them; their geometry
#: is the chain's (abbe.formats.chain_blob.read_chain_blob), not a TrunnionGeometry.
CHAIN_KIND_AXES: dict[int, tuple[str, tuple[str, str]]] = {
    3: ("xyzbc-hh", ("C", "B")), 4: ("xyzbc-ht", ("B", "C")), 5: ("xyzab-tdr", ("B", "A"))}
MAX_HARMONICS = 8
#: Largest |rot_point| and |offset| component, nm (their sum stays an int32).
GEOMETRY_CAP_NM = (1 << 30) - 1
# Kind 3 (head-head): |offset|_1 + |rot_point + offset|_1 at most this, nm (the C loader's
# HH_LEVER_L1_CAP: the fixed-point evaluation's int32 head lever; docs/table-format.md).
HH_LEVER_L1_CAP_NM = (1 << 32) - 1024
_RH_FMT = "<B3s3i3i3i24s"
_RA_FMT = "<2i3iBB2sIII28s"
assert struct.calcsize(_RH_FMT) == 64 and struct.calcsize(_RA_FMT) == 64
_Q8_PER_UM = 256_000.0
_Q36_PER_URAD = 2.0 ** 36 * 1e-6
#: Linear travel of the (empty) linear axes of a table without linear errors, mm.
EMPTY_LINEAR_TRAVEL_MM = (-2000.0, 2000.0)


@dataclass
class FiveAxisTable:
    """A decoded five-axis table: kinematics kind, C axis centre and tilt offset (mm),
    and the errors (quantised to the table's integers)."""

    kind: str
    rot_point_mm: tuple[float, float, float]
    offset_mm: tuple[float, float, float]
    errors: FiveAxisErrors

    def geometry(self, tool_length_mm: float = 0.0,
                 travel_deg: dict[str, tuple[float, float]] | None = None) -> TrunnionGeometry:
        """The nominal geometry (the table holds no tool length or rotary travel: the
        evaluation needs neither)."""
        tilt, table = KINEMATICS[self.kind]
        trav = travel_deg or {tilt: (-180.0, 180.0), table: (-360.0, 360.0)}
        return TrunnionGeometry(self.kind, self.rot_point_mm, self.offset_mm, tool_length_mm, trav)


def _int32(x: float, where: str, unit: str) -> int:
    return _blob._to_int32(_blob._finite(x, where), where, unit)


def _motion_matrix(errs: FiveAxisErrors, axis: str) -> tuple[int, int, np.ndarray]:
    """(component mask, harmonics, (2H, n_comp) int64 matrix) of ``axis``' error motions."""
    present = [(i, c, np.asarray(errs.motions[(axis, c)], dtype=np.float64))
               for i, c in enumerate(MOTION_COMPONENTS)
               if (axis, c) in errs.motions and len(errs.motions[(axis, c)])]
    if not present:
        return 0, 0, np.zeros((0, 0), dtype=np.int64)
    h = max(len(v) // 2 for _, _, v in present)
    if h > MAX_HARMONICS or any(len(v) % 2 for _, _, v in present):
        raise TableError(f"{axis}: error motions need 1..{MAX_HARMONICS} harmonics (sin, cos pairs)",
                         status="ABBE_E_COUNT", field=f"rotary.{axis}.motions")
    mat = np.zeros((2 * h, len(present)), dtype=np.int64)
    mask = 0
    for col, (i, c, v) in enumerate(present):
        mask |= 1 << i
        scale = _Q8_PER_UM if i < 3 else _Q36_PER_URAD
        for r, x in enumerate(v):
            mat[r, col] = _int32(x * scale, f"rotary.{axis}.motions.{c}[{r}]",
                                 "2^-8 nm" if i < 3 else "2^-36 rad")
        cap = _blob.LIN_SUM_CAP if i < 3 else _blob.ANG_SUM_CAP
        if int(np.abs(mat[:, col]).sum()) > cap:
            raise TableError("sum of |coefficients| over the fixed-point cap", status="ABBE_E_RANGE",
                             field=f"rotary.{axis}.motions.{c}")
    return mask, h, mat


def _empty_linear(geom: TrunnionGeometry) -> Table:
    return Table(axes={a: AxisTable(travel_mm=EMPTY_LINEAR_TRAVEL_MM) for a in AXES},
                 reference_mm=tuple(float(v) for v in geom.rot_point_mm))  # type: ignore[arg-type]


def write_five_blob(geom: TrunnionGeometry, errs: FiveAxisErrors) -> bytes:
    """Serialise a five-axis model to a format 1.2 table. Values round to the nearest
    integer of their encoding; TableError if one cannot be represented."""
    if geom.kind not in KIND_CODES:
        raise TableError(f"kinematics {geom.kind!r} is not one of {sorted(KIND_CODES)}",
                         status="ABBE_E_FLAGS", field="rotary.kind")
    ti = _blob._encode(errs.linear if errs.linear is not None else _empty_linear(geom))
    ti.features |= _blob.FEATURE_ROTARY
    tilt = geom.tilt
    rp = [_int32(v * 1e6, f"rotary.rot_point_mm[{i}]", "nm") for i, v in enumerate(geom.rot_point_mm)]
    off = [_int32(v * 1e6, f"rotary.offset_mm[{i}]", "nm") for i, v in enumerate(geom.offset_mm)]
    if off["ABC".index(tilt)] != 0:
        raise TableError(f"the {tilt} axis offset has no component along {tilt}",
                         status="ABBE_E_FLAGS", field="rotary.offset_mm")
    if max(abs(v) for v in rp + off) > GEOMETRY_CAP_NM:
        raise TableError("rotation point / offset beyond 1073 mm", status="ABBE_E_RANGE",
                         field="rotary.geometry")
    sq = [_int32(v * _Q36_PER_URAD, f"rotary.squareness_urad[{i}]", "2^-36 rad")
          for i, v in enumerate(errs.squareness)]
    records, arrays = [], []
    for axis in geom.rotaries:
        names = LOCATION_ERRORS[axis]
        loc = [float(errs.location.get(n, 0.0)) for n in names]
        lin = [_int32(v * _Q8_PER_UM, f"rotary.{axis}.{n}", "2^-8 nm") for v, n in zip(loc[:2], names)]
        ang = [_int32(v * _Q36_PER_URAD, f"rotary.{axis}.{n}", "2^-36 rad")
               for v, n in zip(loc[2:], names[2:])]
        if max(abs(v) for v in sq + ang) > _blob.SQUARENESS_CAP:
            raise TableError("an angle beyond 2^28 x 2^-36 rad (3906 urad)", status="ABBE_E_RANGE",
                             field=f"rotary.{axis}")
        mask, h, mat = _motion_matrix(errs, axis)
        records.append((lin, ang, mask, h))
        arrays.append(mat.reshape(-1))

    def section(offsets: list[tuple[int, int]]) -> bytes:
        out = bytearray(struct.pack(_RH_FMT, KIND_CODES[geom.kind], b"", *rp, *off, *sq, b""))
        for (lin, ang, mask, h), (qo, fo), arr in zip(records, offsets, arrays):
            out += struct.pack(_RA_FMT, *lin, *ang, mask, h, b"", qo, fo, arr.size, b"")
        return bytes(out)

    return _blob._write(ti, _blob.ROTARY_MINOR, _blob.ROTARY_DATA_START, section, arrays)


def read_five_blob(data: bytes, source: str = "<blob>") -> FiveAxisTable:
    """Validate a format 1.2 or 1.4 five-axis table (every check of ``abbe_five_model_load``,
    in its order) and decode it. TableError with the C status name otherwise; a 3-axis
    table is refused here (ABBE_E_FLAGS: no rotary section)."""
    ti = _blob._read_ints(data, source, rotary=True)

    def err(status: str, msg: str, fld: str) -> TableError:
        return TableError(msg, status=status, file=source, field=fld)

    if not ti.features & _blob.FEATURE_ROTARY:
        raise err("ABBE_E_FLAGS", "a 3-axis table: no rotary section (feature ROTARY off)",
                  "features")
    data = bytes(data)
    total = struct.unpack_from("<I", data, 8)[0]
    (kind, res0, *rest) = struct.unpack_from(_RH_FMT, data, _blob.COEF_START)
    rp, off, sq, res1 = rest[0:3], rest[3:6], rest[6:9], rest[9]
    recs = [struct.unpack_from(_RA_FMT, data, _blob.COEF_START + 64 + 64 * r) for r in range(2)]
    # FLAGS
    codes = {v: k for k, v in KIND_CODES.items()}
    minor = struct.unpack_from("<H", data, 6)[0]
    chain = kind in CHAIN_KIND_AXES and minor >= _blob.CHAIN_MINOR
    if kind not in codes and not chain:
        raise err("ABBE_E_FLAGS", f"kinematics kind {kind} is not 1 (xyzac-trt) or 2 (xyzbc-trt)"
                  + (", or 3-5 (format 1.4)" if minor >= _blob.CHAIN_MINOR else ""), "rotary.kind")
    if any(res0) or any(res1[12 if chain else 0:]):
        raise err("ABBE_E_FLAGS", "reserved rotary header bytes are not 0", "rotary.reserved")
    if not chain and off[kind - 1] != 0:
        raise err("ABBE_E_FLAGS", "the offset has a component along the tilt axis", "rotary.offset_nm")
    kname, axes = CHAIN_KIND_AXES[kind] if chain else (codes[kind], KINEMATICS[codes[kind]])
    for axis, r in zip(axes, recs):
        if r[7][0] > (1 if chain else 0) or r[7][1] or any(r[11]):
            raise err("ABBE_E_FLAGS", "reserved rotary axis bytes are not 0 (kinds 3-5: the direction "
                      "byte 0 or 1)", f"rotary.{axis}.reserved")
    # COUNT
    for axis, r in zip(axes, recs):
        mask, h, count = r[5], r[6], r[10]
        if mask & 0xC0 or h > MAX_HARMONICS or count != 2 * h * bin(mask).count("1"):
            raise err("ABBE_E_COUNT", f"comp_mask 0x{mask:02X}, harmonics {h}, coef_count {count}: "
                      "count must be 2 x harmonics x components, harmonics <= 8", f"rotary.{axis}")
    # OFFSET
    start = _blob.ROTARY_DATA_START
    for axis, r in zip(axes, recs):
        count = r[10]
        for o, name in ((r[8], "coef_q_offset"), (r[9], "coef_f32_offset")):
            if count == 0 and o != 0 or count and (o < start or o % 4 or o + 4 * count > total - 4):
                raise err("ABBE_E_OFFSET", f"{name} {o} (+{4 * count} bytes) not a 4-aligned range "
                          f"inside [{start}, {total - 4})", f"rotary.{axis}.{name}")
    # NONFINITE, MISMATCH
    for axis, r in zip(axes, recs):
        if r[10] and not np.all(np.isfinite(np.frombuffer(data, "<f4", r[10], r[9]))):
            raise err("ABBE_E_NONFINITE", "float32 coefficient is NaN or infinite", f"rotary.{axis}.coef_f32")
    for axis, r in zip(axes, recs):
        if r[10]:
            q = np.frombuffer(data, "<i4", r[10], r[8])
            if np.any(q.astype(np.float32).view("<u4") != np.frombuffer(data, "<u4", r[10], r[9])):
                raise err("ABBE_E_MISMATCH", "a float32 coefficient is not its int32 value converted",
                          f"rotary.{axis}.coef_f32")
    # RANGE
    ref = struct.unpack_from("<3i", res1, 0)
    if max(abs(v) for v in (*rp, *off)) > GEOMETRY_CAP_NM or max(abs(v) for v in sq) > _blob.SQUARENESS_CAP \
            or (chain and max(abs(v) for v in ref) > GEOMETRY_CAP_NM):
        raise err("ABBE_E_RANGE", "rotation point / offset beyond 2^30 - 1 nm or squareness beyond 2^28",
                  "rotary.geometry")
    # kind 3 (head-head): the fixed-point evaluation's int32 head lever (docs/table-format.md)
    if chain and kind == 3 and sum(abs(o) + abs(r + o) for r, o in zip(rp, off)) > HH_LEVER_L1_CAP_NM:
        raise err("ABBE_E_RANGE", "head-head: |offset|_1 + |rot_point + offset|_1 beyond 2^32 - 2^10 nm "
                  "(4294 mm), the fixed-point lever's range", "rotary.geometry")
    errs = FiveAxisErrors(squareness=tuple(v / _Q36_PER_URAD for v in sq))  # type: ignore[arg-type]
    for axis, r in zip(axes, recs):
        lin, ang, mask, h, count = r[0:2], r[2:5], r[5], r[6], r[10]
        if max(abs(v) for v in ang) > _blob.SQUARENESS_CAP:
            raise err("ABBE_E_RANGE", "a location angle beyond 2^28 x 2^-36 rad", f"rotary.{axis}")
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
                cap = _blob.LIN_SUM_CAP if i < 3 else _blob.ANG_SUM_CAP
                if int(np.abs(mat[:, col]).sum()) > cap:
                    raise err("ABBE_E_RANGE", "sum of |coefficients| over the fixed-point cap",
                              f"rotary.{axis}.motions.{c}")
                errs.motions[(axis, c)] = mat[:, col] / (_Q8_PER_UM if i < 3 else _Q36_PER_URAD)
                col += 1
    errs.linear = _blob._decode(ti)
    return FiveAxisTable(kname, tuple(v * 1e-6 for v in rp), tuple(v * 1e-6 for v in off),  # type: ignore[arg-type]
                         errs)


def five_reference(table: FiveAxisTable, pos_mm: Any, angles_deg: Any) -> tuple[np.ndarray, np.ndarray]:
    """The float64 reference of the C evaluation: the linearised tool tip error
    (:func:`abbe.model.five_axis.tool_error_linear`) of the table's own (quantised)
    values: position um, orientation urad, (N, 3) each."""
    return tool_error_linear(table.geometry(), table.errors, pos_mm, angles_deg)


def is_five_axis_blob(data: bytes) -> bool:
    """True when ``data`` announces a rotary section (format 1.2 and feature bit ROTARY):
    the readers that take any table (``abbe table``, generated C) then read it with
    :func:`read_five_blob`. Anything shorter than a header is left to the 3-axis reader's
    checks (which name what is wrong)."""
    data = bytes(data[:24])
    if len(data) < 24:
        return False
    minor = struct.unpack_from("<H", data, 6)[0]
    features = struct.unpack_from("<I", data, 20)[0]
    return minor >= _blob.ROTARY_MINOR and bool(features & _blob.FEATURE_ROTARY)


def record_axes(kind: str) -> tuple[str, str]:
    """The rotary axes of records 0 and 1 of a table of kinematics ``kind`` (a trunnion:
    tilt, C; format 1.4's kinds: CHAIN_KIND_AXES)."""
    for name, axes in CHAIN_KIND_AXES.values():
        if name == kind:
            return axes
    return KINEMATICS[kind]


def five_table_lines(table: FiveAxisTable) -> list[str]:
    """Human-readable lines of the rotary section (``abbe table info``, generated C):
    geometry, squareness, each axis' location errors and error motions (um, urad)."""
    e = table.errors
    a0, a1 = record_axes(table.kind)
    lines = [f"kinematics: {table.kind} (tilt {a0}, table {a1})" if table.kind in KIND_CODES
             else f"kinematics: {table.kind} (record 0 {a0}, record 1 {a1}; rot_point and offset as "
                  "docs/table-format.md 'Other kinematic kinds' defines them for this kind)",
             "rot_point_mm: " + ", ".join(f"{v:.6f}" for v in table.rot_point_mm),
             "offset_mm: " + ", ".join(f"{v:.6f}" for v in table.offset_mm),
             "five-axis squareness_urad: S_xy %.6f, S_xz %.6f, S_yz %.6f" % tuple(e.squareness)]
    for axis in record_axes(table.kind):
        names = LOCATION_ERRORS[axis]
        lines.append(f"axis {axis} location: " + ", ".join(
            f"{n} {e.location.get(n, 0.0):.6f} {'um' if i < 2 else 'urad'}"
            for i, n in enumerate(names)))
        mot = [(c, v) for c in MOTION_COMPONENTS if len(v := e.motions.get((axis, c), [])) > 0]
        if not mot:
            lines.append(f"axis {axis} error motions: none")
        for c, v in mot:
            unit = "um" if c in "XYZ" else "urad"
            lines.append(f"axis {axis} motion E{c}{axis}({axis}) {unit}: " + ", ".join(
                f"{'sin' if r % 2 == 0 else 'cos'}{r // 2 + 1} {float(x):.6f}"
                for r, x in enumerate(v)))
    return lines


def five_table_to_json(table: FiveAxisTable) -> dict[str, Any]:
    """The rotary section as plain data (``abbe table to-json`` of a format 1.2 table),
    beside the linear axes' table JSON (:func:`abbe.formats.table_json.table_to_json`
    of ``table.errors.linear``, the caller's). Units: mm, um, urad."""
    e = table.errors
    return {
        "kinematics": table.kind,
        "rot_point_mm": [float(v) for v in table.rot_point_mm],
        "offset_mm": [float(v) for v in table.offset_mm],
        "squareness_urad": dict(zip(("sxy", "sxz", "syz"), (float(v) for v in e.squareness))),
        "axes": {axis: {
            "location": {n: float(e.location.get(n, 0.0)) for n in LOCATION_ERRORS[axis]},
            "location_units": {n: ("um" if i < 2 else "urad")
                               for i, n in enumerate(LOCATION_ERRORS[axis])},
            "motions": {f"E{c}{axis}({axis})": {
                "unit": "um" if c in "XYZ" else "urad", "period_deg": 360.0,
                "coef": {f"{'sin' if r % 2 == 0 else 'cos'}{r // 2 + 1}": float(x)
                         for r, x in enumerate(e.motions[(axis, c)])}}
                for c in MOTION_COMPONENTS if len(e.motions.get((axis, c), [])) > 0},
        } for axis in record_axes(table.kind)},
    }
