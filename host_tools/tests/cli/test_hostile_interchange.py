"""Regression corpus of issue 15 ("hostile input") for ``abbe export`` and ``abbe import``:
the classes of the issue, each with cases of the error files, models, options and output
paths of the two commands.

Each case runs the real command (in-process) through the fuzzing harness, which checks
the promises (exit 0/2, one-line message, no traceback, nothing written on failure, no
staging leftovers, strict JSON), then the case's own expectation: the exit status and
the FILE:LINE / field the message must name.
"""

from __future__ import annotations

import json
import os
import re
import shutil
from pathlib import Path

import pytest
from hostile import expect

REF = ["163.626", "-212.772", "-290.704"]




def _csv_import(ws, out, *extra):
    return ["import", ws.isg_csv, "-o", out, "--reference", *REF, "--max-points", "40", *extra]


def _lines(p: Path) -> list[str]:
    return p.read_text(encoding="utf-8").splitlines()


def _set_isg_cell(p: Path, header: str, col: str, value: str, row: int = 1) -> int:
    """Set cell ``col`` of the ``row``-th record under the header line starting ``header``;
    returns its line number."""
    ls = _lines(p)
    h = next(i for i, ln in enumerate(ls) if ln.startswith(header))
    names = ls[h].split()
    cells = ls[h + row].split()
    cells[names.index(col)] = value
    ls[h + row] = " ".join(cells)
    p.write_text("\n".join(ls) + "\n", encoding="utf-8")
    return h + row + 1


# --------------------------------------------------------------------------- garbage accepted


@pytest.mark.parametrize("value", ["1_0", "\u0661\u0662", "\uff11\uff12", "12\u00a0", "0x1p3",
                                   "nan", "-inf", "1e400", "+-1", "", "1,5.3", "9" * 5000])
def test_foreign_numbers_in_an_isg_csv_are_refused(ws, tmp_path, value):
    line = _set_isg_cell(ws.isg_csv, "X EXX", "EYX", value, row=3)
    out = tmp_path / "o"
    expect(_csv_import(ws, out), [out], where=f"{ws.isg_csv}:{line}:")


@pytest.mark.parametrize("header,col,value,text", [
    ("X EXX", "EXX", "200", r"\[-100000, 100000\] um, got '200' = 200000 um"),  # 200 mm
    ("X EXX", "EAX", "0.5", r"\[-100000, 100000\] urad"),                          # 0.5 rad
    ("X EXX", "X", "5000", r"\[-2147, 2147\] mm"),
    ("C0Y", "C0Y", "0.01", r"\[-3906.25, 3906.25\] urad"),                        # beyond a table
])
def test_absurd_values_in_an_isg_csv_are_refused_with_the_range(ws, tmp_path, header, col,
                                                                value, text):
    line = _set_isg_cell(ws.isg_csv, header, col, value)
    out = tmp_path / "o"
    expect(_csv_import(ws, out), [out], where=f"{ws.isg_csv}:{line}:", field=col, text=text)


def test_a_curve_the_table_cannot_hold_is_located(ws, tmp_path):
    """90 mm of positioning error passes the reading's range (100 mm) but not the table's
    fixed-point cap: the error names the file, the block's line and the ISO name."""
    ls = _lines(ws.isg_csv)
    h = next(i for i, ln in enumerate(ls) if ln.startswith("X EXX"))
    for i in range(h + 1, len(ls)):
        if ls[i].startswith(("#", "//")):
            break
        c = ls[i].split()
        c[1] = f"{90.0 * float(c[0]) / 500.0:.6f}"
        ls[i] = " ".join(c)
    ws.isg_csv.write_text("\n".join(ls) + "\n")
    out = tmp_path / "o"
    expect(_csv_import(ws, out), [out], where=f"{ws.isg_csv}:{h + 1}:", field="EXX",
            text="does not fit in a table")


