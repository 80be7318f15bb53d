"""The printer map readers (Klipper bed mesh, RepRapFirmware height map, skew CSV) under
the project's mutation operators: every mutated file is either read into finite values
of the documented shape or refused with an AbbeInputError naming the file; a hostile
number where a height stood is always refused."""

from __future__ import annotations

import numpy as np
from fuzzing.mutate import mutate, replace_number
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from fuzz_budget import DERANDOMIZE, examples

from abbe.errors import AbbeInputError
from abbe.formats.printer_maps import read_height_map, read_skew_csv

KLIPPER = """[printer]
kinematics: cartesian

#*# <---------------------- SAVE_CONFIG ---------------------->
#*# DO NOT EDIT THIS BLOCK OR BELOW. The contents are auto-generated.
#*#
#*# [bed_mesh default]
#*# version = 1
#*# points =
#*# \t  0.092500, 0.072500, 0.040000, 0.030000
#*# \t  0.022500, 0.020000, -0.030000, -0.007500
#*# \t  -0.017500, -0.002500, -0.057500, -0.030000
#*# x_count = 4
#*# y_count = 3
#*# min_x = 10.0
#*# max_x = 200.0
#*# min_y = 10.0
#*# max_y = 180.0
#*#
#*# [axis_twist_compensation]
#*# z_compensations = 0.0125, 0.005, -0.0175
#*# compensation_start_x = 20.0
#*# compensation_end_x = 183.0
""".encode()

RRF = b"""RepRapFirmware height map file v2 generated at 2026-12-04 10:00, min error -0.1, max error 0.1, mean 0.0, deviation 0.05
axis0,axis1,min0,max0,min1,max1,radius,spacing0,spacing1,num0,num1
X,Y,10.00,190.00,10.00,130.00,-1.00,60.00,60.00,4,3
  0.019,  0.028, -0.010,      0
  0.012,  0.000, -0.031,  0.044
 -0.008,  0.017,  0.022,  0.030
"""

SKEW = b"plane,ac_mm,bd_mm,ad_mm\nXY,141.22,141.15,100\nXZ,141.30,141.10,100\n"

SEEDS = {"printer.cfg": (KLIPPER, read_height_map), "heightmap.csv": (RRF, read_height_map),
         "skew.csv": (SKEW, read_skew_csv)}


def _check(result) -> None:
    for m in (result if isinstance(result, list) else [result]):
        if hasattr(m, "z_mm"):
            z = m.z_mm[np.isfinite(m.z_mm)]
            assert z.size >= 1 and np.all(np.abs(z) <= 50.0)
            assert m.z_mm.shape == (len(m.y_mm), len(m.x_mm))
            assert np.all(np.isfinite(m.x_mm)) and np.all(np.diff(m.x_mm) > 0)
        else:
            assert all(np.isfinite([m.ac_mm, m.bd_mm, m.ad_mm, m.tangent()]))


@settings(max_examples=examples(300), deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data(), name=st.sampled_from(sorted(SEEDS)), rounds=st.integers(1, 4))
def test_mutated_maps_read_or_refused(tmp_path, data, name, rounds):
    seed, reader = SEEDS[name]
    blob, _ = mutate(seed, lambda n: data.draw(st.integers(0, n - 1)) if n > 0 else 0, rounds)
    p = tmp_path / name
    p.write_bytes(blob)
    try:
        _check(reader(p))
    except AbbeInputError as exc:
        assert exc.file == str(p)


@settings(max_examples=examples(100), deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data(), name=st.sampled_from(sorted(SEEDS)))
def test_hostile_number_is_refused(tmp_path, data, name):
    seed, reader = SEEDS[name]
    blob = replace_number(seed, lambda n: data.draw(st.integers(0, n - 1)) if n > 0 else 0)
    p = tmp_path / name
    p.write_bytes(blob)
    try:
        reader(p)
    except AbbeInputError:
        return
    # a number replaced in a comment-free data file must be refused, unless it replaced a
    # number the reader does not read (the mesh 'version', the header's date)
    text = blob.decode("utf-8", "replace")
    assert "version" in text.split("points")[0] and name == "printer.cfg" or "generated at" in text
