"""Fuzzing of the newer readers (seeded, bounded: part of CI; a long run by hand with
``ABBE_FUZZ_SCALE``, tests/fuzz_budget.py).

The thermal record (CSV and .xlsx: bytes of the sheet's XML mutated inside a valid
workbook, and workbooks of drawn cell values), the machine file's ``[thermal]`` section
(with the record it names), ``[chain]`` / ``[chain.fit]`` / ``[probing.N]`` /
``[rtest.N]`` and ``[uncertainty.*]`` / ``[tolerances.*]``. Every reader returns or raises
AbbeInputError naming the file in one line -- never another exception; what it returns
holds finite numbers only; a hostile number in place of a record's number is refused
with its line.
"""

from __future__ import annotations

import io
import math
import re
import tempfile
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from abbe.errors import AbbeInputError
from abbe.formats.machine import load_machine
from abbe.formats.thermal_machine import check_against_record
from abbe.formats.thermal_record import RANGES, read_thermal_csv, read_thermal_record, read_thermal_xlsx
from fuzz_budget import DERANDOMIZE, examples
from fuzzing.mutate import HOSTILE_NUMBERS, mutate, replace_number

REPO = Path(__file__).resolve().parents[3]


def fuzz(n: int) -> settings:
    return settings(max_examples=examples(n), derandomize=DERANDOMIZE, database=None,
                    deadline=None, suppress_health_check=list(HealthCheck))


def _check_error(e: AbbeInputError) -> None:
    assert e.file is not None, str(e)
    assert "\n" not in str(e), str(e)
    assert "np.float64" not in str(e), str(e)


def _check_record(rec) -> None:
    """What a thermal record reader returns: finite, in range, times increasing."""
    assert rec.time_s.size >= 2 and np.all(np.diff(rec.time_s) > 0)
    for kind, arr in (("time", rec.time_s), ("temperature", rec.temps_c),
                      ("displacement", rec.disp_um)) + ((("speed", rec.speed_rpm),)
                                                        if rec.speed_rpm is not None else ()):
        lo, hi, _ = RANGES[kind]
        assert np.all(np.isfinite(arr)) and np.all((arr >= lo) & (arr <= hi)), kind
    assert rec.rows.size == rec.time_s.size and np.all(np.diff(rec.rows) > 0)


def _pick(data):
    return lambda n: data.draw(st.integers(0, max(n - 1, 0)))


# --------------------------------------------------------------------------- seeds
TEMPS = [f"t{k}" for k in range(1, 17)]
CHANNELS = [f"ch{k}" for k in range(1, 6)]


