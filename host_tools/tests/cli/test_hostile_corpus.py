"""Regression corpus of issue 15 ("hostile input"): every case it lists, by class.

Each case runs the real command (in-process) through the fuzzing harness, which
checks the promises (exit 0/2, one-line message, no traceback, nothing written on
failure, no staging leftovers, strict JSON) and then the case's own expectation:
the exit status and the FILE:LINE / field the message must name.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np
import pytest
from hostile import expect

REPO = Path(__file__).resolve().parents[3]




def _edit(path: Path, old: str, new: str, count: int = 1) -> None:
    s = path.read_text(encoding="utf-8")
    assert old in s, (path, old)
    path.write_text(s.replace(old, new, count), encoding="utf-8")


def _set_cell(csv: Path, row: int, col: str, value: str) -> int:
    """Set one cell (row 1 = first data row); returns its line number."""
    lines = csv.read_text().splitlines()
    hdr = lines[0].split(",")
    cells = lines[row].split(",")
    cells[hdr.index(col)] = value
    lines[row] = ",".join(cells)
    csv.write_text("\n".join(lines) + "\n")
    return row + 1


# --------------------------------------------------------------------------- tracebacks


def test_cr_only_line_ends_are_read(ws, tmp_path):
    for f in (ws.laser, ws.ballbar):
        f.write_bytes(f.read_bytes().replace(b"\n", b"\r"))
    expect(["iso230-2", ws.laser, "--json", "-"], rc=0, json_stdout=True)
    expect(["ballbar", ws.machine, "circle1", "--no-plot"], rc=0)


def test_overlong_line_even_a_comment(ws):
    s = ws.laser.read_text().splitlines()
    s.insert(3, "#" + "x" * 140_000)
    ws.laser.write_text("\n".join(s) + "\n")
    expect(["iso230-2", ws.laser], where=f"{ws.laser}:4:", text="limit is 65536")
    b = ws.ballbar.read_text().splitlines()
    b.insert(1, "ccw," + "1" * 200_000)
    ws.ballbar.write_text("\n".join(b) + "\n")
    expect(["ballbar", ws.machine, "circle1", "--no-plot"], where=f"{ws.ballbar}:2:")


def test_23_digit_run_number(ws):
    line = _set_cell(ws.laser, 1, "run", "1" * 23)
    expect(["iso230-2", ws.laser], where=f"{ws.laser}:{line}:", field="run")


@pytest.mark.parametrize("value", ["\u00b2", "9" * 5000, "0", "-3", "1e3"])
def test_dat_counts(ws, value):
    _edit(ws.dat, "CYCLES=3", f"CYCLES={value}")
    expect(["iso230-2", ws.dat], where=f"{ws.dat}:3:", field="CYCLES")


@pytest.mark.parametrize("name,content,text", [
    ("utf16", None, "UTF-16"),
    ("nested", "[" * 5000 + "]" * 5000, "nested deeper"),
    ("huge float", None, "double range"),
    ("huge int", None, "digits"),
])
def test_table_json_hostile(ws, tmp_path, name, content, text):
    d = ws.table_json.read_text()
    if name == "utf16":
        ws.table_json.write_bytes(d.encode("utf-16"))
    elif name == "huge float":
        ws.table_json.write_text(d.replace('"backlash_um": 0.0', '"backlash_um": 1e400', 1))
    elif name == "huge int":
        ws.table_json.write_text(d.replace('"backlash_um": 0.0', '"backlash_um": ' + "7" * 5000, 1))
    else:
        ws.table_json.write_text(content)
    out = tmp_path / "o.bin"
    expect(["table", "from-json", ws.table_json, "-o", out], [out], where=ws.table_json,
            text=text)
    expect(["diagnose", "--iso230-2", ws.dat, "--axis", "X", "--model", ws.table_json, "-o",
             tmp_path / "d", "--no-plots"], [tmp_path / "d"], where=ws.table_json, text=text)


@pytest.mark.parametrize("old,new,text", [
    ("radius_mm = 100.0", "radius_mm = 1e400", "finite"),
    ("radius_mm = 100.0", "radius_mm = " + "1" * 5000, "number too long"),
    ("radius_mm = 100.0", "radius_mm = 1e-320", r"in \[1, 2000\] mm"),
    ("radius_mm = 100.0", "radius_mm = " + "[" * 3000 + "]" * 3000, "nested"),
    ("[ballbar.circle1]", "[ballbar.circle1]\nplane2 = 1", "unknown key"),
])
def test_machine_toml_hostile(ws, tmp_path, old, new, text):
    _edit(ws.machine, old, new)
    out = tmp_path / "o"
    expect(["fit", ws.machine, "-o", out, "--no-clib-check", "--no-report", "-q"], [out],
            where=ws.machine, text=text)


@pytest.mark.parametrize("old,new,field", [
    ("spacing_mm = 50.0", "spacing_mm = 1e-9", "laser.X.spacing_mm"),
    ("radius_mm = 100.0", "radius_mm = 1e-320", "ballbar.circle1.radius_mm"),
    ("seed = 7", "seed = " + "9" * 5000, None),
    ("seed = 7", "seed = 1e400", "machine.seed"),
    ("[noise]", "[nosie]", "nosie"),
])
def test_spec_toml_hostile(ws, tmp_path, old, new, field):
    _edit(ws.spec, old, new)
    out = tmp_path / "sim"
    o = expect(["simulate", ws.spec, "-o", out], [out], where=ws.spec, field=field)
    if field == "nosie":
        assert "did you mean 'noise'" in o.stderr
        assert f"{ws.spec}:" in o.stderr and re.search(r"spec\.toml:\d+:", o.stderr)


def test_machine_path_nul_loop_device(ws, tmp_path):
    out = tmp_path / "o"
    base = ["fit", "-o", out, "--no-clib-check", "--no-report", "-q"]
    expect(base + ["mach\0ine.toml"], [out], text="NUL byte")
    loop = tmp_path / "loop.toml"
    os.symlink(loop, loop)
    expect(base + [loop], [out], where=loop, text="symbolic links")
    expect(base + ["/dev/zero"], [out], where="/dev/zero", text="not a regular file")
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)  # nobody writes: reading it would block forever
    expect(["iso230-2", fifo], where=fifo, text="not a regular file")
    _edit(ws.machine, 'file = "laser/x.csv"', 'file = "/dev/zero"')
    expect(["fit", ws.machine] + base[1:], [out], where="/dev/zero", text="not a regular file")


@pytest.mark.parametrize("kind", ["is a file", "under a file", "dir for a file"])
def test_output_paths(ws, tmp_path, kind):
    f = tmp_path / "afile"
    f.write_text("keep me")
    if kind == "is a file":
        out, jout = f, f
        message = "exists and is not a folder"
    elif kind == "under a file":
        out, jout = f / "sub", f / "x.json"
        message = "is a file, not a folder"
    else:
        out, jout = tmp_path, tmp_path
        message = None
    if kind != "dir for a file":
        for argv in (["fit", ws.machine, "-o", out, "--no-clib-check", "--no-report", "-q"],
                     ["simulate", ws.spec, "-o", out],
                     ["table", "cgen", ws.blob, "-o", out],
                     ["diagnose", "--iso230-2", ws.dat, "--axis", "X", "-o", out, "--no-plots"]):
            expect(argv, [f], where=f, text=message)
    if kind == "is a file":  # a file output may replace a file
        assert f.read_text() == "keep me"
        return
    for argv, opt in ((["table", "from-json", ws.table_json, "-o", jout], "--out"),
                      (["table", "to-json", ws.blob, "-o", jout], "--out"),
                      (["diagnose", "--iso230-2", ws.dat, "--axis", "X", "-o", tmp_path / "d",
                        "--json", jout, "--no-plots"], "--json"),
                      (["ballbar", ws.machine, "circle1", "--plot", jout], "--plot")):
        expect(argv, [f, tmp_path / "d"], where=str(jout), field=opt)
    assert f.read_text() == "keep me"


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_output_folder(ws, tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        expect(["fit", ws.machine, "-o", ro / "out", "--no-clib-check", "--no-report", "-q"],
                [ro / "out"], text="permission denied")
    finally:
        ro.chmod(0o755)


# --------------------------------------------------------------------------- partial output


def test_failed_diagnose_json_leaves_no_folder(ws, tmp_path):
    f = tmp_path / "afile"
    f.write_text("x")
    out = tmp_path / "new" / "deeper"
    expect(["diagnose", "--iso230-2", ws.dat, "--axis", "X", "-o", out, "--json", f / "d.json",
             "--no-plots"], [out, tmp_path / "new"], field="--json")
    assert not (tmp_path / "new").exists()
    # and a failure after the work (bad model) leaves no folder either
    expect(["diagnose", "--iso230-2", ws.dat, "--axis", "X", "-o", out, "--model", f,
             "--no-plots"], [out, tmp_path / "new"], field="model")
    assert not (tmp_path / "new").exists()


def test_fit_replaces_the_old_result_in_one_swap(ws, tmp_path):
    out = tmp_path / "fit"
    expect(["fit", ws.machine, "-o", out, "--no-clib-check", "--no-report", "-q"], [out], rc=0)
    (out / "notes.txt").write_text("mine")
    old = (out / "model.bin").read_bytes()
    _edit(ws.machine, 'map = { linear = "+dx"', 'map = { linear = "-dx"')
    expect(["fit", ws.machine, "-o", out, "--no-clib-check", "--no-report", "-q"], [], rc=0)
    assert (out / "model.bin").read_bytes() != old
    assert (out / "notes.txt").read_text() == "mine"  # the user's files are kept
    before = sorted(p.name for p in tmp_path.iterdir())
    _set_cell(ws.laser, 2, "linear_um", "nan")
    expect(["fit", ws.machine, "-o", out, "--no-clib-check", "--no-report", "-q"], [out])
    assert sorted(p.name for p in tmp_path.iterdir()) == before


# --------------------------------------------------------------------------- garbage accepted


@pytest.mark.parametrize("col,value", [
    ("linear_um", "1e300"), ("linear_um", "1e308"), ("yaw_urad", "1e308"), ("linear_um", "1_0"),
    ("linear_um", "\u0661\u0662"), ("linear_um", "\uff11\uff12"), ("linear_um", "12\u00a0"),
    ("target_mm", "inf"), ("linear_um", "0x1p3"), ("linear_um", "+-1"),
])
def test_absurd_or_foreign_numbers_refused(ws, tmp_path, col, value):
    line = _set_cell(ws.laser, 3, col, value)
    out = tmp_path / "o"
    expect(["fit", ws.machine, "-o", out, "--no-clib-check", "--no-report", "-q"], [out],
            where=f"{ws.laser}:{line}:", field=col)


def test_ballbar_absurd_numbers_refused(ws):
    for col, value in (("radial_um", "1e300"), ("angle_deg", "nan"), ("time_s", "1_0")):
        line = _set_cell(ws.ballbar, 5, col, value)
        expect(["ballbar", ws.machine, "circle1", "--no-plot"], where=f"{ws.ballbar}:{line}:",
                field=col)
        _set_cell(ws.ballbar, 5, col, "1")


def test_misspelt_table_key_is_refused_with_a_suggestion(ws, tmp_path):
    d = json.loads(ws.table_json.read_text())
    d["axes"]["X"]["b\u0430cklash_um"] = d["axes"]["X"].pop("backlash_um")  # Cyrillic a
    ws.table_json.write_text(json.dumps(d, indent=2))
    out = tmp_path / "o.bin"
    o = expect(["table", "from-json", ws.table_json, "-o", out], [out], where=ws.table_json,
                field="axes.X.b\u0430cklash_um")
    assert "backlash_um" in o.stderr and re.search(r"model\.json:\d+:", o.stderr)


@pytest.mark.parametrize("argv_tail,opt", [
    (["--dir", "nan", "0", "0"], "--dir"), (["--dir", "2", "0", "0"], "--dir"),
    (["--temp-c", "inf", "20", "20"], "--temp-c"),
])
def test_table_eval_options(ws, argv_tail, opt):
    o = expect(["table", "eval", ws.blob, "100", "-200", "-100", *argv_tail])
    assert opt in o.stderr


@pytest.mark.parametrize("opt,value", [("--min-effect-um", "-1"), ("--min-effect-um", "nan"),
                                       ("--alpha", "0"), ("--alpha", "inf")])
def test_diagnose_options(ws, tmp_path, opt, value):
    out = tmp_path / "d"
    o = expect(["diagnose", "--iso230-2", ws.dat, "--axis", "X", "-o", out, opt, value], [out])
    assert opt in o.stderr


def test_fit_options(ws, tmp_path):
    out = tmp_path / "o"
    for opt, value in (("--folds", "1"), ("--folds", "1e400"), ("--max-degree", "8")):
        o = expect(["fit", ws.machine, "-o", out, opt, value], [out])
        assert opt in o.stderr


# --------------------------------------------------------------------------- valid input refused


def test_diagnose_iso230_2_on_the_example_laser_csv(tmp_path):
    out = tmp_path / "OUT"
    expect(["diagnose", "--iso230-2", REPO / "examples/vmc500/laser/x.csv", "--axis", "X", "-o",
             out, "--no-plots"], [out], rc=0)
    assert (out / "model.bin").is_file()


def test_bom_and_crlf_are_valid(ws):
    for f in (ws.laser, ws.ballbar, ws.dat, ws.machine):
        f.write_bytes(b"\xef\xbb\xbf" + f.read_bytes().replace(b"\n", b"\r\n"))
    expect(["iso230-2", ws.dat], rc=0)  # a .dat with a BOM is still a .dat
    expect(["iso230-2", ws.laser], rc=0)
    expect(["ballbar", ws.machine, "circle1", "--no-plot"], rc=0)


# --------------------------------------------------------------------------- unclear messages


def test_ballbar_bom_not_in_the_field_name(ws):
    ws.ballbar.write_bytes(b"\xef\xbb\xbf" + ws.ballbar.read_bytes().replace(b"direction", b"dir", 1))
    o = expect(["ballbar", ws.machine, "circle1", "--no-plot"], where=f"{ws.ballbar}:1:")
    assert "\ufeff" not in o.stderr


def test_encoder_range_error_names_file_and_line(ws, tmp_path):
    d = json.loads(ws.table_json.read_text())
    k = next(iter(d["axes"]["X"]["terms"]))
    d["axes"]["X"]["terms"][k][0] = 9e6
    ws.table_json.write_text(json.dumps(d, indent=2))
    out = tmp_path / "o.bin"
    expect(["table", "from-json", ws.table_json, "-o", out], [out],
            text=re.escape(str(ws.table_json)) + r":\d+: field 'axes\.X\.")


def test_unknown_toml_section_names_its_line(ws, tmp_path):
    ws.machine.write_text(ws.machine.read_text() + "\n[ballbaR.c2]\nfile = \"x\"\n")
    n = len(ws.machine.read_text().splitlines()) - 1
    out = tmp_path / "o"
    expect(["fit", ws.machine, "-o", out, "--no-clib-check", "--no-report", "-q"], [out],
            where=f"{ws.machine}:{n}:", text="did you mean 'ballbar'")


# --------------------------------------------------------------------------- scale


def test_dense_line_is_fitted_on_bins(ws, tmp_path):
    """A line of 2001 targets (the issue's 10^4-target case scaled for CI) is fitted on
    FIT_MAX_TARGETS bins; memory and time are measured in bench/bench_scale.py."""
    from abbe.formats.limits import FIT_MAX_TARGETS
    t = np.linspace(0.0, 500.0, 2001)
    rows = ["run,direction,target_mm,linear_um,yaw_urad"]
    for r in (1, 2):
        for d, tt in (("+", t), ("-", t[::-1])):
            rows += [f"{r},{d},{x:.4f},{np.sin(x / 40.0) + 0.01 * r:.4f},{x / 100.0:.4f}"
                     for x in tt]
    ws.laser.write_text("\n".join(rows) + "\n")
    _edit(ws.machine, 'map = { linear = "+dx", straight_h = "+dy", straight_v = "+dz", '
          'pitch = "-ey", yaw = "-ez", roll = "+ex" }', 'map = { linear = "+dx", yaw = "-ez" }')
    out = tmp_path / "o"
    expect(["fit", ws.machine, "-o", out, "--no-clib-check", "--no-report", "-q"], [out], rc=0)
    mj = json.loads((out / "model.json").read_text())
    assert mj["axes"]["X"]["n_targets"] == FIT_MAX_TARGETS
    assert mj["axes"]["X"]["n_targets_measured"] == 2001
    assert mj["axes"]["X"]["terms"]["dx"]["metrics"]["chosen"]["in_sample"]["rmse_um"] < 0.05