def test_a_span_below_a_nanometre_is_located(tmp_path):
    f = tmp_path / "tiny.csv"
    f.write_text("// positions 0.1 nm apart\nX EXX\n" + "".join(
        f"{i * 1e-7:.7f} {0.001 * (i % 2)}\n" for i in range(6)))
    out = tmp_path / "o"
    expect(["import", f, "-o", out, "--reference", "0", "0", "0"], [out], where=f"{f}:2:",
            field="X", text="whole nm")


@pytest.mark.parametrize("old,new,fld,text", [
    ("Gridpoints = {", "Gridpionts = {", "EXX.Gridpionts", "did you mean 'Gridpoints'"),
    ("[EXX]\nGridpoints = {", "[EXX]\nVALUE = 0.001\nGridpoints = {", "EXX", "component error"),
    ("[C0Y]\nVALUE", "[C0Y]\nUnit = rad\nVALUE", "C0Y.Unit", "unknown key"),
    ("[C0Y]\nVALUE = 2.5", "[C0Y]\n[Q0Y]\nVALUE = 2.5", "C0Y", "without VALUE or Gridpoints"),
    ("[EXX]", "[exx]", "exx", "did you mean 'EXX'"),
])
def test_etalon_keys_are_checked(ws, tmp_path, old, new, fld, text):
    s = ws.etalon.read_text()
    assert old in s
    ws.etalon.write_text(s.replace(old, new, 1))
    out = tmp_path / "o"
    expect(["import", ws.etalon, "-o", out, "--reference", *REF], [out], where=f"{ws.etalon}:",
            field=fld, text=text)


@pytest.mark.parametrize("old,new,fld,text", [
    ("file[0] volcomp.csv", "file[0] volcomp.csv\nflie[1] other.csv", "flie[1]",
     r"did you mean 'file\[j\]'"),
    ("chain XYZ", "chain XYZ\nnegate TRUE", "negate", "negate TRUE is not read"),
    ("chain XYZ", "chain YXZ", "chain", "abbe's model is the chain XYZ"),
    ("workpiece_axes 2", "workpiece_axes 0", "workpiece_axes", "abbe's model"),
    ("z 3", "z 2", "z", "already axis Y"),
    ("file_format[0] ISG_CSV\n", "", "file_format[0]", "every parameter file names its format"),
    ("file_format[0] ISG_CSV", "file_format[0] ISG_CVS", "file_format[0]", "did you mean"),
    ("interpolation GRID", "interpolation GRID\nInterpolation AUTO", "Interpolation",
     "given twice"),
    ("file[0] volcomp.csv", "file[0] /dev/zero", "file[0]", "not a regular file"),
    ("file[0] volcomp.csv", "file[0] missing.csv", "file[0]", "no such file"),
    ("file[0] volcomp.csv", "file[12] volcomp.csv", "file[12]", r"in \[0, 9\]"),
    ("x 1", "vol_comp[0].max_records 2000", "vol_comp[0].max_records", "start-up list"),
])
def test_list_file_keys_are_checked(ws, tmp_path, old, new, fld, text):
    s = ws.isg_lis.read_text()
    assert old in s
    ws.isg_lis.write_text(s.replace(old, new, 1))
    out = tmp_path / "o"
    expect(["import", ws.isg_lis, "-o", out, "--machine", ws.machine], [out],
            where=f"{ws.isg_lis}:", field=fld, text=text)


def test_a_controller_path_in_the_list_is_read_beside_it(ws, tmp_path):
    s = ws.isg_lis.read_text().replace("file[0] volcomp.csv", "file[0] C:\\TwinCAT\\vc\\volcomp.csv")
    ws.isg_lis.write_text(s)
    out = tmp_path / "o"
    o = expect(["import", ws.isg_lis, "-o", out, "--machine", ws.machine], [out], rc=0)
    assert "read as volcomp.csv beside the list file" in o.stdout
    assert json.loads((out / "model.json").read_text())["notes"]


# --------------------------------------------------------------------------- text files


