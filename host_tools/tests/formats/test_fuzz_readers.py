"""Property-based and mutation fuzzing of every reader (seeded, bounded: part of CI).

Mutation: seed files of the fuzzing workspace mutated by hypothesis-drawn operators
(fuzzing.mutate); every reader must return or raise AbbeInputError naming the file,
in one line -- never another exception -- within a time bound. A hostile number in
place of any number of a data file must be refused. Property: generated valid files
in any newline style, with or without a BOM, in any declared dialect, read back to
the values written; wrapped ballbar angles read back unwrapped.
"""

from __future__ import annotations

import math
import signal
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from fuzz_budget import DERANDOMIZE, examples

from abbe.errors import AbbeInputError
from fuzzing.mutate import HOSTILE_NUMBERS, mutate, replace_number

#: Mutated inputs per reader in CI (the long run: python -m fuzzing.run).
EXAMPLES = examples(100)
FUZZ = settings(max_examples=EXAMPLES, derandomize=DERANDOMIZE, database=None, deadline=None,
                suppress_health_check=list(HealthCheck))


def _readers(ws):
    from abbe.formats.ballbar_csv import read_ballbar_csv
    from abbe.formats.blob import read_blob_file
    from abbe.formats.etalon import read_etalon
    from abbe.formats.isg_csv import read_isg_csv, read_list
    from abbe.formats.laser_csv import read_laser_csv
    from abbe.formats.machine import load_machine
    from abbe.formats.model_file import load_table
    from abbe.formats.positioning import load_positioning
    from abbe.formats.table_json import load_table_file, load_table_json
    from abbe.sim.spec import load_spec
    from abbe.sim.truth import load_truth

    from abbe.formats.ballbar_file import read_ballbar_file
    from abbe.formats.laser_file import read_laser_line
    from abbe.formats.renishaw_b5r import read_b5r

    def renishaw(p):
        m = load_machine(p)
        if "X" in m.laser:  # a mutation may rename the sections: then there is nothing to read
            read_laser_line(m.laser["X"], channels=tuple(m.laser["X"].map))
        if "circle1" not in m.ballbar:
            return m
        return read_ballbar_file(m.ballbar["circle1"], str(p))

    def declared(p):
        m = load_machine(ws.declared_machine)
        return read_laser_csv(p, channels=("linear", "yaw"), columns=m.laser["X"].columns)

    return {
        "laser": (ws.laser, read_laser_csv),
        "laser_declared": (ws.declared_laser, declared),
        "ballbar": (ws.ballbar, read_ballbar_csv),
        "dat": (ws.dat, load_positioning),
        "machine": (ws.machine, load_machine),
        "spec": (ws.spec, load_spec),
        "table_json": (ws.table_json, load_table_json),
        "blob": (ws.blob, read_blob_file),
        "model": (ws.blob, load_table_file),
        "truth": (ws.machine.parent / "truth" / "truth.json", load_truth),
        "isg_csv": (ws.isg_csv, read_isg_csv),
        "isg_lis": (ws.isg_lis, read_list),
        "etalon": (ws.etalon, read_etalon),
        "model_file blob": (ws.blob, load_table),
        "model_file json": (ws.table_json, load_table),
        "rtl": (ws.rtl, load_positioning),
        "b5r": (ws.b5r, lambda p: read_b5r(p)),
        "machine renishaw": (ws.renishaw_machine, renishaw),
        "rtl cp1250": (ws.rtl_windows, load_positioning),
        "b5r ballbar20": (ws.b5r_ballbar20, lambda p: read_b5r(p)),
        "machine renishaw20": (ws.renishaw20_machine, renishaw),
    }


READERS = ["laser", "laser_declared", "ballbar", "dat", "machine", "spec", "table_json", "blob",
           "model", "truth", "isg_csv", "isg_lis", "etalon", "model_file blob", "model_file json",
           "rtl", "b5r", "machine renishaw", "rtl cp1250", "b5r ballbar20", "machine renishaw20"]


class _Slow(BaseException):
    pass


def _call(fn, path: Path, budget_s: float = 20.0):
    def alarm(*_):
        raise _Slow()
    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, budget_s)
    try:
        return fn(path)
    except _Slow:
        pytest.fail(f"reader ran over {budget_s} s on {path}")
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def _check_error(e: AbbeInputError, path: Path) -> None:
    assert e.file is not None, str(e)
    assert "\n" not in str(e), str(e)
    assert "np.float64" not in str(e)


