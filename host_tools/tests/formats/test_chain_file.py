"""The machine file's [chain]: read strictly (file, line, field, what was expected; the
CLI exits 2), written back by chain_toml, and a trunnion's [rotary] read as its chain."""

from __future__ import annotations

from pathlib import Path

import pytest

from abbe.cli.entry import main
from abbe.errors import AbbeInputError
from abbe.formats.chain import chain_toml
from abbe.formats.machine import load_machine

HEAD = """[machine]
name = "t"
[axes.X]
travel_mm = [-500.0, 500.0]
[axes.Y]
travel_mm = [-500.0, 500.0]
[axes.Z]
travel_mm = [-600.0, 200.0]
[reference]
point_mm = [0.0, 0.0, 0.0]
"""
CHAIN = """[chain]
name = "maxkins"
order = ["C", "X", "Y", "Z", "B"]
[chain.C]
direction = "+Z"
pivot_mm = [20.0, -10.0, -100.0]
travel_deg = [-3600.0, 3600.0]
[chain.B]
direction = "-Y"
pivot_mm = [0.0, 0.0, 150.0]
travel_deg = [-90.0, 90.0]
"""


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "machine.toml"
    p.write_text(HEAD + text, encoding="utf-8")
    return p


def test_chain_is_read(tmp_path: Path) -> None:
    c = load_machine(_write(tmp_path, CHAIN)).extra["chain"]
    assert c.name == "maxkins" and c.kind == "head-table"
    assert c.workpiece_side == ("C",) and c.tool_side == ("B",) and c.rotaries == ("B", "C")
    assert c.axis("B").direction == -1 and c.axis("B").pivot_mm == (0.0, 0.0, 150.0)
    assert c.travel_deg == {"C": (-3600.0, 3600.0), "B": (-90.0, 90.0)}
    assert c.location_names() == ("EX0B", "EZ0B", "EA0B", "EC0B", "EB0B",
                                  "EX0C", "EY0C", "EA0C", "EB0C", "EC0C")


def test_chain_round_trips(tmp_path: Path) -> None:
    c = load_machine(_write(tmp_path, CHAIN)).extra["chain"]
    again = load_machine(_write(tmp_path, chain_toml(c))).extra["chain"]
    assert again == c


def test_a_trunnion_file_is_read_as_its_chain(tmp_path: Path) -> None:
    (tmp_path / "probe.csv").write_text("position,t_s,a_deg,c_deg,x_mm,y_mm,z_mm\n")
    text = ('[rotary]\nkinematics = "xyzac-trt"\nx_rot_point_mm = 10.0\ny_rot_point_mm = 20.0\n'
            'z_rot_point_mm = -300.0\ny_offset_mm = 20.0\nz_offset_mm = -80.0\n'
            '[rotary.A]\ntravel_deg = [-110.0, 110.0]\n[rotary.C]\ntravel_deg = [-360.0, 360.0]\n'
            '[probing.S1]\nfile = "probe.csv"\nsphere_mm = [0.0, 0.0, 0.0]\n'
            'sphere_radius_mm = 12.5\n')
    c = load_machine(_write(tmp_path, text)).extra["chain"]
    assert [a.name for a in c.axes] == ["C", "A", "X", "Y", "Z"]
    assert c.axis("C").pivot_mm == (10.0, 20.0, -300.0)
    assert c.axis("A").pivot_mm == (10.0, 40.0, -380.0)
    with pytest.raises(AbbeInputError, match="not both"):
        load_machine(_write(tmp_path, text + CHAIN))


