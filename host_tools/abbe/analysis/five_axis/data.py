"""The measurement files of a five-axis plan as identification blocks.

Probing files become sphere centres (:mod:`abbe.analysis.five_axis.spheres`);
positions whose fitted radius misses the certificate + stylus radius by more
than the tolerance are rejected and named (as a controller's cycle aborts).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from abbe.analysis.five_axis.problem import Block
from abbe.analysis.five_axis.spheres import SphereCentres, sphere_centres
from abbe.errors import AbbeInputError
from abbe.formats.five_axis import (BALLBAR_CALIBRATION_U_UM, RTEST_CALIBRATION_U_PCT,
                                   FiveAxisSpec, read_indexer, read_probe_points,
                                   read_rotary_ballbar, read_rtest)


@dataclass
class PlanData:
    """Blocks to fit, the sphere fits per probing and the rejected positions (name, number,
    fitted radius mm, expected mm)."""

    blocks: list[Block]
    spheres: dict[str, SphereCentres]
    rejected: list[tuple[str, int, float, float]]
    indexer_raw: dict[str, object]


def load_plan(spec: FiveAxisSpec) -> PlanData:
    """Read every file of the plan; AbbeInputError on bad files or too few good positions."""
    tilt = spec.geometry.tilt
    blocks: list[Block] = []
    spheres: dict[str, SphereCentres] = {}
    rejected: list[tuple[str, int, float, float]] = []
    raw: dict[str, object] = {}
    for name, pl in spec.probing.items():
        pts = read_probe_points(pl.file, tilt)
        nominal = pl.sphere_radius_mm + pl.stylus_radius_mm
        sc = sphere_centres(pts, nominal, pl.radius_tolerance_mm)
        spheres[name] = sc
        for i in np.flatnonzero(~sc.radius_ok):
            rejected.append((name, int(sc.position[i]), float(sc.radius_mm[i]), nominal))
        ok = sc.radius_ok
        if ok.sum() < 3:
            raise AbbeInputError(f"only {int(ok.sum())} probing positions pass the radius check "
                                 f"({nominal} mm +- {pl.radius_tolerance_mm} mm); at least 3 are "
                                 "needed", file=str(pl.file), field=f"probing.{name}")
        blocks.append(Block("probe", name, sc.angles_deg[ok], sc.centre_mm[ok],
                            np.asarray(pl.sphere_mm), time_s=sc.time_s[ok],
                            positions=sc.position[ok], noise_floor_um=sc.centre_noise_um(ok),
                            centre_cov_um2=sc.centre_cov_um2(ok)))
        if pl.datum_u_um is not None:
            # the sphere's declared place: its three set-up unknowns measured at 0 um with
            # the declared uncertainty (what fixes the frame the angular zeros turn)
            blocks.append(Block("datum", name, np.zeros((1, 2)), np.zeros((1, 3)),
                                np.asarray(pl.sphere_mm), sigma=float(pl.datum_u_um),
                                of=f"probe.{name}"))
    for name, rt in spec.rtest.items():
        tr = read_rtest(rt.file, tilt)
        blocks.append(Block("rtest", name, tr.angles_deg, tr.displacement_um,
                            np.asarray(rt.sphere_mm), time_s=tr.time_s,
                            calibration=("scale", RTEST_CALIBRATION_U_PCT, "class default")
                            if rt.calibration_U_pct is None else
                            ("scale", rt.calibration_U_pct, "declared")))
    for axis, ix in spec.indexer.items():
        runs = read_indexer(ix.file)
        raw[axis] = runs
        ang = np.column_stack([np.zeros(runs.target_deg.size), runs.target_deg])
        blocks.append(Block("indexer", axis, ang, runs.deviation_urad,
                            direction=runs.direction.astype(np.float64), sigma=5.0))
    for name, bb in spec.ballbar.items():
        tr = read_rotary_ballbar(bb.file, tilt)
        blocks.append(Block("ballbar", name, tr.angles_deg, tr.radial_um,
                            np.asarray(bb.table_ball_mm), time_s=tr.time_s,
                            tool_mm=np.asarray(bb.tool_ball_mm), setup=bb.setup,
                            calibration=("offset", BALLBAR_CALIBRATION_U_UM, "class default")
                            if bb.calibration_U_um is None else
                            ("offset", bb.calibration_U_um, "declared")))
    return PlanData(blocks, spheres, rejected, raw)