def _record_csv(n: int = 24) -> str:
    """A small record with the sensors and channels of examples/spindle_thermal (15 min
    steps: 6 h, so the machine file's windows are shortened to fit it)."""
    head = ["time_s", "spindle_rpm"] + [f"{t}_c" for t in TEMPS] + [f"{c}_um" for c in CHANNELS]
    lines = [",".join(head)]
    for i in range(n):
        row = [f"{i * 900.0:g}", "1250" if i % 8 < 4 else "0"]
        row += [f"{20.0 + 0.1 * k + 0.01 * i:.3f}" for k in range(16)]
        row += [f"{(k + 1) * 0.2 * math.sin(i / 5):.4f}" for k in range(5)]
        lines.append(",".join(row))
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def seeds(tmp_path_factory) -> dict[str, Path]:
    import openpyxl
    d = tmp_path_factory.mktemp("recent_seeds")
    out: dict[str, Path] = {}
    out["csv"] = d / "record.csv"
    out["csv"].write_text(_record_csv())
    out["xlsx"] = d / "record.xlsx"
    wb = openpyxl.Workbook()
    ws = wb.active
    ws.append(["time(s)", "spindle(RPM)", "t1(°C)", "t2(degC)", "ch1(um)", "ch2(µm)"])
    for i in range(8):
        ws.append([i * 15.0, 1250 if i > 2 else 0, 20.0 + 0.1 * i, "21.5", 0.1 * i, -0.05 * i])
    wb.save(out["xlsx"])
    # [thermal]: the example's machine file, its record the small CSV (hours fitted)
    t = (REPO / "examples" / "spindle_thermal" / "machine.toml").read_text()
    t = re.sub(r'record = "[^"]*"', 'record = "record.csv"', t)
    t = t.replace("identify_hours = [0.0, 24.0]", "identify_hours = [0.0, 3.0]")
    t = t.replace("validate_hours = [24.0, 46.0]", "validate_hours = [3.0, 5.75]")
    t = t.replace("cycle_hours = 8.0", "cycle_hours = 2.0")
    t = t.replace("tool_z_mm = 100.0", "tool_z_mm = 100.0\ntemperature_calibration_U_pct = 1.0")
    out["thermal_machine"] = d / "thermal_machine.toml"
    out["thermal_machine"].write_text(t)
    # [chain] with [chain.fit], a probing and an R-test plan (their files are not read here)
    c = (REPO / "host_tools" / "cases" / "five_axis_chains" / "head-table-maxkins.toml").read_text()
    c += ('\n[chain.fit]\nharmonics = 2\nfolds = 4\n\n[probing.S1]\nfile = "probe.csv"\n'
          "sphere_mm = [60.0, 0.0, -270.0]\nsphere_radius_mm = 12.5\nstylus_radius_mm = 1.5\n"
          'radius_tolerance_mm = 0.02\n\n[rtest.R1]\nfile = "rtest.csv"\n'
          "sphere_mm = [60.0, 0.0, -270.0]\ntip_mm = [0.0, 0.0, 100.0]\n")
    out["chain_machine"] = d / "chain_machine.toml"
    out["chain_machine"].write_text(c)
    # [uncertainty.*] and [tolerances.*] on the vmc500 example (docs/formats.md)
    u = (REPO / "examples" / "vmc500" / "machine.toml").read_text()
    u = re.sub(r'file = "([^"]*)"', lambda m: f'file = "{REPO / "examples" / "vmc500" / m.group(1)}"', u)
    u += ('\n[uncertainty.laser]\ninstrument = "laser_interferometer"\naccuracy_ppm = 0.05\n'
          "dead_path_mm = 50.0\nair_temp_u_c = 0.1\n\n[uncertainty.ballbar]\n"
          "calibration_U_um = 0.5\nscale_pct = 0.1\n\n[tolerances.X]\nE_um = 30.0\nA_um = 45.0\n"
          "R_um = 4.5\n\n[tolerances.ballbar]\nG_um = 25.0\nH_um = 5.0\n")
    out["uncertainty_machine"] = d / "uncertainty_machine.toml"
    out["uncertainty_machine"].write_text(u)
    return out


def test_the_seeds_are_read(seeds):
    """Each seed passes its reader whole: the fuzz tests start from valid inputs."""
    _check_record(read_thermal_csv(seeds["csv"]))
    _check_record(read_thermal_xlsx(seeds["xlsx"]))
    _read_thermal_machine(seeds["thermal_machine"])
    m = load_machine(seeds["chain_machine"])
    assert m.extra["chain_plans"].harmonics == 2 and "S1" in m.extra["chain_plans"].probing
    m = load_machine(seeds["uncertainty_machine"])
    assert "uncertainty" in m.extra


def _read_thermal_machine(p: Path) -> None:
    """The reader of abbe thermal: the machine file, its record, the two checked together."""
    m = load_machine(p)
    spec = m.extra.get("thermal")
    if spec is None:  # a mutation removed the section: nothing more to read
        return
    rec = read_thermal_record(spec.record, spec.sheet)
    _check_record(rec)
    check_against_record(spec, rec.temp_names, rec.channel_names, str(p), lambda f: None)


