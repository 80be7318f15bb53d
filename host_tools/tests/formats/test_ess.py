"""ESS ecmc ISO 230-2 .dat reader: the real file and every bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from abbe.errors import AbbeInputError
from abbe.formats.ess_dat import looks_like_dat, read_dat

from fit_helpers import ESS_DAT, write_lines
from real_data import needs_real_data


def small_dat(positions: int = 3, cycles: int = 2) -> list[str]:
    rows = ["# test file", "UNIT=mm", f"CYCLES={cycles}", f"POSITIONS={positions}", "DEC=4"]
    for i in range(1, positions + 1):
        rows.append(f"TGT_DATA[{i}]={10 * (i - 1)}")
    for d, off in (("FWD", 0.001), ("BWD", -0.002)):
        for c in range(1, cycles + 1):
            for i in range(1, positions + 1):
                rows.append(f"REF_DATA_{d}[{i},{c}]={10 * (i - 1) + off + 0.0001 * c}")
    return rows


@needs_real_data(ESS_DAT)
def test_real_file() -> None:
    d = read_dat(ESS_DAT)
    assert d.targets_mm.tolist() == [-20, -15, -10, -5, 0, 5, 10, 15, 20]
    assert d.up_um.shape == (5, 9) and d.down_um.shape == (5, 9)
    # REF_DATA_FWD[1,1] = -20.0492258741434944 mm -> -49.2258741434944 um
    assert d.up_um[0, 0] == pytest.approx(-49.2258741434944, abs=1e-9)
    assert d.down_um[4, 8] == pytest.approx(40.5726224096368, abs=1e-9)
    assert looks_like_dat(ESS_DAT)


def test_small_file_and_units(tmp_path: Path) -> None:
    d = read_dat(write_lines(tmp_path / "a.dat", small_dat()))
    np.testing.assert_allclose(d.up_um[:, 0], [1.1, 1.2])
    np.testing.assert_allclose(d.down_um[1], [-1.8] * 3)
    rows = [r.replace("UNIT=mm", "UNIT=um") for r in small_dat()]
    d = read_dat(write_lines(tmp_path / "b.dat", rows))
    assert d.targets_mm.tolist() == pytest.approx([0.0, 0.01, 0.02])  # 0, 10, 20 um
    assert d.up_um[0, 0] == pytest.approx(0.0011)


def test_descending_targets_are_reordered(tmp_path: Path) -> None:
    rows = small_dat()
    rows = [r.replace("TGT_DATA[1]=0", "TGT_DATA[1]=X").replace("TGT_DATA[3]=20", "TGT_DATA[1]=20")
            .replace("TGT_DATA[1]=X", "TGT_DATA[3]=0") for r in rows]
    d = read_dat(write_lines(tmp_path / "a.dat", rows))
    assert d.targets_mm.tolist() == [0.0, 10.0, 20.0]


def edit(rows: list[str], old: str, new: str | None) -> list[str]:
    out = []
    hit = False
    for r in rows:
        if r.startswith(old) and not hit:
            hit = True
            if new is not None:
                out.append(new)
        else:
            out.append(r)
    assert hit, old
    return out


BAD = [
    # name, old-line prefix, replacement (None deletes), line, field, fragment
    ("unknown key", "DEC=", "DECIMALS=4", 5, "DECIMALS", "unknown key"),
    ("no equals", "DEC=", "DEC 4", 5, None, "KEY=value"),
    ("malformed index", "TGT_DATA[2]", "TGT_DATA[2;1]=10", 7, "TGT_DATA[2;1]", "malformed"),
    ("non-numeric", "REF_DATA_FWD[2,1]", "REF_DATA_FWD[2,1]=ten", 10, "REF_DATA_FWD[2,1]",
     "number"),
    ("NaN", "REF_DATA_BWD[1,2]", "REF_DATA_BWD[1,2]=nan", 18, "REF_DATA_BWD[1,2]", "finite"),
    ("Inf target", "TGT_DATA[3]", "TGT_DATA[3]=inf", 8, "TGT_DATA[3]", "finite"),
    ("duplicated key", "TGT_DATA[3]", "TGT_DATA[2]=20", 8, "TGT_DATA[2]", "duplicated"),
    ("index outside", "REF_DATA_FWD[3,2]", "REF_DATA_FWD[3,3]=20", 14, "REF_DATA_FWD[3,3]",
     "outside"),
    ("missing reading", "REF_DATA_BWD[2,2]", None, None, "REF_DATA_BWD[2,2]", "unequal run"),
    ("missing target", "TGT_DATA[2]", None, None, "TGT_DATA[2]", "missing target"),
    ("unsorted targets", "TGT_DATA[2]", "TGT_DATA[2]=30", 8, "TGT_DATA[3]", "unsorted"),
    ("duplicated target", "TGT_DATA[3]", "TGT_DATA[3]=10", 8, "TGT_DATA[3]", "duplicated"),
    ("bad unit", "UNIT=", "UNIT=inch", 2, "UNIT", "unsupported unit"),
    ("bad cycles", "CYCLES=", "CYCLES=two", 3, "CYCLES", "expected an integer"),
]


@pytest.mark.parametrize("name,old,new,line,field,frag", BAD, ids=[b[0] for b in BAD])
def test_bad_dat(tmp_path: Path, name, old, new, line, field, frag) -> None:
    p = write_lines(tmp_path / "bad.dat", edit(small_dat(), old, new))
    with pytest.raises(AbbeInputError) as ei:
        read_dat(p)
    e = ei.value
    assert e.file == str(p), name
    assert e.line == line, (name, str(e))
    assert e.field == field, (name, str(e))
    assert frag in e.message, (name, str(e))