@pytest.mark.parametrize("nl", [b"\r\n", b"\r"])
def test_crlf_cr_and_bom_are_valid_error_files(ws, tmp_path, nl):
    for f in (ws.isg_csv, ws.isg_lis, ws.etalon):
        f.write_bytes(b"\xef\xbb\xbf" + f.read_bytes().replace(b"\n", nl))
    a, b = tmp_path / "a", tmp_path / "b"
    expect(["import", ws.isg_lis, "-o", a, "--machine", ws.machine], [a], rc=0)
    expect(["import", ws.etalon, "-o", b, "--reference", *REF, "--no-unfold"], [b], rc=0)


def test_encodings_and_binary_are_refused_with_their_line(ws, tmp_path):
    out = tmp_path / "o"
    text = ws.isg_csv.read_text()
    ws.isg_csv.write_bytes(text.encode("utf-16"))
    expect(_csv_import(ws, out), [out], where=f"{ws.isg_csv}:1:", text="UTF-16")
    ls = _lines(ws.etalon)
    ls[4] = ls[4] + " // \xe9"
    ws.etalon.write_bytes("\n".join(ls).encode("latin-1"))
    expect(["import", ws.etalon, "-o", out, "--reference", *REF], [out], where=f"{ws.etalon}:5:",
            text="not UTF-8")
    ws.isg_lis.write_bytes(b"x 1\n\x00\n")
    expect(["import", ws.isg_lis, "-o", out, "--machine", ws.machine], [out],
            where=f"{ws.isg_lis}:2:", text="NUL byte")


def test_line_and_size_limits(ws, tmp_path):
    from abbe.formats.limits import COMPONENT_FILE_MAX_RECORDS, LIS_MAX_BYTES
    out = tmp_path / "o"
    ls = _lines(ws.isg_csv)
    ls.insert(1, "// " + "x" * 70_000)
    ws.isg_csv.write_text("\n".join(ls) + "\n")
    expect(_csv_import(ws, out), [out], where=f"{ws.isg_csv}:2:", text="limit is 65536")
    rows = ["X EXX"] + [f"{i * 1e-3:.3f} 0" for i in range(COMPONENT_FILE_MAX_RECORDS + 1)]
    ws.isg_csv.write_text("\n".join(rows) + "\n")
    expect(_csv_import(ws, out), [out], where=f"{ws.isg_csv}:{COMPONENT_FILE_MAX_RECORDS + 2}:",
            text="more than 100000 records")
    ws.isg_lis.write_text("// " + "y" * 100 + "\n" * LIS_MAX_BYTES)
    expect(["import", ws.isg_lis, "-o", out, "--machine", ws.machine], [out], where=ws.isg_lis,
            text="larger than the limit of 64.0 KiB")


def test_paths_that_are_not_files(ws, tmp_path):
    out = tmp_path / "o"
    loop = tmp_path / "loop.exc"
    os.symlink(loop, loop)
    expect(["import", loop, "-o", out, "--reference", *REF], [out], where=loop,
            text="symbolic links")
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)  # nobody writes: reading it would block forever
    expect(["import", fifo, "-o", out, "--reference", *REF], [out], where=fifo,
            text="not a regular file")
    expect(["export", fifo, "-f", "marlin", "-o", out], [out], where=fifo,
            text="not a regular file")
    expect(["export", "/dev/zero", "-f", "marlin", "-o", out], [out], text="not a regular file")
    expect(["import", tmp_path, "-o", out, "--reference", *REF], [out], text="is a directory")


# --------------------------------------------------------------------------- models


def _fit_json(ws, tmp_path) -> Path:
    """A model.json of abbe import (a wrapped table), made from the seed .lis."""
    o = tmp_path / "imp"
    expect(["import", ws.isg_lis, "-o", o, "--machine", ws.machine], [o], rc=0)
    return o / "model.json"


