"""``abbe table thermal``: a thermal.json into a table (format 1.3), strip it again,
``abbe table info`` shows it; bad input exits 2 naming the file and field."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from abbe.cli.entry import main
from abbe.formats import golden
from abbe.formats.blob import write_blob
from abbe.formats.thermal_blob import read_thermal_blob
from abbe.model.thermal import ThermalChannel, ThermalInput, ThermalModel, ThermalTerm, as_dict


def _files(tmp_path: Path) -> tuple[Path, Path]:
    table = tmp_path / "model.bin"
    table.write_bytes(write_blob(golden.backlash_table()))
    m = ThermalModel(inputs=(ThermalInput("t1"), ThermalInput("s", kind="speed", reference=0.0,
                                                              valid_min=0.0, valid_max=9000.0,
                                                              max_step=9000.0)),
                     channels=(ThermalChannel("ch5", "z", (ThermalTerm(0, 300.0, 1.5),
                                                           ThermalTerm(1, 900.0, -2.0))),))
    tj = tmp_path / "thermal.json"
    tj.write_text(json.dumps(as_dict(m)))
    return table, tj


def test_put_strip_info(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    table, tj = _files(tmp_path)
    out = tmp_path / "t.bin"
    assert main(["table", "thermal", str(table), str(tj), "-o", str(out)]) == 0
    _, th = read_thermal_blob(out.read_bytes())
    assert th is not None and th.channels[0].terms[1].gain == -2.0
    assert main(["table", "info", str(out)]) == 0
    assert "thermal block (format 1.3): 2 inputs" in capsys.readouterr().out
    back = tmp_path / "s.bin"
    assert main(["table", "thermal", str(out), "--strip", "-o", str(back)]) == 0
    assert back.read_bytes() == table.read_bytes()


def test_bad_json_exits_2_naming_file_and_field(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    table, tj = _files(tmp_path)
    d = json.loads(tj.read_text())
    d["channels"][0]["terms"][0]["input"] = 7
    tj.write_text(json.dumps(d))
    out = tmp_path / "t.bin"
    assert main(["table", "thermal", str(table), str(tj), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "thermal.json" in err and "term input 7 out of range" in err
    assert not out.exists()
