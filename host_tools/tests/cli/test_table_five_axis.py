"""``abbe table info | eval | to-json | cgen`` read the format 1.2 five-axis tables abbe
writes (issue 33: they refused them as "newer than 1.1"). eval takes joint positions
X Y Z TILT C; its numbers are the float64 reference and, with --clib, the C library's."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from abbe.cli.entry import main
from abbe.formats.five_axis_blob import five_reference, read_five_blob, write_five_blob
from abbe.model import clib
from abbe.model.five_axis import FiveAxisErrors, TrunnionGeometry

GEOM = TrunnionGeometry("xyzbc-trt", (-40.0, 15.0, -280.0), (25.0, 0.0, -60.0), 100.0,
                        {"B": (-90.0, 90.0), "C": (-360.0, 360.0)})
ERRS = FiveAxisErrors({"EX0C": 30.0, "EY0C": -12.5, "EA0C": 41.0, "EZ0B": 7.25, "EC0B": -18.0},
                      {("C", "Z"): np.array([0.4, -0.2, 0.1, 0.05])}, (3.0, 0.0, -2.0))


@pytest.fixture()
def blob(tmp_path: Path) -> Path:
    p = tmp_path / "model_five.bin"
    p.write_bytes(write_five_blob(GEOM, ERRS))
    return p


def test_info_shows_the_rotary_section(blob: Path, capsys) -> None:
    assert main(["table", "info", str(blob)]) == 0
    out = capsys.readouterr().out
    assert "format 1.2" in out and "kinematics: xyzbc-trt" in out
    assert "EX0C 30.000000 um" in out  # 2^-8 nm steps: exact
    ea0c = float(re.search(r"EA0C (\S+) urad", out).group(1))
    assert ea0c == pytest.approx(41.0, abs=2e-5)  # 2^-36 rad steps
    assert "EZC(C) um: sin1 0.400000, cos1 -0.200000" in out


def _numbers(line: str) -> list[list[float]]:
    return [[float(v) for v in part.split()] for part in line.split("|")]


def test_eval_at_joint_positions(blob: Path, capsys) -> None:
    joints = [[120.0, -40.0, -180.0, 30.0, 45.0], [-60.0, 80.0, -250.0, -70.0, 300.0]]
    args = ["table", "eval", str(blob)] + [str(v) for j in joints for v in j]
    with_c = clib.available()
    assert main(args + (["--clib"] if with_c else [])) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 3
    pos, rot = five_reference(read_five_blob(blob.read_bytes()), np.array(joints)[:, :3],
                              np.array(joints)[:, 3:])
    assert np.abs(pos).max() > 5.0
    for i, line in enumerate(lines[1:]):
        parts = _numbers(line)
        assert parts[0] == joints[i]
        assert parts[1] == pytest.approx(pos[i], abs=1e-4)
        assert parts[2] == pytest.approx(rot[i], abs=1e-4)
        if with_c:
            assert parts[3] == pytest.approx(pos[i], abs=2e-3)
            assert parts[4] == pytest.approx(rot[i], abs=2e-3)


def test_eval_refuses_triples_for_a_five_axis_table(blob: Path, capsys) -> None:
    assert main(["table", "eval", str(blob), "1", "2", "3"]) == 2
    err = capsys.readouterr().err
    assert "X Y Z TILT C" in err and "3 numbers" in err


def test_to_json_holds_every_value(blob: Path, tmp_path: Path) -> None:
    out = tmp_path / "t.json"
    assert main(["table", "to-json", str(blob), "-o", str(out)]) == 0
    d = json.loads(out.read_text())
    rot = d["rotary"]
    assert rot["kinematics"] == "xyzbc-trt" and rot["rot_point_mm"] == pytest.approx([-40, 15, -280])
    for n, v in ERRS.location.items():
        axis = "C" if n.endswith("C") else "B"
        assert rot["axes"][axis]["location"][n] == pytest.approx(v, abs=1e-5)
    assert rot["axes"]["C"]["motions"]["EZC(C)"]["coef"]["cos2"] == pytest.approx(0.05, abs=1e-6)
    assert rot["squareness_urad"]["sxy"] == pytest.approx(3.0, abs=2e-5)  # 2^-36 rad steps
    assert "axes" in d and set(d["axes"]) == {"X", "Y", "Z"}  # the linear axes' table
    # from-json reads 3-axis tables only: the rotary key is refused, not dropped
    assert main(["table", "from-json", str(out), "-o", str(tmp_path / "back.bin")]) == 2
    assert not (tmp_path / "back.bin").exists()


def test_cgen_lists_the_rotary_section(blob: Path, tmp_path: Path) -> None:
    assert main(["table", "cgen", str(blob), "-o", str(tmp_path / "gen")]) == 0
    c = (tmp_path / "gen" / "abbe_model.c").read_text()
    assert "abbe_five_model_load" in c and "EX0C 30.000000 um" in c
    data = blob.read_bytes()
    assert f"const uint8_t abbe_model_blob[{len(data)}]" in c
    body = c.split("= {", 1)[1].split("};", 1)[0]
    assert bytes(int(v, 16) for v in body.replace(",", " ").split()) == data


@pytest.mark.parametrize("command", ["fit", "diagnose"])
def test_help_mentions_five_axis_machines(command: str, capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main([command, "--help"])
    assert exc.value.code == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "five-axis" in out and "[rotary]" in out
    assert "examples/trunnion5ax/machine.toml" in out
