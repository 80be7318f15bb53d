"""The ISG CSV and Etalon readers on arbitrary text: they return data or raise
AbbeInputError (file, field), nothing else; whatever they return is finite."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from fuzz_budget import DERANDOMIZE, examples

from abbe.errors import AbbeInputError
from abbe.formats.etalon import read_etalon
from abbe.formats.isg_csv import read_isg_csv

TOKENS = ["X", "Y", "Z", "A", "EXX", "EYX", "EZY", "EAZ", "C0Y", "B0Z", "A0Z", "C0B", "EQQ",
          "0", "1.5", "-2e-3", "nan", "inf", "1e999", "x1", "#", "//", "[EXX]", "[C0Y]",
          "Gridpoints", "=", "{", "}", "VALUE", ",", ";", "\t"]
lines = st.lists(st.lists(st.sampled_from(TOKENS), max_size=6).map(" ".join), max_size=25)


def _check(data) -> None:
    for c in data.curves.values():
        assert np.all(np.isfinite(c.pos_mm)) and np.all(np.isfinite(c.values))
        assert np.all(np.diff(c.pos_mm) > 0)
    if data.squareness_urad is not None:
        assert all(np.isfinite(data.squareness_urad))


@settings(max_examples=examples(300), deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=lines)
def test_readers_accept_or_refuse_cleanly(tmp_path, text) -> None:
    f = tmp_path / "f.txt"
    f.write_text("\n".join(text))
    for reader in (read_isg_csv, read_etalon):
        try:
            _check(reader(f))
        except AbbeInputError as exc:
            assert exc.file == str(f)