# --------------------------------------------------------------------------- thermal record
@pytest.mark.parametrize("name", ["csv", "xlsx"])
def test_mutated_records_are_read_or_refused(seeds, name):
    """Bytes of the CSV, or of the sheet's XML inside a valid .xlsx, mutated."""
    seed = seeds[name]
    if name == "csv":
        blob_seed = seed.read_bytes()
    else:
        z = zipfile.ZipFile(seed)
        parts = {n: z.read(n) for n in z.namelist()}
        blob_seed = parts["xl/worksheets/sheet1.xml"]

    @fuzz(60)
    @given(st.data())
    def run(data):
        blob, _ = mutate(blob_seed, _pick(data), data.draw(st.integers(1, 4)))
        with tempfile.TemporaryDirectory() as d:
            p = Path(d) / seed.name
            if name == "csv":
                p.write_bytes(blob)
            else:
                buf = io.BytesIO()
                with zipfile.ZipFile(buf, "w") as zo:
                    for n, b in parts.items():
                        zo.writestr(n, blob if n == "xl/worksheets/sheet1.xml" else b)
                p.write_bytes(buf.getvalue())
            try:
                _check_record(read_thermal_record(p))
            except AbbeInputError as e:
                _check_error(e)

    run()


def test_a_hostile_number_in_a_record_is_refused(seeds):
    head, body = seeds["csv"].read_bytes().split(b"\n", 1)  # the header's digits are names

    @fuzz(40)
    @given(st.data())
    def run(data):
        blob = head + b"\n" + replace_number(body, _pick(data))
        with tempfile.TemporaryDirectory() as d:
            p = Path(d) / "record.csv"
            p.write_bytes(blob)
            with pytest.raises(AbbeInputError) as ei:
                read_thermal_csv(p)
            _check_error(ei.value)
            assert ei.value.line is not None, str(ei.value)

    run()


_HEADS = st.sampled_from(["time(s)", "時間(s) ", "spindle(RPM)", "t1(°C)", "t2(degC)", "t3(C)",
                          "ch1(um)", "ch2(µm)", "ch3(μm)", "ch1(mm)", "(s)", "t 1(°C)", "x(um",
                          "", " ", "t1(°C)"])
_CELLS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-(10 ** 30), 10 ** 30),
    st.sampled_from(HOSTILE_NUMBERS[:-8] + ("12.5", " 3 ", "1e2", "-0", "0")),
    st.none(), st.booleans(),
    st.datetimes(), st.dates(), st.times(),
)


@fuzz(25)
@given(head=st.lists(st.one_of(_HEADS, st.none(), st.integers(0, 3)), min_size=1, max_size=6),
       body=st.lists(st.lists(_CELLS, max_size=7), max_size=6), gap=st.integers(0, 3))
def test_drawn_workbooks_are_read_or_refused(head, body, gap):
    """Workbooks of drawn header and cell values (openpyxl writes what Excel would)."""
    import openpyxl
    wb = openpyxl.Workbook()
    ws = wb.active
    for _ in range(gap):
        ws.append([])
    ws.append(head)
    for row in body:
        ws.append(row)
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "drawn.xlsx"
        try:
            wb.save(p)
        except (ValueError, TypeError):  # a value openpyxl itself cannot store
            return
        try:
            _check_record(read_thermal_xlsx(p))
        except AbbeInputError as e:
            _check_error(e)


# --------------------------------------------------------------------------- machine sections
@pytest.mark.parametrize("name", ["thermal_machine", "chain_machine", "uncertainty_machine"])
def test_mutated_machine_sections_are_read_or_refused(seeds, name):
    """``[thermal]`` (with its record), ``[chain]`` + plans, ``[uncertainty]`` /
    ``[tolerances]``: the seed's bytes mutated (structure breakers, hostile numbers)."""
    seed_path = seeds[name]
    seed = seed_path.read_bytes()
    read = _read_thermal_machine if name == "thermal_machine" else load_machine

    @fuzz(60)
    @given(st.data())
    def run(data):
        blob, _ = mutate(seed, _pick(data), data.draw(st.integers(1, 4)))
        p = seed_path.parent / f".fuzz-{seed_path.name}"  # beside the record it names
        p.write_bytes(blob)
        try:
            read(p)
        except AbbeInputError as e:
            _check_error(e)
        finally:
            p.unlink()

    run()


