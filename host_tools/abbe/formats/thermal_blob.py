"""The table's thermal block (format 1.3): write it from a ThermalModel, read it back.

A table of format 1.3 is a 1.0 / 1.1 table (3-axis) that carries, before its CRC, a
thermal block: the dynamic thermal model of :mod:`abbe.model.thermal` in integers
(docs/table-format.md, "Thermal block"). It sets header feature bit 6 THERMAL_DYN and
version_minor 3, and the header's reserved word holds the block's offset. Readers of
1.0 - 1.2 (and the C library's ``abbe_model_load``) refuse it with
``ABBE_E_VERSION_MINOR``; ``abbe_thermal_load`` (C) and :func:`read_thermal_blob` read
it, with the same checks in the same order and the same status names.

Integers: input values in milli-units (m degC; rpm, i.e. milli-krpm), time constants and
times in ms, gains in 2^-16 um per unit (um/K, um/krpm; urad/... for tilts), channel
limits in nm (nrad). The block holds no names: the reader names inputs ``in0`` ..,
channels by their output.
"""

from __future__ import annotations

import struct
import zlib

from abbe.formats import blob as _blob
from abbe.model.table import Table, TableError
from abbe.model.thermal import (
    MAX_CHANNELS,
    MAX_INPUTS,
    MAX_TERMS_PER_CHANNEL,
    OUTPUTS,
    SPEED,
    TEMPERATURE,
    ThermalChannel,
    ThermalInput,
    ThermalModel,
    ThermalTerm,
)

THERMAL_MINOR = _blob.THERMAL_MINOR
FEATURE_THERMAL_DYN = _blob.FEATURE_THERMAL_DYN
KINDS = (TEMPERATURE, SPEED)  # kind byte 0, 1
HEADER_SIZE, INPUT_SIZE, CHANNEL_SIZE, TERM_SIZE = 16, 20, 56, 12
VALUE_CAP = 1 << 20    # |reference|, |valid_min|, |valid_max|, milli-units
STEP_CAP = 1 << 21     # max_step, milli-units
LIMIT_CAP = 1 << 30    # channel limit, nm / nrad
GAIN_CAP = 1 << 28     # |gain|, 2^-16 um per unit
TIME_CAP = 1 << 31     # tau, max_gap, fade, ms
_H_FEATURES, _H_MINOR, _H_RESERVED, _H_TOTAL = 20, 6, 60, 8


def block_size(n_inputs: int, n_channels: int) -> int:
    """Bytes of a thermal block with that many inputs and channels."""
    return HEADER_SIZE + INPUT_SIZE * n_inputs + CHANNEL_SIZE * n_channels


def _milli(kind: str, value: float) -> int:
    return int(round(value if kind == SPEED else value * 1000.0))


