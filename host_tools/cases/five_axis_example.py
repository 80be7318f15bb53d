"""Regenerate examples/trunnion5ax (the five-axis example machine) with abbe.sim.five_axis.

A/C trunnion (LinuxCNC xyzac-trt), hidden location errors and error motions (2
harmonics), sphere set-up errors, probe pre-travel residual, noise, a slow pivot
drift; probing 4 A x 8 C angles, an R-test path (C turning at A = 0, -45, -90) and
a laser + rotary indexer on C. The truth goes to truth/truth.json, apart from
the data.

    python -m cases.five_axis_example ../examples/trunnion5ax
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import numpy as np

from abbe.model.five_axis import TrunnionGeometry
from abbe.sim.five_axis import VirtualFiveAxis, probing_positions, random_errors, write_campaign


def generate(out: Path, seed: int = 2026) -> Path:
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
    mf = write_campaign(vm, out, positions=probing_positions(g, 4, 8), sphere_mm=(80.0, 0.0, 40.0),
                        rtest_path=path, indexer_targets=np.arange(0.0, 360.0, 15.0), harmonics=2,
                        name="trunnion5ax (virtual A/C trunnion)")
    (out / "truth").mkdir(exist_ok=True)
    shutil.move(str(out / "truth.json"), str(out / "truth" / "truth.json"))
    return mf


if __name__ == "__main__":
    generate(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("examples/trunnion5ax"))