def _number_slots(text: str, section: str) -> list[tuple[int, int]]:
    """(start, end) of every number in the lines of ``[section...]`` tables."""
    out, inside, pos = [], False, 0
    for ln in text.splitlines(keepends=True):
        s = ln.strip()
        if s.startswith("["):
            inside = s.startswith(f"[{section}")
        elif inside and "=" in s and not s.startswith("#"):
            body = ln.split("#", 1)[0]
            for m in re.finditer(r"(?<![\w.])-?[0-9]+(?:\.[0-9]+)?(?:[eE][-+]?[0-9]+)?", body):
                if m.start() > body.index("="):
                    out.append((pos + m.start(), pos + m.end()))
        pos += len(ln)
    return out


@pytest.mark.parametrize("name,section", [("thermal_machine", "thermal"),
                                          ("chain_machine", "chain"),
                                          ("chain_machine", "probing"),
                                          ("uncertainty_machine", "uncertainty"),
                                          ("uncertainty_machine", "tolerances")])
def test_a_non_finite_number_in_a_section_is_refused(seeds, name, section):
    """nan / inf / 1e400 (TOML reads them as floats) where a number of the section was:
    always refused, naming the file and the line."""
    seed_path = seeds[name]
    text = seed_path.read_text()
    slots = _number_slots(text, section)
    assert slots, section

    @fuzz(20)
    @given(st.sampled_from(slots), st.sampled_from(["nan", "inf", "-inf", "+nan", "1e400",
                                                    "-1e400"]))
    def run(slot, value):
        a, b = slot
        p = seed_path.parent / f".fuzz-num-{seed_path.name}"
        p.write_text(text[:a] + value + text[b:])
        try:
            with pytest.raises(AbbeInputError) as ei:
                load_machine(p)
            _check_error(ei.value)
            assert ei.value.line is not None, str(ei.value)
        finally:
            p.unlink()

    run()


# --------------------------------------------------------------------------- five-axis tables
def _five_blobs() -> list[bytes]:
    """The golden five-axis tables: trunnions (format 1.2) and the chain kinds 3-5 (1.4)."""
    from abbe.formats.golden_five import chain_golden_tables, golden_tables
    return [g.blob for g in golden_tables()] + [g.blob for g in chain_golden_tables()]


def _refresh_crc(b: bytearray) -> bytes:
    import struct
    import zlib
    total = struct.unpack_from("<I", b, 8)[0]
    if 260 <= total <= len(b) and total % 4 == 0:
        struct.pack_into("<I", b, total - 4, zlib.crc32(bytes(b[:total - 4])) & 0xFFFFFFFF)
    return bytes(b)


def test_mutated_five_axis_tables_in_table_eval_and_info():
    """abbe table info / eval on a five-axis table of any kind with bytes of its rotary
    section changed (the CRC renewed, so the checks behind it are reached): exit 0 with
    finite numbers, or exit 2 naming the file in one line."""
    import contextlib
    from abbe.cli.entry import main

    blobs = _five_blobs()

    @fuzz(25)
    @given(st.data())
    def run(data):
        b = bytearray(data.draw(st.sampled_from(blobs)))
        for _ in range(data.draw(st.integers(1, 3))):
            i = data.draw(st.integers(256, len(b) - 5))
            b[i] = data.draw(st.sampled_from([0, 1, 2, 3, 5, 6, 0x7F, 0x80, 0xFF,
                                              data.draw(st.integers(0, 255))]))
        with tempfile.TemporaryDirectory() as d:
            p = Path(d) / "five.bin"
            p.write_bytes(_refresh_crc(b))
            for argv in (["table", "info", str(p)],
                         ["table", "eval", str(p), "100", "-50", "-40", "10", "20",
                          "-300", "200", "-100", "-45", "300"]):
                out, err = io.StringIO(), io.StringIO()
                with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                    rc = main(argv)
                assert rc in (0, 2), (argv[1], rc, err.getvalue()[-400:])
                if rc == 2:
                    msg = err.getvalue().strip()
                    assert "five.bin" in msg and msg.count("\n") == 0, msg[:400]
                    break
                assert not re.search(r"\b(nan|inf)\b", out.getvalue().lower()), out.getvalue()

    run()