@pytest.mark.parametrize("name", READERS)
def test_mutated_inputs_are_read_or_refused(seed_ws, name):
    seed_path, fn = _readers(seed_ws)[name]
    seed = seed_path.read_bytes()

    @FUZZ
    @given(st.data())
    def run(data):
        pick = lambda n: data.draw(st.integers(0, max(n - 1, 0)))  # noqa: E731
        rounds = data.draw(st.integers(1, 4))
        blob, ops = mutate(seed, pick, rounds)
        with tempfile.TemporaryDirectory() as d:
            p = Path(d) / seed_path.name
            p.write_bytes(blob)
            if name in ("machine", "laser_declared", "isg_lis", "machine renishaw",
                        "machine renishaw20"):  # keep the relative data paths
                p = seed_path.parent / f".fuzz-{seed_path.name}"
                p.write_bytes(blob)
            try:
                _call(fn, p)
            except AbbeInputError as e:
                _check_error(e, p)
            finally:
                if p.parent == seed_path.parent:
                    p.unlink()

    run()


@pytest.mark.parametrize("name", ["laser", "ballbar", "dat", "isg_csv", "etalon", "rtl", "b5r"])
def test_a_hostile_number_in_a_data_file_is_always_refused(seed_ws, name):
    """(Not the decimal-comma export: there "0,000" minus its "0" is still a number.
    Comment lines of the error files are dropped first: a number in a comment is text.)"""
    seed_path, fn = _readers(seed_ws)[name]
    seed = b"\n".join(ln for ln in seed_path.read_bytes().split(b"\n")
                      if not ln.lstrip().startswith(b"//"))
    seed_head = b""

    @FUZZ
    @given(st.data())
    def run(data):
        pick = lambda n: data.draw(st.integers(0, max(n - 1, 0)))  # noqa: E731
        blob = seed_head + replace_number(seed, pick)
        p = seed_path.parent / f".fuzz-num-{seed_path.name}"
        p.write_bytes(blob)
        try:
            with pytest.raises(AbbeInputError) as ei:
                _call(fn, p)
            _check_error(ei.value, p)
            assert ei.value.line is not None, str(ei.value)
        finally:
            p.unlink()

    run()


# --------------------------------------------------------------------------- properties

_NL = st.sampled_from(["\n", "\r\n", "\r"])


@st.composite
def laser_files(draw):
    """A valid abbe laser CSV: runs x (+, -) passes over sorted targets, any column order."""
    T = draw(st.integers(3, 12))
    steps = draw(st.lists(st.floats(0.5, 40.0), min_size=T - 1, max_size=T - 1))
    t0 = draw(st.floats(0.0, 100.0))
    targets = np.round(t0 + np.concatenate([[0.0], np.cumsum(steps)]), 3)
    runs = draw(st.integers(1, 4))
    cols = ["run", "direction", "target_mm", "linear_um", "yaw_urad"]
    order = draw(st.permutations(cols))
    vals = draw(st.lists(st.floats(-1e4, 1e4, allow_nan=False), min_size=runs * 2 * T * 2,
                         max_size=runs * 2 * T * 2))
    rows, k, want = [], 0, {"linear": np.zeros((runs, 2, T)), "yaw": np.zeros((runs, 2, T))}
    for r in range(runs):
        for d, idx in ((0, range(T)), (1, range(T - 1, -1, -1))):
            for i in idx:
                lin, yaw = vals[k], vals[k + 1]
                k += 2
                want["linear"][r, d, i], want["yaw"][r, d, i] = lin, yaw
                cell = {"run": str(r + 1), "direction": "+-"[d], "target_mm": f"{targets[i]:.3f}",
                        "linear_um": repr(lin), "yaw_urad": repr(yaw)}
                rows.append(",".join(cell[c] for c in order))
    nl = draw(_NL)
    text = nl.join([",".join(order)] + rows) + (nl if draw(st.booleans()) else "")
    bom = b"\xef\xbb\xbf" if draw(st.booleans()) else b""
    return bom + text.encode(), targets, want


@settings(max_examples=examples(80), derandomize=DERANDOMIZE, database=None, deadline=None)
@given(laser_files())
def test_valid_laser_files_read_back(f):
    from abbe.formats.laser_csv import read_laser_csv
    raw, targets, want = f
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "x.csv"
        p.write_bytes(raw)
        got = read_laser_csv(p, channels=("linear", "yaw"))
    assert np.allclose(got.targets_mm, targets)
    for ch in ("linear", "yaw"):
        assert np.array_equal(got.channels[ch], want[ch])


