"""The five-axis example (cases/five_axis_example.py: same machine, errors, seed and plan)
plus a second probing on a sphere 60 mm higher and 80 mm nearer the C axis (issue 37 item
5: "what the report says is needed"). Measured with it: EX0C goes from 20.6 +- 37.1 um
(U, k = 2) to -6.84 +- 1.23 um (truth -5.84) and EB0C becomes observable (-13.40 +- 2.87
urad, truth -13.38); EA0A, EY0C, EA0C, EC0C stay confounded with the spheres' y and z
positions: only a datum (a sphere position known in the workpiece frame) separates them
(``[probing.NAME] datum_u_um``: cases/five_axis_complete.py, the demo's plan). Writes into
``out``; returns the machine file."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from abbe.formats.five_axis import probe_csv
from abbe.model.five_axis import TrunnionGeometry
from abbe.sim.five_axis import VirtualFiveAxis, probing_positions, random_errors, write_campaign

#: The second sphere relative to the rotation point, mm (the first: (80, 0, 40)).
SECOND_SPHERE_MM = (0.0, 0.0, 100.0)


def example_campaign(out: Path, seed: int, name: str):
    """The five-axis example's machine and campaign (examples/trunnion5ax's plan) written to
    ``out``: returns the geometry, the virtual machine, the probing positions and the machine
    file. The cases that add a sphere (this one, five_axis_complete.py) start from it."""
    g = TrunnionGeometry("xyzac-trt", (0.0, 0.0, -350.0), (0.0, 25.0, -90.0), 110.0,
                         {"A": (-110.0, 110.0), "C": (-360.0, 360.0)})
    rng = np.random.default_rng(seed)
    errs = random_errors(g, rng, motion_um=1.0, motion_urad=4.0, harmonics=2)
    vm = VirtualFiveAxis(g, errs, drift_per_h={"EZ0A": 0.5}, sphere_offset_mm=(0.04, -0.02, 0.03),
                         sphere_radius_error_mm=0.0015, pretravel_um=0.2, pretravel_lobe_um=0.2,
                         probe_noise_um=0.4, rtest_noise_um=0.3, indexer_noise_urad=0.8,
                         rotary_backlash_urad=6.0, seed=seed)
    c = np.arange(0.0, 360.0, 10.0)
    path = np.vstack([np.column_stack([np.full(c.size, a), c]) for a in (0.0, -45.0, -90.0)])
    pos = probing_positions(g, 4, 8)
    mf = write_campaign(vm, out, positions=pos, sphere_mm=(80.0, 0.0, 40.0), rtest_path=path,
                        indexer_targets=np.arange(0.0, 360.0, 15.0), harmonics=2, name=name)
    return g, vm, pos, mf


def generate(out: Path, seed: int = 2026) -> Path:
    g, vm, pos, mf = example_campaign(out, seed, "trunnion5ax + a second sphere height")
    first = (out / "probe.csv").read_text().strip().splitlines()
    t_end = float(first[-1].split(",")[first[0].split(",").index("t_s")])
    sphere2 = tuple(float(v) for v in np.asarray(g.rot_point_mm) + np.asarray(SECOND_SPHERE_MM))
    p = vm.probe(sphere2, 12.5, 1.5, pos, t0_s=t_end + 60.0)  # type: ignore[arg-type]
    (out / "probe_S2.csv").write_text(probe_csv("A", p["position"], p["t_s"], p["angles_deg"],
                                                p["points_mm"]), encoding="utf-8")
    mf.write_text(mf.read_text() + f'\n[probing.S2]\nfile = "probe_S2.csv"\n'
                  f"sphere_mm = {list(sphere2)!r}\nsphere_radius_mm = 12.5\n"
                  "stylus_radius_mm = 1.5\n", encoding="utf-8")
    return mf


if __name__ == "__main__":
    generate(Path(sys.argv[1]))