def encode_block(model: ThermalModel) -> bytes:
    """The thermal block of ``model`` (validated first; TableError with the status the
    C reader would give if a value does not fit the block's integer ranges)."""
    model.validate()

    def err(msg: str, fld: str) -> TableError:
        return TableError(msg, status="ABBE_E_RANGE", field=fld)

    gap, fade = int(round(model.max_gap_s * 1000)), int(round(model.fade_s * 1000))
    if not (1 <= gap <= TIME_CAP and 1 <= fade <= TIME_CAP):
        raise err(f"max_gap {gap} ms / fade {fade} ms: expected 1 .. 2^31 ms", "thermal")
    out = bytearray(struct.pack("<BBHIII", len(model.inputs), len(model.channels), 0, gap, fade, 0))
    for k, inp in enumerate(model.inputs):
        vals = [_milli(inp.kind, v) for v in (inp.reference, inp.valid_min, inp.valid_max, inp.max_step)]
        if any(abs(v) > VALUE_CAP for v in vals[:3]) or vals[1] >= vals[2] or not 1 <= vals[3] <= STEP_CAP:
            raise err(f"reference / valid range / max_step {vals} (milli-units) outside the block's "
                      f"ranges (|v| <= 2^20, min < max, 1 <= step <= 2^21)", f"thermal.inputs[{k}]")
        stuck_min = int(round(inp.stuck_s / 60.0))
        stuck_res = _milli(inp.kind, inp.stuck_resolution) if stuck_min else 0
        if not (0 <= stuck_min <= 255 and 0 <= stuck_res <= 0xFFFF):
            raise err(f"stuck {stuck_min} min / resolution {stuck_res} milli-units: expected "
                      "0..255, 0..65535", f"thermal.inputs[{k}]")
        out += struct.pack("<BBHiiii", KINDS.index(inp.kind), stuck_min, stuck_res, *vals)
    for j, ch in enumerate(model.channels):
        limit = int(round(ch.limit * 1000))
        if not 1 <= limit <= LIMIT_CAP:
            raise err(f"limit {limit} nm: expected 1 .. 2^30", f"thermal.channels[{j}].limit")
        rec = bytearray(struct.pack("<BBHi", OUTPUTS.index(ch.output), len(ch.terms), 0, limit))
        for n, t in enumerate(ch.terms):
            tau, gain = int(round(t.tau_s * 1000)), int(round(t.gain * 65536))
            if tau > TIME_CAP or abs(gain) > GAIN_CAP:
                raise err(f"tau {tau} ms / gain {gain} (2^-16): over 2^31 / 2^28",
                          f"thermal.channels[{j}].terms[{n}]")
            rec += struct.pack("<B3xIi", t.input, tau, gain)
        rec += bytes(TERM_SIZE * (MAX_TERMS_PER_CHANNEL - len(ch.terms)))
        out += rec
    assert len(out) == block_size(len(model.inputs), len(model.channels))
    return bytes(out)


def _base_minor(features: int) -> int:
    return 1 if features & _blob.FEATURE_REVERSAL else 0


def write_thermal_blob(table_blob: bytes, model: ThermalModel) -> bytes:
    """``table_blob`` (a valid 3-axis table, format 1.0, 1.1 or 1.3) with ``model`` as its
    thermal block (replacing one it had): a format 1.3 table."""
    data = bytes(table_blob)
    base = read_thermal_blob(data)[0]  # validates (any minor this module reads)
    del base
    total = struct.unpack_from("<I", data, _H_TOTAL)[0]
    features = struct.unpack_from("<I", data, _H_FEATURES)[0]
    end = total - 4
    if features & FEATURE_THERMAL_DYN:
        end = struct.unpack_from("<I", data, _H_RESERVED)[0]  # the old block was appended last
    block = encode_block(model)
    out = bytearray(data[:end]) + block
    struct.pack_into("<I", out, _H_TOTAL, len(out) + 4)
    struct.pack_into("<H", out, _H_MINOR, THERMAL_MINOR)
    struct.pack_into("<I", out, _H_FEATURES, features | FEATURE_THERMAL_DYN)
    struct.pack_into("<I", out, _H_RESERVED, end)
    out += struct.pack("<I", zlib.crc32(bytes(out)) & 0xFFFFFFFF)
    return bytes(out)


def strip_thermal_blob(data: bytes) -> bytes:
    """The table without its thermal block, at the minor it then needs (1.0 / 1.1)."""
    read_thermal_blob(data)
    features = struct.unpack_from("<I", data, _H_FEATURES)[0]
    if not features & FEATURE_THERMAL_DYN:
        return bytes(data[:struct.unpack_from("<I", data, _H_TOTAL)[0]])
    end = struct.unpack_from("<I", data, _H_RESERVED)[0]
    out = bytearray(data[:end])
    struct.pack_into("<I", out, _H_TOTAL, end + 4)
    struct.pack_into("<H", out, _H_MINOR, _base_minor(features))
    struct.pack_into("<I", out, _H_FEATURES, features & ~FEATURE_THERMAL_DYN)
    struct.pack_into("<I", out, _H_RESERVED, 0)
    out += struct.pack("<I", zlib.crc32(bytes(out)) & 0xFFFFFFFF)
    return bytes(out)


