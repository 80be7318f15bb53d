"""Thermal records in: the real .xlsx, the CSV format, and the strict-reader promises."""

from __future__ import annotations

import numpy as np
import pytest

from abbe.errors import AbbeInputError
from abbe.formats.thermal_record import read_thermal_csv, read_thermal_record, read_thermal_xlsx

from thermal_helpers import REAL_XLSX


def test_real_xlsx_is_read_whole(real_record):
    r = real_record
    assert r.time_s.size == 11115 and r.row_kind == "row"
    assert r.rows[0] == 2 and r.rows[-1] == 11116          # sheet rows, header on row 1
    assert r.temp_names == tuple(f"t{k}" for k in range(1, 17))
    assert r.channel_names == ("ch1", "ch2", "ch3", "ch4", "ch5")
    assert r.time_s[0] == 0.0 and r.time_s[-1] == 166710.0
    assert np.all(np.diff(r.time_s) == 15.0)
    assert r.disp_um[0, 0] == pytest.approx(0.377452788)
    assert r.temps_c[-1, 15] == pytest.approx(27.2422846392133)
    assert set(np.unique(r.speed_rpm)) >= {0.0, 1250.0, 2500.0, 3750.0, 5000.0, 3500.0}


def test_csv_round_trip(real_record, tmp_path):
    p = tmp_path / "r.csv"
    p.write_text(real_record.to_csv())
    r = read_thermal_csv(p)
    assert r.rows[0] == 2 and r.time_s.size == real_record.time_s.size
    np.testing.assert_allclose(r.disp_um, real_record.disp_um, atol=1e-8)
    np.testing.assert_allclose(r.temps_c, real_record.temps_c, atol=1e-8)
    assert r.temp_names == real_record.temp_names


GOOD = "time_s,spindle_rpm,a_c,b_c,x_um\n0,0,20,21,0\n15,1000,20.1,21,0.5\n30,1000,20.2,21.1,0.9\n"


@pytest.mark.parametrize("text,line,field,words", [
    (GOOD.replace("20.1,21,0.5", "nan,21,0.5"), 3, "a_c", "nan"),
    (GOOD.replace("20.1,21,0.5", "20.1,21,inf"), 3, "x_um", "inf"),
    (GOOD.replace("20.1,21,0.5", "20.1,,0.5"), 3, "b_c", ""),
    (GOOD.replace("30,1000", "15,1000"), 4, "time", "increasing"),
    (GOOD.replace("x_um", "x_mm"), 1, "x_mm", "unknown column"),
    (GOOD.replace("20.2,21.1,0.9", "20.2,21.1"), 4, None, "cells"),
    (GOOD.replace("20,21,0", "20,999,0"), 2, "b_c", "200"),
])
def test_csv_errors_name_line_and_field(tmp_path, text, line, field, words):
    p = tmp_path / "bad.csv"
    p.write_text(text)
    with pytest.raises(AbbeInputError) as e:
        read_thermal_csv(p)
    assert e.value.file == str(p) and e.value.line == line
    if field:
        assert e.value.field == field
    assert words in str(e.value)


def _xlsx(path, rows):
    import openpyxl
    wb = openpyxl.Workbook()
    ws = wb.active
    for r in rows:
        ws.append(list(r))
    wb.save(path)


HEAD = ("時間(s) ", "spindle(RPM)", "ch1(um)", "t1(°C)")


def test_xlsx_small_good(tmp_path):
    p = tmp_path / "ok.xlsx"
    _xlsx(p, [HEAD, (0, 0, 0.1, 20.0), (15, 1250, "0.3", 20.5)])
    r = read_thermal_record(p)
    assert r.channel_names == ("ch1",) and r.temp_names == ("t1",)
    assert r.disp_um[:, 0].tolist() == [0.1, 0.3] and r.rows.tolist() == [2, 3]


@pytest.mark.parametrize("rows,row,field,words", [
    ([HEAD, (0, 0, 0.1, 20.0), (15, 0, None, 20.0)], 3, "ch1", "empty cell C3"),
    ([HEAD, (0, 0, 0.1, 20.0), (15, 0, "nan", 20.0)], 3, "ch1", "nan"),
    ([HEAD, (0, 0, 0.1, 20.0), (None, None, None, None), (30, 0, 0.1, 20.0)], 3, None, "empty row"),
    ([("time(s)", "spindle(RPM)", "ch1(mm)", "t1(°C)"), (0, 0, 0.1, 20.0)], 1, "ch1(mm)", "unit"),
    ([HEAD, (0, 0, 0.1, 20.0), (15, 0, 0.1, 500.0)], 3, "t1", "200"),
    ([HEAD, (0, 0, 0.1, 20.0), (0, 0, 0.1, 20.0)], 3, "time", "increasing"),
    ([HEAD, (0, 0, True, 20.0)], 2, "ch1", "number"),
    # a text cell with a no-break space is not the number (it was read as 0.3)
    ([HEAD, (0, 0, "0.3\u00a0", 20.0)], 2, "ch1", "ASCII"),
    ([HEAD, (0, 0, 0.1, "\u300020.5")], 2, "t1", "ASCII"),
])
def test_xlsx_errors_name_row_and_field(tmp_path, rows, row, field, words):
    p = tmp_path / "bad.xlsx"
    _xlsx(p, rows)
    with pytest.raises(AbbeInputError) as e:
        read_thermal_xlsx(p)
    assert e.value.file == str(p) and e.value.line == row
    if field:
        assert e.value.field == field
    assert words in str(e.value)


def test_not_a_workbook(tmp_path):
    p = tmp_path / "fake.xlsx"
    p.write_bytes(b"PK\x03\x04 not really")
    with pytest.raises(AbbeInputError, match="not a readable .xlsx"):
        read_thermal_record(p)


def test_real_file_is_where_the_project_carries_it():
    assert REAL_XLSX.is_file()


def test_xlsx_cell_beyond_the_header(tmp_path):
    p = tmp_path / "wide.xlsx"
    _xlsx(p, [HEAD, (0, 0, 0.1, 20.0), (15, 0, 0.2, 20.0, 99.0)])
    with pytest.raises(AbbeInputError) as e:
        read_thermal_xlsx(p)
    assert e.value.line == 3 and e.value.field == "E" and "beyond the header" in str(e.value)
