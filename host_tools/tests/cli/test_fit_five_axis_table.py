"""``abbe fit`` on a five-axis machine file writes model_five.bin (format 1.2) beside
five_axis.json: the identified values and, of the ones the plan cannot observe alone, the
fit's convention (the fixed set as 0, the others as determined in it, issue 33), readable by the
Python reader and by the C library, which evaluates it as the Python reference does."""

from __future__ import annotations

import ctypes as C
import json
import zlib
from pathlib import Path

import numpy as np
import pytest

from abbe.cli.entry import main
from abbe.formats.five_axis_blob import five_reference, read_five_blob
from abbe.model import clib

REPO = Path(__file__).resolve().parents[3]
EXAMPLE = REPO / "examples" / "trunnion5ax"


def _machine() -> Path:
    files = sorted(p for p in EXAMPLE.glob("*.toml") if "[rotary]" in p.read_text(encoding="utf-8"))
    assert files, "examples/trunnion5ax has no machine file with a [rotary] section"
    return files[0]


@pytest.fixture(scope="module")
def fitted(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("fit") / "out"
    assert main(["fit", str(_machine()), "-o", str(out), "--no-report", "--quiet"]) == 0
    return out


def test_table_holds_the_identified_values(fitted: Path) -> None:
    doc = json.loads((fitted / "five_axis.json").read_text())
    blob = (fitted / "model_five.bin").read_bytes()
    entry = doc["blob"]
    assert entry["file"] == "model_five.bin" and entry["format"] == "1.2" and entry["bytes"] == len(blob)
    assert entry["crc32"] == f"0x{zlib.crc32(blob[:-4]):08X}"
    table = read_five_blob(blob)
    assert table.kind == doc["kinematics"]
    zero = set(entry["written_as_zero_not_observable"])
    checked = in_convention = 0
    for p in doc["parameters"]:
        if p["kind"] != "location":
            continue
        got = table.errors.location[p["name"]]
        if p["observable"]:
            # quantisation: 2^-8 nm / 2^-36 rad; the table's value is the fit's moved by the
            # prior on what the plan sees only in the convention, within its interval
            assert got == pytest.approx(p["value_in_table"], abs=1e-5), p["name"]
            assert abs(p["value_in_table"] - p["value"]) <= p["ci95"], p["name"]
            checked += 1
        elif p["fixed_by_convention"]:
            assert p["name"] in zero and got == 0.0
        else:  # determined in the convention: held, with its value stated in the JSON
            assert p["name"] not in zero, p["name"]
            assert entry["convention"]["determined_in_convention"][p["name"]] == pytest.approx(
                p["value_in_convention"])
            assert got == pytest.approx(p["value_in_convention"], abs=1e-5), p["name"]
            in_convention += 1
    assert checked >= 4
    # the example's A/C plan: EA0A and EC0C fixed, the C line's place relative to A held
    assert {"EA0A", "EC0C"} <= zero and in_convention >= 1


@pytest.mark.skipif(not clib.available(), reason="C library not built")
def test_c_library_evaluates_the_table(fitted: Path) -> None:
    blob = (fitted / "model_five.bin").read_bytes()
    table = read_five_blob(blob)
    lib = clib.load_library()
    lib.abbe_five_model_load.argtypes = [C.c_void_p, C.c_void_p, C.c_size_t]
    buf = C.create_string_buffer(blob, len(blob))
    model = C.create_string_buffer(1 << 15)
    assert lib.abbe_five_model_load(model, buf, len(blob)) == 0

    class In(C.Structure):
        _fields_ = [("pos", C.c_int32 * 3), ("ang", C.c_int32 * 2), ("dir", C.c_int32 * 3), ("temp", C.c_int32 * 3)]

    class Out(C.Structure):
        _fields_ = [("err", C.c_int32 * 3), ("rot", C.c_int32 * 3), ("flags", C.c_uint32)]

    rng = np.random.default_rng(3)
    pos_nm = rng.integers(-300_000_000, 300_000_000, (20, 3))
    ang_udeg = np.column_stack([rng.integers(-90_000_000, 90_000_000, 20), rng.integers(-720_000_000, 720_000_000, 20)])
    p_ref, r_ref = five_reference(table, pos_nm * 1e-6, ang_udeg * 1e-6)
    assert np.max(np.abs(p_ref)) > 1.0  # the identified errors are not nothing
    for i in range(20):
        inp, out = In(), Out()
        inp.pos[:] = [int(v) for v in pos_nm[i]]
        inp.ang[:] = [int(v) for v in ang_udeg[i]]
        lib.abbe_five_error_eval_q(model, C.byref(inp), C.byref(out))
        assert np.all(np.abs(np.array(out.err[:]) - p_ref[i] * 1e3) <= 2.0)
        assert np.all(np.abs(np.array(out.rot[:]) - r_ref[i] * 1e3) <= 1.0)
