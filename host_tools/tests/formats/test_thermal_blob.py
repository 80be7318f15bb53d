"""The table's thermal block (format 1.3): writer and reader round trip, older readers
refuse it, the C loader (abbe_thermal_load) and the Python reader give the same status
for the same mutation, the committed golden files are what the generator writes."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from fuzz_budget import DERANDOMIZE, examples

from abbe.formats import golden, golden_thermal
from abbe.formats.blob import read_blob, write_blob
from abbe.formats.thermal_blob import (
    block_size,
    quantize_thermal,
    read_thermal_blob,
    strip_thermal_blob,
    write_thermal_blob,
)
from abbe.model import clib
from abbe.model.table import TableError
from abbe.model.thermal import ThermalChannel, ThermalInput, ThermalModel, ThermalTerm

REPO = Path(__file__).resolve().parents[3]


def _model() -> ThermalModel:
    return ThermalModel(
        inputs=(ThermalInput("t1", reference=20.5), ThermalInput("t2", reference=19.25),
                ThermalInput("spindle", kind="speed", reference=0.0, valid_min=0.0,
                             valid_max=15000.0, max_step=15000.0)),
        channels=(ThermalChannel("ch5", "z", (ThermalTerm(0, 1234.5678, 2.345678),
                                              ThermalTerm(2, 3600.0, -3.5))),
                  ThermalChannel("ch1", "a", (ThermalTerm(1, 0.0, 1.25),), limit=50.0)),
        max_gap_s=45.0, fade_s=20.0)


def test_round_trip_and_older_readers() -> None:
    base = write_blob(golden.backlash_table())
    blob = write_thermal_blob(base, _model())
    assert struct.unpack_from("<H", blob, 6)[0] == 3
    assert len(blob) == len(base) + block_size(3, 2)
    table, model = read_thermal_blob(blob)
    assert model is not None and model == quantize_thermal(_model()).__class__(
        inputs=model.inputs, channels=model.channels, max_gap_s=45.0, fade_s=20.0)
    q = quantize_thermal(_model())
    assert [i.name for i in q.inputs] == ["t1", "t2", "spindle"]
    assert q.channels[0].terms[0].tau_s == pytest.approx(1234.568, abs=1e-9)
    assert q.channels[0].terms[0].gain == round(2.345678 * 65536) / 65536
    assert [c.terms for c in model.channels] == [c.terms for c in q.channels]
    with pytest.raises(TableError) as e:
        read_blob(blob)
    assert e.value.status == "ABBE_E_VERSION_MINOR"
    assert strip_thermal_blob(blob) == base
    assert read_thermal_blob(base)[1] is None
    # replacing a block keeps one block
    again = write_thermal_blob(blob, _model())
    assert again == blob


def test_value_out_of_the_block_range_is_refused() -> None:
    bad = ThermalModel(inputs=(ThermalInput("t1"),),
                       channels=(ThermalChannel("c", "x", (ThermalTerm(0, 10.0, 5000.0),)),))
    with pytest.raises(TableError) as e:
        write_thermal_blob(write_blob(golden.backlash_table()), bad)
    assert e.value.status == "ABBE_E_RANGE"


def test_stuck_check_round_trip_and_refusals() -> None:
    """The stuck check (minutes, resolution) goes through the block and thermal.json; a
    block without it is byte for byte what it was; bad values are refused by field."""
    from abbe.errors import AbbeInputError
    from abbe.model.thermal import as_dict, from_dict
    m = _model()
    base = write_blob(golden.backlash_table())
    plain = write_thermal_blob(base, m)
    stuck = ThermalModel(inputs=(ThermalInput("t1", reference=20.5, stuck_s=600.0,
                                              stuck_resolution=0.02),) + m.inputs[1:],
                         channels=m.channels, max_gap_s=m.max_gap_s, fade_s=m.fade_s)
    blob = write_thermal_blob(base, stuck)
    off = struct.unpack_from("<I", blob, 60)[0] + 16
    assert blob[off + 1] == 10 and struct.unpack_from("<H", blob, off + 2)[0] == 20
    assert blob[:off] == plain[:off] and blob[off + 4:-4] == plain[off + 4:-4]
    _, back = read_thermal_blob(blob)
    assert back.inputs[0].stuck_s == 600.0 and back.inputs[0].stuck_resolution == 0.02
    assert back.inputs[1].stuck_s == 0.0 and back.inputs[1].stuck_resolution == 0.0
    assert quantize_thermal(stuck).inputs[0].stuck_s == 600.0
    assert from_dict(as_dict(stuck)) == stuck
    assert "stuck_s" not in as_dict(m)["inputs"][0]  # files without the check unchanged
    for bad in ((90.0, 0.02), (0.0, 0.02), (600.0, 66.0), (256 * 60.0, 0.0),
                (600.0, -0.01), (float("nan"), 0.0)):
        with pytest.raises(AbbeInputError) as e:
            ThermalModel(inputs=(ThermalInput("t1", stuck_s=bad[0], stuck_resolution=bad[1]),),
                         channels=(ThermalChannel("c", "x", (ThermalTerm(0, 0.0, 1.0),)),)
                         ).validate()
        assert e.value.field == "thermal.inputs[0] (t1)", bad


def test_golden_files_are_current(tmp_path: Path) -> None:
    golden_thermal.write(tmp_path)
    for name in ("golden_thermal.h", "golden_thermal.c"):
        assert (tmp_path / name).read_bytes() == (REPO / "tests/golden" / name).read_bytes(), name


needs_c = pytest.mark.skipif(not clib.available(), reason="C library not built")
_SEED_BLOB = golden_thermal.golden_blob_and_model()[0]
_OFF = struct.unpack_from("<I", _SEED_BLOB, 60)[0]
# fields aimed at: header minor/features/offset, the block's header, the first inputs,
# every channel's record
_FIELDS = [(6, 2), (20, 4), (60, 4)] + [(_OFF + o, s) for o, s in (
    (0, 1), (1, 1), (2, 2), (4, 4), (8, 4), (12, 4))] + [
    (_OFF + 16 + 20 * k + o, s) for k in (0, 5, 16) for o, s in ((0, 1), (1, 1), (2, 2), (4, 4), (8, 4), (12, 4), (16, 4))
] + [(_OFF + 16 + 340 + 56 * c + o, s) for c in range(5) for o, s in (
    (0, 1), (1, 1), (2, 2), (4, 4), (8, 1), (9, 1), (12, 4), (16, 4), (44, 1), (48, 4), (52, 4))]


def _status_py(blob: bytes) -> str:
    try:
        read_thermal_blob(blob)
    except TableError as exc:
        return str(exc.status)
    return "ABBE_OK"


@needs_c
@settings(max_examples=examples(400), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.integers(0, len(_FIELDS) - 1), st.integers(0, 2**32 - 1)),
                min_size=1, max_size=3))
def test_c_and_python_give_the_same_status(muts: list[tuple[int, int]]) -> None:
    b = bytearray(_SEED_BLOB)
    for f, v in muts:
        off, size = _FIELDS[f]
        small = (0, 1, 2, 3, 4, 5, 16, 17, 18, 255)[v % 10] if v % 3 == 0 else v
        b[off:off + size] = (small & ((1 << (8 * size)) - 1)).to_bytes(size, "little")
    total = struct.unpack_from("<I", b, 8)[0]
    if 260 <= total <= len(b) and total % 4 == 0:
        struct.pack_into("<I", b, total - 4, zlib.crc32(bytes(b[:total - 4])))
    assert clib.thermal_load_status(bytes(b)) == _status_py(bytes(b))


@needs_c
def test_every_status_reached_by_the_differential() -> None:
    """The mutations above reach the thermal checks (not only the CRC)."""
    rng = np.random.default_rng(7)
    seen = set()
    for _ in range(1500):
        b = bytearray(_SEED_BLOB)
        off, size = _FIELDS[int(rng.integers(len(_FIELDS)))]
        v = int(rng.choice([0, 1, 2, 5, 17, 18, 255, 2**31 + 1, int(rng.integers(2**32))]))
        b[off:off + size] = (v & ((1 << (8 * size)) - 1)).to_bytes(size, "little")
        total = struct.unpack_from("<I", b, 8)[0]
        if 260 <= total <= len(b) and total % 4 == 0:
            struct.pack_into("<I", b, total - 4, zlib.crc32(bytes(b[:total - 4])))
        s = _status_py(bytes(b))
        assert clib.thermal_load_status(bytes(b)) == s
        seen.add(s)
    assert {"ABBE_OK", "ABBE_E_FLAGS", "ABBE_E_COUNT", "ABBE_E_OFFSET", "ABBE_E_RANGE",
            "ABBE_E_VERSION_MINOR"} <= seen, seen
