"""Laser CSV reader and step 1 (sign conversion): every bad input names file/line/field."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from abbe.errors import AbbeInputError
from abbe.formats.laser_csv import read_laser_csv, to_terms
from abbe.formats.machine import ChannelMap, LaserLine

from fit_helpers import lines_of, small_laser, write_lines


def test_reads_runs_directions_targets(tmp_path: Path) -> None:
    p = small_laser(tmp_path / "x.csv", n_runs=3)
    d = read_laser_csv(p, travel_mm=(0, 500))
    assert d.n_runs == 3
    np.testing.assert_array_equal(d.targets_mm, np.arange(0.0, 101.0, 10.0))
    assert d.channels["linear"].shape == (3, 2, 11)
    # Row order: run 1 '+' ascending (lines 2..12), then run 1 '-' descending (13..23).
    assert d.line_no[0, 0, 0] == 2 and d.line_no[0, 0, -1] == 12
    assert d.line_no[0, 1, -1] == 13 and d.line_no[0, 1, 0] == 23
    rows = lines_of(p)
    # the '-' pass reading at target 100 is line 13
    assert float(rows[12].split(",")[3]) == pytest.approx(d.channels["linear"][0, 1, -1], abs=1e-4)
    assert d.time_s is None and d.temp_c is None
    assert len(d.sha256) == 64


def test_sign_conversion_follows_the_map(tmp_path: Path) -> None:
    d = read_laser_csv(small_laser(tmp_path / "x.csv"))
    line = LaserLine("X", tmp_path / "x.csv", (0, 0, 0), (100, 0, 0),
                     {"linear": ChannelMap("linear", 1, "dx"), "yaw": ChannelMap("yaw", -1, "ez"),
                      "pitch": ChannelMap("pitch", -1, "ey")})
    t = to_terms(d, line)
    assert sorted(t) == ["dx", "ey", "ez"]
    np.testing.assert_array_equal(t["dx"], d.channels["linear"])
    np.testing.assert_array_equal(t["ez"], -d.channels["yaw"])
    np.testing.assert_array_equal(t["ey"], -d.channels["pitch"])


def test_only_linear_required_for_iso(tmp_path: Path) -> None:
    p = write_lines(tmp_path / "lin.csv", ["run,direction,target_mm,linear_um",
                                           "1,+,0,1", "1,+,10,2", "1,-,10,3", "1,-,0,4",
                                           "2,+,0,1", "2,+,10,2", "2,-,10,3", "2,-,0,4"])
    d = read_laser_csv(p, channels=("linear",))
    assert d.channels["linear"][1, 1].tolist() == [4.0, 3.0]
    with pytest.raises(AbbeInputError) as ei:
        read_laser_csv(p)  # the full reader needs all six channels
    assert ei.value.field == "straight_h_um" and ei.value.line == 1


def mutate(tmp_path: Path, fn) -> Path:
    p = small_laser(tmp_path / "x.csv")
    rows = lines_of(p)
    fn(rows)
    return write_lines(p, rows)


def cells(rows: list[str], i: int) -> list[str]:
    return rows[i].split(",")


def set_cell(rows: list[str], i: int, col: int, value: str) -> None:
    c = cells(rows, i)
    c[col] = value
    rows[i] = ",".join(c)


def swap(rows: list[str], i: int, j: int) -> None:
    rows[i], rows[j] = rows[j], rows[i]


BAD = [
    # name, mutation, expected line, field, message fragment
    ("misspelt column", lambda r: r.__setitem__(0, r[0].replace("pitch_urad", "pich_urad")),
     1, "pich_urad", "did you mean 'pitch_urad'"),
    ("missing column", lambda r: [r.__setitem__(i, ",".join(cells(r, i)[:8])) for i in range(len(r))],
     1, "roll_urad", "missing column"),
    ("duplicated column", lambda r: r.__setitem__(0, r[0].replace("straight_v_um", "roll_urad")),
     1, "roll_urad", "duplicated"),
    ("non-numeric cell", lambda r: set_cell(r, 5, 4, "1.2.3"), 6, "straight_h_um", "number"),
    ("empty cell", lambda r: set_cell(r, 5, 4, ""), 6, "straight_h_um", "number"),
    ("NaN", lambda r: set_cell(r, 7, 6, "nan"), 8, "pitch_urad", "finite"),
    ("Inf", lambda r: set_cell(r, 7, 8, "-inf"), 8, "roll_urad", "finite"),
    ("NaN target", lambda r: set_cell(r, 7, 2, "NaN"), 8, "target_mm", "finite"),
    ("bad run number", lambda r: set_cell(r, 3, 0, "one"), 4, "run", "expected an integer"),
    ("run zero", lambda r: set_cell(r, 3, 0, "0"), 4, "run", "in [1, 100]"),
    ("bad direction", lambda r: set_cell(r, 3, 1, "up"), 4, "direction", "'+' or '-'"),
    ("duplicated target", lambda r: set_cell(r, 4, 2, cells(r, 3)[2]), 5, "target_mm", "duplicated"),
    ("unsorted + pass", lambda r: swap(r, 4, 5), 6, "target_mm", "ascending"),
    ("unsorted - pass", lambda r: swap(r, 14, 15), 16, "target_mm", "descending"),
    ("unequal run counts (target missing)", lambda r: r.pop(40), 41, "target_mm",
     "expected target 40.0 mm here, got 30.0 mm"),
    ("unequal run counts (last target missing)", lambda r: r.pop(44), 44, "target_mm",
     "target 0.0 mm is missing"),
    ("unequal run counts (extra target)", lambda r: r.insert(45, r[44].replace(",0.000,", ",-5.000,")),
     46, "target_mm", "extra target -5.0 mm"),
    ("unequal run counts (other target)", lambda r: r.__setitem__(43, r[43].replace(",10.000,", ",5.000,")),
     44, "target_mm", "expected target 10.0 mm here, got 5.0 mm"),
    ("run without '-' pass", lambda r: [r.pop(56) for _ in range(11)], 46, "direction",
     "no '-' pass"),
    ("run numbering gap", lambda r: [set_cell(r, i, 0, "4") for i in range(45, 67)], 46, "run",
     "run 3 is missing"),
    ("split pass", lambda r: swap(r, 12, 24), 24, "run", "first block at line 13"),
    ("short row", lambda r: r.__setitem__(9, ",".join(cells(r, 9)[:5])), 10, None, "cells"),
]


@pytest.mark.parametrize("name,fn,line,field,frag", BAD, ids=[b[0] for b in BAD])
def test_bad_input_names_file_line_field(tmp_path: Path, name, fn, line, field, frag) -> None:
    p = mutate(tmp_path, fn)
    with pytest.raises(AbbeInputError) as ei:
        read_laser_csv(p)
    e = ei.value
    assert e.file == str(p), name
    assert e.line == line, (name, str(e))
    assert e.field == field, (name, str(e))
    assert frag in e.message, (name, str(e))


def test_target_outside_travel_and_span(tmp_path: Path) -> None:
    p = small_laser(tmp_path / "x.csv")
    with pytest.raises(AbbeInputError) as ei:
        read_laser_csv(p, travel_mm=(0.0, 90.0))
    assert ei.value.field == "target_mm" and ei.value.line == 12 and "travel" in ei.value.message
    with pytest.raises(AbbeInputError) as ei:
        read_laser_csv(p, span_mm=(100.0, 10.0))
    assert ei.value.line == 2 and "start..end" in ei.value.message


def test_map_channel_missing_from_file(tmp_path: Path) -> None:
    p = write_lines(tmp_path / "lin.csv", ["run,direction,target_mm,linear_um",
                                           "1,+,0,1", "1,+,10,2", "1,-,10,3", "1,-,0,4"])
    d = read_laser_csv(p, channels=("linear",))
    line = LaserLine("X", p, (0, 0, 0), (10, 0, 0), {"roll": ChannelMap("roll", 1, "ex")})
    with pytest.raises(AbbeInputError) as ei:
        to_terms(d, line)
    assert ei.value.field == "roll_urad" and ei.value.file == str(p) and ei.value.line == 1


def test_empty_and_missing_file(tmp_path: Path) -> None:
    p = write_lines(tmp_path / "e.csv", [])
    with pytest.raises(AbbeInputError) as ei:
        read_laser_csv(p)
    assert ei.value.file == str(p) and "header" in ei.value.message
    with pytest.raises(AbbeInputError) as ei:
        read_laser_csv(tmp_path / "none.csv")
    assert "cannot read" in ei.value.message
