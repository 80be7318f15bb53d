"""abbe export --format sinumerik-carr: SINUMERIK toolholder data $TC_CARR, type P
(issue 23 part 4).

* golden files of examples/trunnion5ax (the model of golden/trunnion5ax-fit);
* the independent reader (tests/export_readers.py, from the Siemens documentation that
  docs/exports.md cites) runs the written data set's chain on the poses docs/exports.md
  describes, and the exact model (abbe.model.five_axis) gives back residual.json; the
  residual is far below linuxcnc-trt's (the vectors hold the tilts);
* a machine whose only errors are location errors (positions, tilts, zeros; both kinds)
  is corrected to the written decimals, which fixes every sign of the mapping; the
  vectors are checked against the first-order directions of ISO 230-7's tilts;
* an error motion is named with its size and is what is left;
* bad input exits 2 and writes nothing; the reader refuses a broken program.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from export_readers import (
    FormatError,
    carr_joints,
    read_linuxcnc_trt,
    read_sinumerik_carr,
    trt_joints,
)
from golden_compare import compare_dir
from test_linuxcnc_trt import (
    BC_MACHINE,
    GOLDEN,
    HELD_ERRORS,
    MACHINE,
    MODEL,
    check_against_report,
    doc_poses,
    exact_position_error,
    export,
)

from abbe.formats.five_axis_blob import read_five_blob, write_five_blob
from abbe.formats.machine import load_machine
from abbe.model.five_axis import FiveAxisErrors, nominal_joints

TARGET = "sinumerik-carr"
PROGRAM = "ABBE_CARR.MPF"


def carr(out: Path, model: Path, machine: Path | None = MACHINE, *opts: str) -> int:
    return export(out, model, machine, *opts, target=TARGET)


def reader_residual(out: Path, machine: Path, errs: FiveAxisErrors, program: str = PROGRAM):
    """{"volume"/"tcp_path": (residual norms, uncompensated norms)} and the data set read
    back, from the written program only."""
    m = load_machine(machine)
    geom = m.five_axis.geometry
    carrier, vals = read_sinumerik_carr(out / program)
    vol, path = doc_poses(geom, {a: m.axes[a].travel_mm for a in "XYZ"})
    got = {}
    for key, (W, A) in (("volume", vol), ("tcp_path", path)):
        q, t = carr_joints(vals, W, A)
        r = exact_position_error(geom, errs, W, A, q, t)
        u = exact_position_error(geom, errs, W, A, nominal_joints(geom, W, A), A)
        got[key] = (np.linalg.norm(r, axis=1), np.linalg.norm(u, axis=1))
    return got, (carrier, vals)


def bc_machine(folder: Path) -> Path:
    """The B/C machine file of test_linuxcnc_trt, written into ``folder``."""
    path = folder / "bc.toml"
    path.write_text(BC_MACHINE)
    return path


def test_golden_files(tmp_path) -> None:
    assert carr(tmp_path / TARGET, MODEL) == 0
    assert compare_dir(tmp_path / TARGET, GOLDEN / TARGET) == []


def test_reader_reproduces_the_residual_of_the_example(tmp_path) -> None:
    (tmp_path / "model_five.bin").write_bytes(MODEL.read_bytes())
    (tmp_path / "five_axis.json").write_bytes((GOLDEN / "five_axis.json").read_bytes())
    out = tmp_path / "carr"
    assert carr(out, tmp_path / "model_five.bin") == 0
    errs = read_five_blob(MODEL.read_bytes()).errors
    got, (carrier, vals) = reader_residual(out, MACHINE, errs)
    check_against_report(out, got)
    assert carrier == 1 and vals[21] == "A" and vals[22] == "C" and vals[23] == "P"
    rep = json.loads((out / "residual.json").read_text())
    trt = json.loads((GOLDEN / "linuxcnc-trt" / "residual.json").read_text())
    for key in ("volume", "tcp_path"):
        r, u = got[key]
        # the tilts EB0A, EC0A (151 / 110 um alone over the volume) are held: what is left
        # is the error motions, under a tenth of linuxcnc-trt's residual
        assert np.max(r) < 0.1 * trt[key]["residual"]["norm"]["max_um"], key
        assert np.max(r) < 0.1 * np.max(u), key
    kinds = {d["kind"] for d in rep["not_held"]}
    assert kinds == {"error motion"}
    # the largest error motion alone is of the size of what is left
    big = max(d["volume"]["max_um"] for d in rep["not_held"])
    assert big <= rep["volume"]["residual"]["norm"]["max_um"] <= 3.0 * big
    assert {"EA0C", "EB0C"} <= set(rep["not_observable"]["items"])


LOCATION = {"xyzac-trt": {"EX0C": 30.0, "EY0C": -20.0, "EA0C": 45.0, "EB0C": -35.0,
                          "EC0C": -60.0, "EY0A": 15.0, "EZ0A": -25.0, "EB0A": 80.0,
                          "EC0A": -55.0, "EA0A": 40.0},
            "xyzbc-trt": {"EX0C": -18.0, "EY0C": 22.0, "EA0C": -30.0, "EB0C": 25.0,
                          "EC0C": 70.0, "EX0B": 35.0, "EZ0B": 12.0, "EA0B": 60.0,
                          "EC0B": -40.0, "EB0B": -45.0}}


@pytest.mark.parametrize("kind", sorted(LOCATION))
def test_every_location_error_is_corrected(tmp_path, kind) -> None:
    machine = MACHINE if kind == "xyzac-trt" else bc_machine(tmp_path)
    geom = load_machine(machine).five_axis.geometry
    e = LOCATION[kind]
    errs = FiveAxisErrors(location=dict(e))
    (tmp_path / "m.bin").write_bytes(write_five_blob(geom, errs))
    out = tmp_path / "carr"
    assert carr(out, tmp_path / "m.bin", machine) == 0
    got, (_, vals) = reader_residual(out, machine, errs)
    check_against_report(out, got)
    for key, (r, u) in got.items():
        assert np.max(r) < 0.01, key      # nm text of l2..l4, 1e-9 of v1, v2, offsets
        assert np.max(u) > 10.0, key
    assert json.loads((out / "residual.json").read_text())["not_held"] == []
    # first order (ISO 230-7): a tilt of the A line about Y (EB0A) tips its direction to
    # -Z, about Z (EC0A) to +Y; C's about X (EA0C) to -Y, about Y (EB0C) to +X
    tilt = geom.tilt
    v1 = np.array([vals[7], vals[8], vals[9]])
    v2 = np.array([vals[10], vals[11], vals[12]])
    if tilt == "A":
        want1 = np.array([1.0, e["EC0A"] * 1e-6, -e["EB0A"] * 1e-6])
    else:  # B about X (EA0B) tips +Y to +Z, about Z (EC0B) to -X
        want1 = np.array([-e["EC0B"] * 1e-6, 1.0, e["EA0B"] * 1e-6])
    want2 = np.array([e["EB0C"] * 1e-6, -e["EA0C"] * 1e-6, 1.0])
    assert v1 == pytest.approx(want1, abs=1e-8)
    assert v2 == pytest.approx(want2, abs=1e-8)
    # l2 is a point of the tilt line, l2 + l3 of the C line, l4 closes the chain
    c_point = np.array(geom.rot_point_mm) + [e["EX0C"] * 1e-3, e["EY0C"] * 1e-3, 0.0]
    l2 = np.array([vals[4], vals[5], vals[6]])
    l3 = np.array([vals[15], vals[16], vals[17]])
    l4 = np.array([vals[18], vals[19], vals[20]])
    assert l2 + l3 == pytest.approx(c_point, abs=2e-6)
    assert l2 + l3 + l4 == pytest.approx(np.zeros(3), abs=1e-12)
    # the part turns by axis - offset: the offset is -E0 in degrees
    assert vals[24] == pytest.approx(-np.degrees(e[f"E{tilt}0{tilt}"] * 1e-6), abs=1e-9)
    assert vals[25] == pytest.approx(-np.degrees(e["EC0C"] * 1e-6), abs=1e-9)


@pytest.mark.parametrize("kind", sorted(HELD_ERRORS))
def test_same_joints_as_linuxcnc_trt_where_both_hold_the_errors(tmp_path, kind) -> None:
    """Without tilts both data sets describe the same machine: the type P chain (read from
    the program) and trtfuncs.c (read from the HAL file; checked in LinuxCNC itself by
    port/linuxcnc/tests/trt_sim_check.py) command the same joints."""
    machine = MACHINE if kind == "xyzac-trt" else bc_machine(tmp_path)
    geom = load_machine(machine).five_axis.geometry
    (tmp_path / "m.bin").write_bytes(write_five_blob(
        geom, FiveAxisErrors(location=dict(HELD_ERRORS[kind]))))
    assert carr(tmp_path / "carr", tmp_path / "m.bin", machine) == 0
    assert export(tmp_path / "trt", tmp_path / "m.bin", machine) == 0
    _, vals = read_sinumerik_carr(tmp_path / "carr" / PROGRAM)
    _, pins, home = read_linuxcnc_trt(tmp_path / "trt")
    m = load_machine(machine)
    (W, A), (Wp, Ap) = doc_poses(geom, {a: m.axes[a].travel_mm for a in "XYZ"}, n_lin=3)
    for w, a in ((W, A), (Wp, Ap)):
        q_carr, t_carr = carr_joints(vals, w, a)
        q_trt = trt_joints(kind, pins, w, a)
        assert np.max(np.abs(q_carr - q_trt)) < 2e-6          # the 6-decimal texts
        # the table's angle: trt moves the joint scale (HOME_OFFSET), the data set the
        # rotation (offset): the same axis positions relative to the table
        assert np.max(np.abs((t_carr - a) - (-np.array([home[3], home[4]])))) < 2e-9


def test_an_error_motion_is_named_with_its_size(tmp_path) -> None:
    geom = load_machine(MACHINE).five_axis.geometry
    errs = FiveAxisErrors(location={"EB0A": 50.0},
                          motions={("C", "Z"): np.array([0.0, 0.0, 4.0, -3.0])})
    (tmp_path / "m.bin").write_bytes(write_five_blob(geom, errs))
    out = tmp_path / "o"
    assert carr(out, tmp_path / "m.bin") == 0
    rep = json.loads((out / "residual.json").read_text())
    (item,) = rep["not_held"]
    assert item["item"] == "EZC(C)" and item["kind"] == "error motion"
    assert abs(rep["volume"]["residual"]["norm"]["max_um"] - item["volume"]["max_um"]) < 0.05
    assert 4.0 < item["volume"]["max_um"] < 5.5   # |4 sin 2c - 3 cos 2c| <= 5 um
    got, _ = reader_residual(out, MACHINE, errs)
    check_against_report(out, got)


def test_options_name_the_data_set(tmp_path) -> None:
    assert carr(tmp_path / "o", MODEL, MACHINE, "carrier=3", "tilt_axis=A1", "c_axis=C1",
                "program=TC_SWIVEL") == 0
    carrier, vals = read_sinumerik_carr(tmp_path / "o" / "TC_SWIVEL.MPF")
    assert carrier == 3 and vals[21] == "A1" and vals[22] == "C1"
    assert (tmp_path / "o" / "TC_SWIVEL.MPF").read_text().startswith("%_N_TC_SWIVEL_MPF\n")


VMC_MODEL = GOLDEN.parent / "vmc500-fit" / "model.bin"


@pytest.mark.parametrize("model, machine, opts, words", [
    (VMC_MODEL, MACHINE, (), "rotary section"),
    (MODEL, None, (), "--machine"),
    (MODEL, MACHINE, ("carrier=0",), "carrier"),
    (MODEL, MACHINE, ("c_axis=A",), "both named A"),
    (MODEL, MACHINE, ("tilt_axis=a;b",), "tilt_axis"),
    (MODEL, MACHINE, ("program=x/y",), "program"),
    (MODEL, MACHINE, ("tcp_point=X=inf",), "tcp_point"),
    (None, MACHINE, (), "short.bin"),
])
def test_bad_input_exits_2_and_writes_nothing(tmp_path, capsys, model, machine, opts,
                                              words) -> None:
    if model is None:  # a truncated table
        model = tmp_path / "short.bin"
        model.write_bytes(MODEL.read_bytes()[:300])
    out = tmp_path / "out"
    assert carr(out, model, machine, *opts) == 2
    assert words in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("edit", [
    lambda s: s.replace("%_N_ABBE_CARR_MPF", "ABBE_CARR"),
    lambda s: s.replace("$TC_CARR8[1]=", "$TC_CARR8[2]="),
    lambda s: s.replace('"P"', '"X"'),
    lambda s: s.replace("N240 M30", ""),
    lambda s: s.replace("N50 ", "N5 "),
    lambda s: s.replace("$TC_CARR5[1]=", "$TC_CARR6[1]="),
    lambda s: s.replace("$TC_CARR9[1]=", "$TC_CARR9[1]=nan"),
])
def test_reader_refuses_a_broken_program(tmp_path, edit) -> None:
    """The reader is strict: a test of the writer through it cannot pass on a program the
    control would read otherwise."""
    assert carr(tmp_path / "o", MODEL) == 0
    text = (tmp_path / "o" / PROGRAM).read_text()
    broken = edit(text)
    assert broken != text
    (tmp_path / "b.MPF").write_text(broken)
    with pytest.raises(FormatError):
        read_sinumerik_carr(tmp_path / "b.MPF")