def read_thermal_blob(data: bytes, source: str = "<blob>") -> tuple[Table, ThermalModel | None]:
    """Validate a table of format 1.0, 1.1 or 1.3 (every check of
    :func:`abbe.formats.blob.read_blob`, then the thermal block's, in the C library's
    order) and decode it: the geometric table and the thermal model (None without a
    block). TableError with the C status name of the first failed check."""
    ti = _blob._read_ints(data, source, thermal=True)
    table = _blob._decode(ti)
    if not ti.features & FEATURE_THERMAL_DYN:
        return table, None
    return table, _read_block(bytes(data), source)


def _read_block(data: bytes, source: str) -> ThermalModel:
    def err(status: str, msg: str, fld: str) -> TableError:
        return TableError(msg, status=status, file=source, field=fld)

    total = struct.unpack_from("<I", data, _H_TOTAL)[0]
    off = struct.unpack_from("<I", data, _H_RESERVED)[0]
    end = total - 4
    # OFFSET (its header)
    if off % 4 or off < _blob.COEF_START or off > end or end - off < HEADER_SIZE:
        raise err("ABBE_E_OFFSET", f"thermal block offset {off}: expected a 4-aligned offset in "
                  f"[{_blob.COEF_START}, {end - HEADER_SIZE}]", "thermal.offset")
    n_in, n_ch, res0, gap, fade, res1 = struct.unpack_from("<BBHIII", data, off)
    # COUNT (inputs, channels)
    if not (1 <= n_in <= MAX_INPUTS and 1 <= n_ch <= MAX_CHANNELS):
        raise err("ABBE_E_COUNT", f"{n_in} inputs, {n_ch} channels: expected 1..{MAX_INPUTS}, "
                  f"1..{MAX_CHANNELS}", "thermal.counts")
    # OFFSET (the whole block)
    if end - off < block_size(n_in, n_ch):
        raise err("ABBE_E_OFFSET", f"thermal block of {block_size(n_in, n_ch)} bytes at {off} "
                  f"overruns the table ({total} bytes)", "thermal.offset")
    # (kind, stuck minutes, stuck resolution milli-units, ref, min, max, step)
    inputs = [struct.unpack_from("<BBHiiii", data, off + HEADER_SIZE + INPUT_SIZE * k)
              for k in range(n_in)]
    ch_off = [off + HEADER_SIZE + INPUT_SIZE * n_in + CHANNEL_SIZE * j for j in range(n_ch)]
    chans = [struct.unpack_from("<BBHi", data, o) for o in ch_off]
    terms = [[struct.unpack_from("<B3BIi", data, o + 8 + TERM_SIZE * k)
              for k in range(MAX_TERMS_PER_CHANNEL)] for o in ch_off]
    # FLAGS
    if res0 or res1:
        raise err("ABBE_E_FLAGS", "reserved thermal header field is not 0", "thermal.reserved")
    for k, (kind, stuck_min, stuck_res, *_v) in enumerate(inputs):
        if kind > 1 or (stuck_min == 0 and stuck_res != 0):
            raise err("ABBE_E_FLAGS", f"kind {kind} (expected 0 temperature, 1 speed), or a stuck "
                      f"resolution ({stuck_res}) without a stuck time", f"thermal.inputs[{k}]")
    seen: set[int] = set()
    for j, ((out, n_t, res, _lim), tl) in enumerate(zip(chans, terms)):
        if out > 4 or out in seen or res:
            raise err("ABBE_E_FLAGS", f"output {out}: expected 0..4 (x y z a b), each once; "
                      "reserved bytes 0", f"thermal.channels[{j}]")
        seen.add(out)
        for k, (inp, r1, r2, r3, tau, gain) in enumerate(tl):
            if r1 or r2 or r3 or (k >= n_t and (inp or tau or gain)):
                raise err("ABBE_E_FLAGS", "reserved term bytes or an unused term slot not 0",
                          f"thermal.channels[{j}].terms[{k}]")
    # COUNT (terms, their inputs)
    for j, ((_o, n_t, _r, _l), tl) in enumerate(zip(chans, terms)):
        if not 1 <= n_t <= MAX_TERMS_PER_CHANNEL:
            raise err("ABBE_E_COUNT", f"{n_t} terms: expected 1..{MAX_TERMS_PER_CHANNEL}",
                      f"thermal.channels[{j}].n_terms")
        for k in range(n_t):
            if tl[k][0] >= n_in:
                raise err("ABBE_E_COUNT", f"term input {tl[k][0]} >= {n_in} inputs",
                          f"thermal.channels[{j}].terms[{k}]")
    # RANGE
    if not (1 <= gap <= TIME_CAP and 1 <= fade <= TIME_CAP):
        raise err("ABBE_E_RANGE", f"max_gap {gap} ms / fade {fade} ms: expected 1 .. 2^31",
                  "thermal.times")
    for k, (_kind, _m, _s, ref, lo, hi, step) in enumerate(inputs):
        if (abs(ref) > VALUE_CAP or abs(lo) > VALUE_CAP or abs(hi) > VALUE_CAP or lo >= hi
                or not 1 <= step <= STEP_CAP):
            raise err("ABBE_E_RANGE", "reference / valid range / max_step outside |v| <= 2^20, "
                      "min < max, 1 <= step <= 2^21", f"thermal.inputs[{k}]")
    for j, ((_o, n_t, _r, lim), tl) in enumerate(zip(chans, terms)):
        if not 1 <= lim <= LIMIT_CAP:
            raise err("ABBE_E_RANGE", f"limit {lim}: expected 1 .. 2^30", f"thermal.channels[{j}].limit")
        for k in range(n_t):
            if tl[k][4] > TIME_CAP or abs(tl[k][5]) > GAIN_CAP:
                raise err("ABBE_E_RANGE", "tau over 2^31 ms or |gain| over 2^28",
                          f"thermal.channels[{j}].terms[{k}]")

    def natural(kind: int, v: int) -> float:
        return float(v) if kind == 1 else v / 1000.0

    model_inputs = tuple(
        ThermalInput(name=f"in{k}", kind=KINDS[kind], reference=natural(kind, ref),
                     valid_min=natural(kind, lo), valid_max=natural(kind, hi),
                     max_step=natural(kind, step), stuck_s=60.0 * stuck_min,
                     stuck_resolution=natural(kind, stuck_res))
        for k, (kind, stuck_min, stuck_res, ref, lo, hi, step) in enumerate(inputs))
    channels = tuple(
        ThermalChannel(name=OUTPUTS[out], output=OUTPUTS[out], limit=lim / 1000.0,
                       terms=tuple(ThermalTerm(input=tl[k][0], tau_s=tl[k][4] / 1000.0,
                                               gain=tl[k][5] / 65536.0) for k in range(n_t)))
        for (out, n_t, _r, lim), tl in zip(chans, terms))
    return ThermalModel(inputs=model_inputs, channels=channels, max_gap_s=gap / 1000.0,
                        fade_s=fade / 1000.0)


def quantize_thermal(model: ThermalModel) -> ThermalModel:
    """``model`` as the table holds it (values rounded to the block's integers), with its
    names kept: what the C library evaluates."""
    q = _read_block_from(encode_block(model))
    return ThermalModel(
        inputs=tuple(ThermalInput(name=o.name, kind=i.kind, reference=i.reference,
                                  valid_min=i.valid_min, valid_max=i.valid_max,
                                  max_step=i.max_step, stuck_s=i.stuck_s,
                                  stuck_resolution=i.stuck_resolution)
                      for o, i in zip(model.inputs, q.inputs)),
        channels=tuple(ThermalChannel(name=o.name, output=c.output, terms=c.terms, limit=c.limit)
                       for o, c in zip(model.channels, q.channels)),
        max_gap_s=q.max_gap_s, fade_s=q.fade_s, notes=model.notes)


def _read_block_from(block: bytes) -> ThermalModel:
    """Decode a bare block (placed in a dummy frame so the offsets hold)."""
    pad = _blob.COEF_START
    data = bytearray(pad) + block + bytes(4)
    struct.pack_into("<I", data, _H_TOTAL, len(data))
    struct.pack_into("<I", data, _H_RESERVED, pad)
    return _read_block(bytes(data), "<block>")
