"""Format 1.4 five-axis tables (kinds 3-5): the writer, the C loader's checks, and the C
evaluation against the chain model's linearisation (abbe.model.chain.tool_error_linear)
on the three LinuxCNC sample chains of cases/five_axis_chains."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from abbe.formats.chain_blob import chain_kind, read_chain_blob, write_chain_blob
from abbe.formats.five_axis_blob import read_five_blob
from abbe.formats.machine import load_machine
from abbe.model.chain import tool_error_linear
from abbe.model.clib import CFiveModel
from abbe.model.examples import paper_table
from abbe.model.five_axis import LOCATION_ERRORS, MOTION_COMPONENTS, FiveAxisErrors
from abbe.model.table import TableError

CHAINS = Path(__file__).resolve().parents[2] / "cases" / "five_axis_chains"
SAMPLES = {"head-head-5axiskins": 3, "head-table-maxkins": 4, "table-dual-rotary-xyzab": 5}


def _chain(stem: str):  # type: ignore[no-untyped-def]
    return load_machine(CHAINS / f"{stem}.toml").extra["chain"]


def _errors(chain, seed: int) -> FiveAxisErrors:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(seed)
    e = FiveAxisErrors()
    for ax in chain.rotaries:
        for n in LOCATION_ERRORS[ax]:
            e.location[n] = float(rng.normal(0.0, 30.0))
        for c in MOTION_COMPONENTS:
            e.motions[(ax, c)] = rng.normal(0.0, 3.0, 6)
    e.squareness = (10.0, -5.0, 7.0)
    e.linear = paper_table()
    return e


def _refresh_crc(b: bytearray) -> bytes:
    total = struct.unpack_from("<I", b, 8)[0]
    struct.pack_into("<I", b, total - 4, zlib.crc32(bytes(b[:total - 4])) & 0xFFFFFFFF)
    return bytes(b)


@pytest.mark.parametrize("stem", sorted(SAMPLES))
def test_c_evaluation_matches_chain_model(stem: str) -> None:
    ch = _chain(stem)
    e = _errors(ch, 39)
    b = write_chain_blob(ch, e)
    assert chain_kind(ch) == SAMPLES[stem]
    ch2, e2 = read_chain_blob(b)
    rng = np.random.default_rng(7)
    pos = rng.uniform(-400.0, 400.0, (150, 3))
    ang = rng.uniform(-100.0, 100.0, (150, 2))
    ref_p, ref_w = tool_error_linear(ch2, e2, pos, ang)
    # the decoded (quantised) chain is the written one within the encodings' steps
    orig_p, _ = tool_error_linear(ch, e, pos, ang)
    assert np.abs(orig_p - ref_p).max() < 1e-3
    m = CFiveModel(b)
    assert m.kind == SAMPLES[stem]
    assert read_five_blob(b).kind == {3: "xyzbc-hh", 4: "xyzbc-ht", 5: "xyzab-tdr"}[SAMPLES[stem]]
    got_p, got_w, flags = m.error_f32(pos, ang)
    assert np.abs(ref_p).max() > 20.0  # the errors are not negligible
    assert np.abs(got_p - ref_p).max() < 2e-3  # um (docs/numerics.md's five-axis bound)
    assert np.abs(got_w - ref_w).max() < 1e-3  # urad


def _blob(stem: str = "head-table-maxkins") -> bytearray:
    ch = _chain(stem)
    return bytearray(write_chain_blob(ch, _errors(ch, 1)))


def _status(b: bytes) -> str:
    """The C loader's status, checked to be the Python reader's too."""
    with pytest.raises(TableError) as ex:
        CFiveModel(b)
    with pytest.raises(TableError) as py:
        read_five_blob(b)
    assert py.value.status == ex.value.status
    return str(ex.value.status)


def test_older_minor_refuses_the_new_kinds() -> None:
    b = _blob()
    struct.pack_into("<H", b, 6, 2)
    assert _status(_refresh_crc(b)) == "ABBE_E_FLAGS"
    b = _blob()
    struct.pack_into("<H", b, 6, 3)  # 1.3 is the thermal block's: never a five-axis minor
    assert _status(_refresh_crc(b)) == "ABBE_E_VERSION_MINOR"
    b = _blob()
    struct.pack_into("<H", b, 6, 5)
    assert _status(_refresh_crc(b)) == "ABBE_E_VERSION_MINOR"


@pytest.mark.parametrize("where,value,status", [
    (256, 6, "ABBE_E_FLAGS"),                    # kind 6
    (256 + 64 + 22, 2, "ABBE_E_FLAGS"),          # direction byte not 0 / 1
    (256 + 64 + 23, 1, "ABBE_E_FLAGS"),          # the byte after it is reserved
    (256 + 52, 1, "ABBE_E_FLAGS"),               # reserved after the squareness reference
])
def test_loader_refuses_bad_bytes(where: int, value: int, status: str) -> None:
    b = _blob()
    b[where] = value
    assert _status(_refresh_crc(b)) == status


def test_squareness_reference_range_and_trunnion_reserved() -> None:
    b = _blob()
    struct.pack_into("<i", b, 256 + 40, 1 << 30)  # beyond 1073.7 mm
    assert _status(_refresh_crc(b)) == "ABBE_E_RANGE"
    b = _blob()
    b[256] = 2  # a trunnion kind keeps its reserved bytes, direction bytes included
    assert _status(_refresh_crc(b)) == "ABBE_E_FLAGS"


def test_direction_byte_changes_the_result() -> None:
    """maxkins' B turns about -Y: the byte is read (flipping it moves the tool error)."""
    ch = _chain("head-table-maxkins")
    b = bytearray(write_chain_blob(ch, _errors(ch, 3)))
    assert b[256 + 64 + 22] == 1  # record 0 = B, direction -Y
    pos, ang = np.array([[100.0, 50.0, -30.0]]), np.array([[40.0, 30.0]])
    p1, _, _ = CFiveModel(bytes(b)).error_f32(pos, ang)
    b[256 + 64 + 22] = 0
    p2, _, _ = CFiveModel(_refresh_crc(b)).error_f32(pos, ang)
    assert np.abs(p1 - p2).max() > 1.0


def test_writer_refuses_a_trunnion_chain() -> None:
    from abbe.model.chain import trunnion_chain
    from abbe.model.five_axis import TrunnionGeometry
    g = TrunnionGeometry("xyzac-trt", (0.0, 0.0, 0.0), (0.0, 0.0, 10.0), 0.0,
                         {"A": (-90.0, 90.0), "C": (-360.0, 360.0)})
    with pytest.raises(TableError):
        write_chain_blob(trunnion_chain(g), FiveAxisErrors())


@pytest.mark.parametrize("z_extra,status", [(0, None), (1, "ABBE_E_RANGE")])
def test_head_head_lever_range(z_extra: int, status: str | None) -> None:
    """Kind 3: |offset|_1 + |rot_point + offset|_1 <= 2^32 - 2^10 nm (the fixed-point head
    lever's int32 range), refused by the C loader and the Python reader alike, one nm over."""
    b = _blob("head-head-5axiskins")
    z = (1 << 32) - 1024 - 4_000_000_000 + z_extra
    struct.pack_into("<3i", b, 256 + 4, 1_000_000_000, 1_000_000_000, z)  # rot_point, nm
    struct.pack_into("<3i", b, 256 + 16, 1_000_000_000, 0, 0)  # offset, nm
    blob = _refresh_crc(b)
    if status is None:
        assert CFiveModel(blob).kind == 3
        assert read_five_blob(blob).kind == "xyzbc-hh"
    else:
        assert _status(blob) == status
