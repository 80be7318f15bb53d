"""The .xlsx thermal record reader on sheets whose XML an exporter (or a corruption) wrote
unlike openpyxl would: findings of the long fuzz run (tests/formats/test_fuzz_recent_readers.py).

openpyxl's read-only row iterator trusts the sheet's ``<dimension ref=...>`` and the row
order: rows past the declared dimension, cells right of it, and a row numbered at or
below an earlier one were dropped without a word, and a broken sheet XML escaped as
ParseError / ValueError / TypeError instead of an AbbeInputError naming the file.
"""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import numpy as np
import pytest

from abbe.errors import AbbeInputError
from abbe.formats.thermal_record import read_thermal_xlsx

SHEET = "xl/worksheets/sheet1.xml"


@pytest.fixture(scope="module")
def seed(tmp_path_factory) -> Path:
    """Header + 5 rows (times 0..40 s), two displacement channels, written by openpyxl."""
    import openpyxl
    p = tmp_path_factory.mktemp("sheetxml") / "seed.xlsx"
    wb = openpyxl.Workbook()
    ws = wb.active
    ws.append(["time(s)", "spindle(RPM)", "t1(°C)", "ch1(um)", "ch2(um)"])
    for i in range(5):
        ws.append([i * 10.0, 1000, 20.0 + i * 0.1, i * 0.5, -i * 0.25])
    wb.save(p)
    assert b'<dimension ref="A1:E6"' in zipfile.ZipFile(p).read(SHEET)
    return p


def _variant(seed: Path, dest: Path, *edits: tuple[bytes, bytes]) -> Path:
    """The seed workbook with the sheet XML edited (each ``old`` must occur)."""
    src = zipfile.ZipFile(seed)
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as zo:
        for n in src.namelist():
            b = src.read(n)
            if n == SHEET:
                for old, new in edits:
                    assert old in b, old
                    b = b.replace(old, new, 1)
            zo.writestr(n, b)
    p = dest / "v.xlsx"
    p.write_bytes(out.getvalue())
    return p


def test_rows_past_a_too_small_dimension_are_read(seed, tmp_path):
    r = read_thermal_xlsx(_variant(seed, tmp_path, (b'ref="A1:E6"', b'ref="A1:E4"')))
    assert r.time_s.tolist() == [0.0, 10.0, 20.0, 30.0, 40.0] and r.rows.tolist() == [2, 3, 4, 5, 6]


def test_columns_right_of_a_too_narrow_dimension_are_read(seed, tmp_path):
    r = read_thermal_xlsx(_variant(seed, tmp_path, (b'ref="A1:E6"', b'ref="A1:D6"')))
    assert r.channel_names == ("ch1", "ch2")
    np.testing.assert_array_equal(r.disp_um[:, 1], [0.0, -0.25, -0.5, -0.75, -1.0])


@pytest.mark.parametrize("edits,row,words", [
    ([(b'<row r="6"', b'<row r="5"'), (b'r="A6"', b'r="A5"'), (b'r="B6"', b'r="B5"'),
      (b'r="C6"', b'r="C5"'), (b'r="D6"', b'r="D5"'), (b'r="E6"', b'r="E5"')],
     5, "row 5 comes after row 5"),
    # row 4 renumbered 9: rows 4-8 missing before it (openpyxl dropped 9 and everything after)
    ([(b'<row r="4"', b'<row r="9"')], 4, "empty row 4 between data rows"),
])
def test_a_row_repeated_or_out_of_order_is_refused(seed, tmp_path, edits, row, words):
    with pytest.raises(AbbeInputError) as e:
        read_thermal_xlsx(_variant(seed, tmp_path, *edits))
    assert e.value.file and e.value.line == row and words in str(e.value), str(e.value)


def test_a_cell_repeated_in_its_row_is_refused(seed, tmp_path):
    with pytest.raises(AbbeInputError) as e:
        read_thermal_xlsx(_variant(seed, tmp_path, (b'r="C3"', b'r="B3"')))
    assert e.value.line == 3 and e.value.field == "B" and "cell B3" in str(e.value), str(e.value)


@pytest.mark.parametrize("old,new", [
    (b"</row>", b"</rwo>"),                      # XML syntax: ParseError
    (b'<row r="3"', b'<row r="3x"'),             # a row number: ValueError
    (b'<c r="B4"', b'<c r="4B"'),                # a cell reference: ValueError
    (b"<sheetData>", b'<pageMargins bWttom="1"/><sheetData>'),  # TypeError inside openpyxl
])
def test_a_broken_sheet_xml_is_an_input_error(seed, tmp_path, old, new):
    with pytest.raises(AbbeInputError) as e:
        read_thermal_xlsx(_variant(seed, tmp_path, (old, new)))
    assert e.value.file and "\n" not in str(e.value) and "sheet" in str(e.value), str(e.value)