def test_model_files_are_read_strictly(ws, tmp_path):
    out = tmp_path / "e"
    mj = _fit_json(ws, tmp_path)
    expect(["export", mj, "-f", "marlin", "-o", out], [out], rc=0)  # the wrapped form works
    shutil.rmtree(out)
    d = json.loads(mj.read_text())
    d["table"]["axes"]["X"]["b\u0430cklash_um"] = d["table"]["axes"]["X"].pop("backlash_um")
    mj.write_text(json.dumps(d, indent=2))
    o = expect(["export", mj, "-f", "marlin", "-o", out], [out],
                field="table.axes.X.b\u0430cklash_um", text="did you mean 'backlash_um'")
    assert re.search(re.escape(str(mj)) + r":\d+:", o.stderr)
    mj.write_text(mj.read_text().replace('"S_xy": ', '"S_xy": NaN, "x": ', 1))
    expect(["export", mj, "-f", "marlin", "-o", out], [out], where=f"{mj}:", text="NaN")
    mj.write_text(json.dumps({"format": "abbe-fit", "table": [1]}))
    expect(["export", mj, "-f", "marlin", "-o", out], [out], field="table",
            text="needs a 'table' object")
    tj = ws.table_json
    tj.write_bytes(tj.read_text().encode("utf-16"))
    expect(["export", tj, "-f", "marlin", "-o", out], [out], where=f"{tj}:1:", text="UTF-16")
    tj.write_text('{"a": ' * 5000 + "1" + "}" * 5000)
    expect(["export", tj, "-f", "marlin", "-o", out], [out], where=tj, text="nested deeper")
    blob = bytearray(ws.blob.read_bytes())
    blob[40] ^= 0xFF
    ws.blob.write_bytes(bytes(blob))
    expect(["export", ws.blob, "-f", "marlin", "-o", out], [out], where=ws.blob, text="CRC")
    ws.blob.write_bytes(b"ABBE" + b"\0" * (70 * 1024))
    expect(["export", ws.blob, "-f", "marlin", "-o", out], [out], where=ws.blob,
            text="at most 65536 bytes")
    assert not out.exists()


@pytest.mark.parametrize("form", ["table JSON", "wrapped"])
def test_a_json_table_the_format_cannot_hold_is_located(ws, tmp_path, form):
    """Found by the long fuzz run (two lines of a table JSON swapped: a travel [3.87, 0]
    mm reached the grid choice as a negative span, ValueError, exit 70): a JSON model is
    checked against the table format like `table from-json` does."""
    d = json.loads(ws.table_json.read_text())
    d["axes"]["Y"]["travel_mm"] = [3.87, 0.0]
    m = tmp_path / "m.json"
    if form == "wrapped":
        d = {"format": "abbe-fit", "table": {"crc32": "0x0", **d}}
    m.write_text(json.dumps(d, indent=2))
    out = tmp_path / "e"
    fld = ("table." if form == "wrapped" else "") + "axes.Y.travel_mm"
    ls = m.read_text().splitlines()
    y = next(i for i, ln in enumerate(ls) if ln.strip().startswith('"Y": {'))
    line = next(i for i, ln in enumerate(ls[y:], y + 1) if '"travel_mm"' in ln)
    expect(["export", m, "-f", "sinumerik-lec", "-o", out], [out], where=f"{m}:{line}:",
            field=fld, text="must be below max")


# --------------------------------------------------------------------------- options


@pytest.mark.parametrize("target,setting,text", [
    ("heidenhain-com", "points=1e9", r"expected an integer"),
    ("heidenhain-com", "points=10001", r"in \[2, 10000\]"),
    ("heidenhain-com", "points=\u0663\u0663", "expected an integer"),
    ("heidenhain-com", "pionts=64", "did you mean 'points'"),
    ("heidenhain-com", "axis_names=X=a b", "expected a name"),
    ("heidenhain-com", "axis_names=X=A,X=B", "axis X given twice"),
    ("fanuc-pitch", "unit_um=nan", "expected a finite number"),
    ("fanuc-pitch", "unit_um=1_0", "expected a number"),
    ("fanuc-pitch", "reference=X=inf", "finite"),
    ("fanuc-pitch", "ref_return=X=x", r"one of \+, -"),
    ("isg-csv", "file=../x.csv", "expected a name"),
    ("isg-csv", "file=residual.json", "another output file"),
    ("isg-csv", "logical_axes=Y=0", r"in \[1, 65535\]"),
    ("linuxcnc-comp", "joints=Z=99", r"in \[0, 15\]"),
    ("marlin", "skew_factor_max=0", r"in \(0, 10\]"),
    ("sinumerik-cec", "tables=1e400", "expected an integer"),
    ("linuxcnc-matrixkins", "component=a\nb", "expected a name"),
])
def test_export_settings_are_range_checked(ws, tmp_path, target, setting, text):
    out = tmp_path / "e"
    name = setting.partition("=")[0]
    o = expect(["export", ws.blob, "-f", target, "-o", out, "--set", setting], [out], text=text)
    assert f"field '--set {name}" in o.stderr, o.stderr  # (an axis value names its axis too)


