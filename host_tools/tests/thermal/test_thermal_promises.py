"""The promises (docs/formats.md, "Promises") of `abbe thermal` under hostile records, run
through the fuzzing harness: exit 2, one line naming FILE:LINE and the field, nothing
written, no traceback; every hostile number of the fuzzer refused in a record cell."""

from __future__ import annotations

import pytest
from fuzzing.mutate import HOSTILE_NUMBERS
from hostile import expect
from thermal_helpers import machine_text

HEAD = "time_s,spindle_rpm,T1_c,T2_c,T3_c,T4_c,chz_um"


def _record(rows: int = 400) -> list[str]:
    out = [HEAD]
    for k in range(rows):
        on = 1500 if (k * 900 // 3600) % 8 < 4 else 0
        out.append(f"{k * 900},{on},20.{k % 10},21,22,21,{0.01 * k:.2f}")
    return out


@pytest.mark.parametrize("cell", HOSTILE_NUMBERS)
def test_every_hostile_number_is_refused(tmp_path, cell):
    rows = _record()
    parts = rows[5].split(",")
    parts[6] = cell
    rows[5] = ",".join(parts)
    (tmp_path / "r.csv").write_text("\n".join(rows) + "\n")
    (tmp_path / "m.toml").write_text(machine_text("r.csv", {"chz": "z"}))
    out = tmp_path / "out"
    # a cell with the delimiter in it splits into two: the row's width is the error
    expect(["thermal", "fit", tmp_path / "m.toml", "-o", out], [out],
           where=f"{tmp_path / 'r.csv'}:6", field=None if "," in cell else "chz_um",
           text="cells" if "," in cell else None)


def test_missing_record_file(tmp_path):
    (tmp_path / "m.toml").write_text(machine_text("nope.csv", {"chz": "z"}))
    expect(["thermal", "evaluate", tmp_path / "m.toml"], where="nope.csv")


def test_duplicate_column(tmp_path):
    rows = _record()
    rows[0] = HEAD.replace("T4_c", "T3_c")
    (tmp_path / "r.csv").write_text("\n".join(rows) + "\n")
    (tmp_path / "m.toml").write_text(machine_text("r.csv", {"chz": "z"}))
    expect(["thermal", "evaluate", tmp_path / "m.toml"], where=f"{tmp_path / 'r.csv'}:1",
           text="twice")
