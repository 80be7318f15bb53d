"""Regenerate examples/trunnion5ax_complete: the five-axis demo's complete plan (issue 37
item 5). The machine, errors, seed and first campaign are cases/five_axis_example.py's
(probing sphere S1, R-test, laser + rotary indexer on C); added: a second probing on a
datum sphere D1 at a second height and off the C axis, its centre known in the workpiece
frame (a reference sphere in a calibrated location on the table, ``datum_u_um``).

Why each piece: the second height separates the C axis' tilt from its radial motion
(EX0C, EB0C; cases/five_axis_second_sphere.py); the datum fixes where the table frame is,
which the angular zeros (EA0A, EC0C) and the C axis' y line and tilt (EY0C, EA0C) turn or
shift and which the spheres' set-up unknowns absorb otherwise. The datum's true place
differs from the declared one by ``DATUM_ERROR_MM`` (within its uncertainty).

    python -m cases.five_axis_complete ../examples/trunnion5ax_complete
"""

from __future__ import annotations

import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

from abbe.formats.five_axis import probe_csv
from cases.five_axis_second_sphere import example_campaign

#: The datum sphere relative to the rotation point, mm: 100 mm above the table's pivot
#: height (S1: 40 mm) and 150 mm off the C axis, at 127 deg from S1.
DATUM_SPHERE_MM = (-90.0, 120.0, 100.0)
#: The datum's declared standard uncertainty (um) and where it truly is against that (mm).
DATUM_U_UM = 1.0
DATUM_ERROR_MM = (0.0008, -0.0010, 0.0005)


def generate(out: Path, seed: int = 2026) -> Path:
    g, vm, pos, mf = example_campaign(out, seed,
                                      "trunnion5ax complete (virtual A/C trunnion + datum sphere)")
    rt = (out / "rtest.csv").read_text().strip().splitlines()
    t_end = float(rt[-1].split(",")[rt[0].split(",").index("t_s")])
    # the same machine (errors, drift, probe) with the datum sphere on its table: its own
    # noise stream, its place off the declared one by DATUM_ERROR_MM
    vd = dataclasses.replace(vm, sphere_offset_mm=DATUM_ERROR_MM, seed=seed + 1)
    datum = tuple(float(v) for v in np.asarray(g.rot_point_mm) + np.asarray(DATUM_SPHERE_MM))
    p = vd.probe(datum, 12.5, 1.5, pos, t0_s=t_end + 120.0)  # type: ignore[arg-type]
    (out / "probe_D1.csv").write_text(probe_csv("A", p["position"], p["t_s"], p["angles_deg"],
                                                p["points_mm"]), encoding="utf-8")
    mf.write_text(mf.read_text() + f'\n[probing.D1]\nfile = "probe_D1.csv"\n'
                  f"sphere_mm = {list(datum)!r}\nsphere_radius_mm = 12.5\n"
                  f"stylus_radius_mm = 1.5\ndatum_u_um = {DATUM_U_UM!r}\n", encoding="utf-8")
    truth = json.loads((out / "truth.json").read_text(encoding="utf-8"))
    # the datum's true place against its declaration (the other spheres': sphere_offset_mm)
    truth["datum"] = {"D1": {"declared_mm": list(datum), "true_offset_mm": list(DATUM_ERROR_MM),
                             "declared_u_um": DATUM_U_UM}}
    (out / "truth").mkdir(exist_ok=True)
    (out / "truth" / "truth.json").write_text(json.dumps(truth, indent=2) + "\n",
                                              encoding="utf-8")
    (out / "truth.json").unlink()
    return mf


if __name__ == "__main__":
    generate(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("../examples/trunnion5ax_complete"))