@pytest.mark.parametrize("edit, field, words", [
    (('order = ["C", "X", "Y", "Z", "B"]\n', ""), "chain", "missing required key 'order'"),
    (('["C", "X", "Y", "Z", "B"]', '["C", "X", "Y", "X", "B"]'), "chain.order",
     "each of X, Y, Z exactly once"),
    (('["C", "X", "Y", "Z", "B"]', '["X", "C", "Y", "Z", "B"]'), "chain.order", "next to each other"),
    (('["C", "X", "Y", "Z", "B"]', '["C", "X", "Y", "Z", "C"]'), "chain.order", "two different"),
    (('["C", "X", "Y", "Z", "B"]', '["C", "X", "Y", "Z", "B", "A"]'), "chain.order", "two different"),
    (('["C", "X", "Y", "Z", "B"]', '"CXYZB"'), "chain.order", "array of axis names"),
    (('direction = "-Y"', 'direction = "+Z"'), "chain.B.direction", 'expected "+Y" or "-Y"'),
    (('direction = "-Y"', 'direction = 1'), "chain.B.direction", 'expected "+Y" or "-Y"'),
    (("[-90.0, 90.0]", "[90.0, -90.0]"), "chain.B.travel_deg", "min < max"),
    (("[-90.0, 90.0]", "[-90.0, nan]"), "chain.B.travel_deg", "finite"),
    (("[0.0, 0.0, 150.0]", "[0.0, 150.0]"), "chain.B.pivot_mm", "array of 3"),
    (("[0.0, 0.0, 150.0]", "[0.0, inf, 150.0]"), "chain.B.pivot_mm", "finite"),
    (("[0.0, 0.0, 150.0]", "[0.0, 0.0, 1e9]"), "chain.B.pivot_mm", "in [-2147"),
    (("[chain.B]\n", "[chain.A]\n"), "chain.A", "unknown key"),
    (('name = "maxkins"', 'name = "maxkins"\ntool_lenght_mm = 3.0'), "chain.tool_lenght_mm",
     "unknown key"),
    (('direction = "-Y"', 'direction = "-Y"\npivot = 1'), "chain.B.pivot", "unknown key"),
    (('name = "maxkins"', 'name = "maxkins"\ntool_length_mm = -1.0'), "chain.tool_length_mm",
     "in [0"),
    (("[-90.0, 90.0]\n", "[-90.0, 90.0]\n[chain.fit]\nharmonics = 9\n"), "chain.fit.harmonics",
     "[0, 8]"),
    (("[-90.0, 90.0]\n", "[-90.0, 90.0]\n[chain.fit]\nharmonics = 2.0\n"),
     "chain.fit.harmonics", "integer"),
    (("[-90.0, 90.0]\n", "[-90.0, 90.0]\n[chain.fit]\nharmonic = 2\n"), "chain.fit.harmonic",
     "unknown key"),
    (("[-90.0, 90.0]\n", "[-90.0, 90.0]\n[chain.fit]\nfolds = 1\n"), "chain.fit.folds",
     "[2, 20]"),
])
def test_bad_chains_are_located(tmp_path: Path, edit, field, words) -> None:
    text = CHAIN.replace(*edit)
    assert text != CHAIN
    with pytest.raises(AbbeInputError) as ei:
        load_machine(_write(tmp_path, text))
    assert ei.value.field == field, str(ei.value)
    assert words in str(ei.value) and ei.value.line is not None


def test_missing_axis_section(tmp_path: Path) -> None:
    text = CHAIN.split("[chain.B]")[0]
    with pytest.raises(AbbeInputError, match=r"missing \[chain.B\]") as ei:
        load_machine(_write(tmp_path, text))
    assert ei.value.line is not None


def test_cli_refuses_a_bad_chain_with_exit_2(tmp_path: Path, capsys) -> None:
    p = _write(tmp_path, CHAIN.replace('direction = "-Y"', 'direction = "+X"'))
    assert main(["fit", str(p), "-o", str(tmp_path / "o"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "machine.toml:" in err and "chain.B.direction" in err


@pytest.mark.parametrize("kind, offset", [("xyzac-trt", (0.0, 20.0, -80.0)),
                                          ("xyzbc-trt", (15.0, 0.0, -60.0))])
def test_a_trunnion_written_as_a_chain_is_the_trunnion(kind: str, offset) -> None:
    """cases/five_axis_chains/trunnions/: the [chain] form reads to the chain the [rotary]
    form stands for."""
    from abbe.model.chain import trunnion_chain
    from abbe.model.five_axis import TrunnionGeometry

    from cases.chain_suite import CHAINS

    f = CHAINS / "trunnions" / f"{kind}.toml"
    tilt = "A" if kind == "xyzac-trt" else "B"
    g = TrunnionGeometry(kind, (100.0, 50.0, -300.0), offset, 0.0,
                         {tilt: (-110.0, 110.0), "C": (-360.0, 360.0)})
    assert load_machine(f).extra["chain"] == trunnion_chain(g)


def test_chain_fit_section_is_read(tmp_path: Path) -> None:
    """``[chain.fit]``: the error motions' highest harmonic and the diagnose folds (0 and 4
    without it)."""
    plans = load_machine(_write(tmp_path, CHAIN)).extra["chain_plans"]
    assert (plans.harmonics, plans.folds) == (0, 4)
    text = CHAIN + "[chain.fit]\nharmonics = 3\nfolds = 5\n"
    plans = load_machine(_write(tmp_path, text)).extra["chain_plans"]
    assert (plans.harmonics, plans.folds) == (3, 5)