def test_a_setting_given_twice_is_refused(ws, tmp_path):
    out = tmp_path / "e"
    expect(["export", ws.blob, "-f", "heidenhain-com", "-o", out, "--set", "points=64",
             "--set", "points=128"], [out], field="--set points", text="given twice")


@pytest.mark.parametrize("argv_tail,opt", [
    (["--reference", "nan", "0", "0"], "--reference"),
    (["--reference", "1e400", "0", "0"], "--reference"),
    (["--reference", "3000", "0", "0"], "--reference"),
    (["--reference", *REF, "--tool-offset", "0", "inf", "0"], "--tool-offset"),
    (["--reference", *REF, "--max-points", "4"], "--max-points"),
    (["--reference", *REF, "--max-points", "1000000000"], "--max-points"),
    (["--reference", *REF, "--max-points", "1e3"], "--max-points"),
])
def test_import_options_are_range_checked(ws, tmp_path, argv_tail, opt):
    out = tmp_path / "o"
    o = expect(["import", ws.isg_csv, "-o", out, *argv_tail], [out])
    assert opt in o.stderr


def test_tool_offset_with_a_machine_file_is_refused(ws, tmp_path):
    out = tmp_path / "o"
    expect(["import", ws.isg_lis, "-o", out, "--machine", ws.machine, "--tool-offset", "0", "0",
             "1"], [out], field="--tool-offset")


# --------------------------------------------------------------------------- outputs


@pytest.mark.parametrize("cmd", ["export", "import"])
def test_output_paths_are_checked_before_the_work(ws, tmp_path, cmd):
    f = tmp_path / "afile"
    f.write_text("keep me")
    for out, text in ((f, "exists and is not a folder"), (f / "sub", "is a file, not a folder")):
        argv = (["export", ws.blob, "-f", "marlin", "-o", out] if cmd == "export"
                else _csv_import(ws, out))
        expect(argv, [f], where=str(f), field="--out", text=text)
    assert f.read_text() == "keep me"


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_output_folder(ws, tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        expect(["export", ws.blob, "-f", "marlin", "-o", ro / "out"], [ro / "out"],
                text="permission denied")
    finally:
        ro.chmod(0o755)


def test_a_failed_run_leaves_the_old_result_intact(ws, tmp_path):
    e, i = tmp_path / "e", tmp_path / "i"
    expect(["export", ws.blob, "-f", "isg-csv", "-o", e, "--machine", ws.machine], [e], rc=0)
    expect(_csv_import(ws, i), [i], rc=0)
    (e / "notes.txt").write_text("mine")
    before = sorted(p.name for p in tmp_path.iterdir())
    # failures after the work started: a bad machine file, a bad record deep in the file
    m = ws.machine.read_text().replace("radius_mm = 100.0", "radius_mm = 1e400")
    ws.machine.write_text(m)
    expect(["export", ws.blob, "-f", "isg-csv", "-o", e, "--machine", ws.machine], [e],
            where=ws.machine)
    line = _set_isg_cell(ws.isg_csv, "Z EXZ", "EZZ", "nan", row=5)
    expect(_csv_import(ws, i), [i], where=f"{ws.isg_csv}:{line}:", field="EZZ")
    assert (e / "notes.txt").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # no staging leftovers


def test_export_json_on_stdout_is_strict(ws, tmp_path):
    out = tmp_path / "e"
    o = expect(["export", ws.blob, "-f", "fanuc-pitch", "-o", out, "--json", "-"], [out], rc=0,
                json_stdout=True)
    assert json.loads(o.stdout)["target"] == "fanuc-pitch"