@st.composite
def declared_files(draw):
    """The same readings written as an instrument export in a drawn dialect."""
    raw, targets, want = draw(laser_files())
    text = raw.decode("utf-8-sig").replace("\r\n", "\n").replace("\r", "\n")
    lines = [ln for ln in text.split("\n") if ln]
    hdr = lines[0].split(",")
    delim = draw(st.sampled_from([";", "\t", "|"] + ([","] * 1)))
    decimal = "," if delim != "," and draw(st.booleans()) else "."
    lin_unit = draw(st.sampled_from(["mm", "um", "nm"]))
    ang_unit = draw(st.sampled_from(["urad", "arcsec", "mm/m"]))
    sign = draw(st.sampled_from([1, -1]))
    units_row = draw(st.booleans())
    skip = draw(st.integers(0, 3))
    from abbe.formats.columns import UNITS
    ls, asc = UNITS["linear"][lin_unit], UNITS["angular"][ang_unit]
    names = {"run": "Run no.", "direction": "Dir", "target_mm": "Pos", "linear_um": "Linear",
             "yaw_urad": "Yaw"}
    out = [f"preamble line {i}; 1,5; x" for i in range(skip)]
    out.append(delim.join(names[h] for h in hdr))
    if units_row:
        out.append(delim.join({"target_mm": "[mm]", "linear_um": f"[{lin_unit}]",
                               "yaw_urad": f"({ang_unit})"}.get(h, "") for h in hdr))
    for ln in lines[1:]:
        c = dict(zip(hdr, ln.split(",")))
        c["direction"] = {"+": "FWD", "-": "bwd"}[c["direction"]]
        c["linear_um"] = repr(sign * float(c["linear_um"]) / ls)
        c["yaw_urad"] = repr(float(c["yaw_urad"]) / asc)
        cells = [c[h] for h in hdr]
        if decimal == ",":
            cells = [x.replace(".", ",") for x in cells]
        out.append(delim.join(cells))
    decl = {"delimiter": {"\t": "tab"}.get(delim, delim), "decimal": decimal, "skip_lines": skip,
            "units_row": units_row, "run": "Run no.", "direction": "Dir",
            "direction_values": ["fwd", "BWD"], "target": "Pos",
            "linear": {"column": "Linear", "sign": sign} if units_row else
            {"column": "Linear", "unit": lin_unit, "sign": sign},
            "yaw": "Yaw" if units_row else {"column": "Yaw", "unit": ang_unit}}
    nl = draw(_NL)
    return (nl.join(out) + nl).encode(), decl, targets, want


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"').replace("\t", "\\t") + '"'
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return "{ " + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + " }"


@settings(max_examples=examples(80), derandomize=DERANDOMIZE, database=None, deadline=None)
@given(declared_files())
def test_declared_dialects_read_back(f):
    from abbe.formats.columns import LASER_ROLES, parse_columns
    from abbe.formats.laser_csv import read_laser_csv
    raw, decl, targets, want = f

    def err(dotted, msg):
        return AbbeInputError(msg, field=dotted)
    cols = parse_columns(decl, LASER_ROLES, "laser.X.columns", err, ("+", "-"))
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "export.txt"
        p.write_bytes(raw)
        got = read_laser_csv(p, channels=("linear", "yaw"), columns=cols)
    assert np.allclose(got.targets_mm, targets)
    for ch in ("linear", "yaw"):
        assert np.allclose(got.channels[ch], want[ch], rtol=1e-12, atol=1e-9)


@settings(max_examples=examples(60), derandomize=DERANDOMIZE, database=None, deadline=None)
@given(st.floats(0.0, 359.0), st.floats(0.25, 3.0), st.integers(0, 40), st.booleans())
def test_wrapped_ballbar_angles_unwrap(start, step, arc, feed):
    """A trace written with angles wrapped into [0, 360) reads back as abbe's convention."""
    from abbe.formats.ballbar_csv import read_ballbar_csv
    step = 360.0 / round(360.0 / step)
    a = arc * step if feed else 0.0
    ccw = np.arange(-a, 360.0 + a + 1e-9, step)
    cw = ccw[::-1]
    t = np.arange(ccw.size + cw.size) * 0.1
    rows = ["direction,angle_deg,radial_um,time_s"]
    for i, (d, ang) in enumerate([("ccw", x) for x in ccw] + [("cw", x) for x in cw]):
        rows.append(f"{d},{math.fmod(ang + 720.0, 360.0):.6f},{math.sin(math.radians(ang)):.4f},"
                    f"{t[i]:.3f}")
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "b.csv"
        p.write_text("\n".join(rows) + "\n")
        tr = read_ballbar_csv(p)
    assert np.allclose(tr.angle_deg, np.concatenate([ccw, cw]), atol=1e-5)


@pytest.mark.parametrize("value", HOSTILE_NUMBERS)
def test_every_hostile_number_is_refused_in_a_laser_cell(seed_ws, value, tmp_path):
    from abbe.formats.laser_csv import read_laser_csv
    lines = seed_ws.laser.read_text().splitlines()
    cells = lines[2].split(",")
    cells[3] = value
    lines[2] = ",".join(cells)
    p = tmp_path / "x.csv"
    p.write_text("\n".join(lines) + "\n", encoding="utf-8")
    with pytest.raises(AbbeInputError) as ei:
        read_laser_csv(p)
    assert ei.value.line == 3, str(ei.value)
