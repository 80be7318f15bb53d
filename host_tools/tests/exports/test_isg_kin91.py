"""abbe export --format isg-kin91: the rotary axes of the ISG / Beckhoff universal
kinematics (ID 91) (issue 23 part 4).

* golden files of examples/trunnion5ax;
* the independent reader (tests/export_readers.py, from the TF5240 pages docs/exports.md
  cites) composes the chain from the workpiece with 4x4 transforms and reproduces
  residual.json with the exact model;
* a machine with the positions and tilts of both lines (both kinds) is corrected to the
  written decimals; the angular zeros are named, not held;
* bad input exits 2 and writes nothing; the reader refuses a broken list.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from export_readers import FormatError, kin91_joints, read_isg_kin91
from golden_compare import compare_dir
from test_linuxcnc_trt import GOLDEN, MACHINE, MODEL, check_against_report, doc_poses, export
from test_linuxcnc_trt import exact_position_error as pos_error
from test_sinumerik_carr import LOCATION, bc_machine

from abbe.formats.five_axis_blob import read_five_blob, write_five_blob
from abbe.formats.machine import load_machine
from abbe.model.five_axis import FiveAxisErrors, nominal_joints

TARGET = "isg-kin91"
LIST = "kin91_rotary.lis"


def kin91(out: Path, model: Path, machine: Path | None = MACHINE, *opts: str) -> int:
    return export(out, model, machine, *opts, target=TARGET)


def residual_from_files(out: Path, machine: Path, errs: FiveAxisErrors, chain=(4, 3)):
    m = load_machine(machine)
    geom = m.five_axis.geometry
    axes = read_isg_kin91(out / LIST)
    got = {}
    for key, (W, A) in zip(("volume", "tcp_path"),
                           doc_poses(geom, {a: m.axes[a].travel_mm for a in "XYZ"})):
        q, t = kin91_joints(axes, chain, W, A)
        got[key] = (np.linalg.norm(pos_error(geom, errs, W, A, q, t), axis=1),
                    np.linalg.norm(pos_error(geom, errs, W, A, nominal_joints(geom, W, A), A),
                                   axis=1))
    return got, axes


def test_golden_files(tmp_path) -> None:
    assert kin91(tmp_path / TARGET, MODEL) == 0
    assert compare_dir(tmp_path / TARGET, GOLDEN / TARGET) == []


def test_reader_reproduces_the_residual_of_the_example(tmp_path) -> None:
    out = tmp_path / "k"
    assert kin91(out, MODEL) == 0
    got, axes = residual_from_files(out, MACHINE, read_five_blob(MODEL.read_bytes()).errors)
    check_against_report(out, got)
    assert sorted(axes) == [3, 4]
    # workpiece side: the C axis' orientation is -Z
    assert axes[4]["orientation"] == pytest.approx([0.0, 0.0, -1.0], abs=1e-8)
    trt = json.loads((GOLDEN / "linuxcnc-trt" / "residual.json").read_text())
    for key, (r, _) in got.items():
        assert np.max(r) < 0.1 * trt[key]["residual"]["norm"]["max_um"], key


@pytest.mark.parametrize("kind", sorted(LOCATION))
def test_lines_are_corrected_and_zeros_named(tmp_path, kind) -> None:
    machine = MACHINE if kind == "xyzac-trt" else bc_machine(tmp_path)
    geom = load_machine(machine).five_axis.geometry
    tilt = geom.tilt
    zeros = {f"E{tilt}0{tilt}", "EC0C"}
    lines_only = FiveAxisErrors(location={k: v for k, v in LOCATION[kind].items()
                                          if k not in zeros})
    (tmp_path / "m.bin").write_bytes(write_five_blob(geom, lines_only))
    assert kin91(tmp_path / "o", tmp_path / "m.bin", machine) == 0
    got, _ = residual_from_files(tmp_path / "o", machine, lines_only)
    check_against_report(tmp_path / "o", got)
    for key, (r, u) in got.items():
        assert np.max(r) < 0.01, key
        assert np.max(u) > 10.0, key
    every = FiveAxisErrors(location=dict(LOCATION[kind]))
    (tmp_path / "z.bin").write_bytes(write_five_blob(geom, every))
    assert kin91(tmp_path / "z", tmp_path / "z.bin", machine) == 0
    rep = json.loads((tmp_path / "z" / "residual.json").read_text())
    assert {d["item"] for d in rep["not_held"]} == zeros


def test_bad_input_exits_2_and_writes_nothing(tmp_path, capsys) -> None:
    for opts, words in ((("c_index=3",), "both axis[3]"), (("tilt_index=1",), "3..5"),
                        (("trafo=10",), "trafo")):
        out = tmp_path / words.replace(" ", "_")
        assert kin91(out, MODEL, MACHINE, *opts) == 2
        assert words in capsys.readouterr().err
        assert not out.exists()
    assert kin91(tmp_path / "nomachine", MODEL, None) == 2
    assert not (tmp_path / "nomachine").exists()


@pytest.mark.parametrize("old, new", [("axis[3].type 2", "axis[3].type 1"),
                                      ("trafo[0].axis[4].point[2]", "trafo[1].axis[4].point[2]"),
                                      ("axis[3].orientation[1]", "axis[3].orientation[0]"),
                                      ("axis[4].point[0] ", "axis[4].point[0] x")])
def test_reader_refuses_a_broken_list(tmp_path, old, new) -> None:
    assert kin91(tmp_path / "o", MODEL) == 0
    text = (tmp_path / "o" / LIST).read_text()
    assert old in text
    (tmp_path / "b.lis").write_text(text.replace(old, new, 1))
    with pytest.raises(FormatError):
        read_isg_kin91(tmp_path / "b.lis")
