"""The virtual five-axis machine of any kinematic chain (head-head, head-table, dual-rotary
table, trunnion) and its sphere instruments.

A :class:`VirtualChainMachine` holds a :class:`abbe.model.chain.KinematicChain`, hidden
errors (:class:`abbe.model.five_axis.FiveAxisErrors`), the calibration sphere's set-up
error (its true place on the table off its nominal one) and instrument noise:

* touch probe: the sphere's centre as the probing finds it - the machine position q
  (the linear axes' positions, as the trunnions' probe files hold them) at which the
  stylus tip, carried by the tool-side rotary axes, sits on the true sphere centre (the
  sphere fit's result: the radius and the stylus radius cancel in the centre), plus
  noise per axis;
* R-test: under tool-centre-point control the nest (three sensors on the spindle at
  ``tip_mm``, turned by the tool-side rotary axes with the spindle) reads the true
  sphere centre minus the true nest position in the nest's own frame (um), zeroed at
  the first reading, plus noise.

Units: mm, um, urad, degrees.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from abbe.model.chain import (KinematicChain, nominal_joints, tool_tip, tool_transform,
                              workpiece_transform)
from abbe.model.five_axis import LOCATION_ERRORS, FiveAxisErrors


@dataclass
class VirtualChainMachine:
    """A five-axis machine of any chain with hidden errors (see module)."""

    chain: KinematicChain
    errors: FiveAxisErrors
    sphere_offset_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    probe_noise_um: float = 0.0
    rtest_noise_um: float = 0.0
    seed: int = 0
    rng: np.random.Generator = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.rng = np.random.default_rng(self.seed)

    def true_centre(self, sphere_mm: np.ndarray, angles_deg: np.ndarray) -> np.ndarray:
        """(M, 3) true machine position (mm) of the sphere's centre at each angle pair."""
        ang = np.asarray(angles_deg, dtype=np.float64).reshape(-1, 2)
        s = np.asarray(sphere_mm, dtype=np.float64) + np.asarray(self.sphere_offset_mm)
        T = workpiece_transform(self.chain, self.errors, ang)
        return np.einsum("nij,j->ni", T[:, :3, :3], s) + T[:, :3, 3]

    def probe_centres(self, sphere_mm: tuple[float, float, float], angles_deg: np.ndarray,
                      tip_mm: tuple[float, float, float] = (0.0, 0.0, 0.0),
                      noise: bool = True) -> np.ndarray:
        """(M, 3) machine positions q (mm) that put the stylus tip on the sphere's centre
        (``noise``: plus the probe noise per axis, a sphere fit's centre noise)."""
        ang = np.asarray(angles_deg, dtype=np.float64).reshape(-1, 2)
        target = self.true_centre(np.asarray(sphere_mm), ang)
        q = nominal_joints(self.chain, np.asarray(sphere_mm)[None, :].repeat(len(ang), 0), ang,
                           tip_mm)
        for _ in range(4):  # the linear axes' error depends (weakly) on where q is
            q = q + (target - tool_tip(self.chain, self.errors, q, ang, tip_mm))
        if not noise:
            return q
        return q + self.rng.normal(0.0, self.probe_noise_um * 1e-3, q.shape)

    def rtest(self, sphere_mm: tuple[float, float, float], angles_deg: np.ndarray,
              tip_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
        """(M, 3) R-test readings (um, the nest's frame) along an angle path under TCP."""
        ang = np.asarray(angles_deg, dtype=np.float64).reshape(-1, 2)
        s = np.asarray(sphere_mm, dtype=np.float64)
        q = nominal_joints(self.chain, s[None, :].repeat(len(ang), 0), ang, tip_mm)
        nest = tool_tip(self.chain, self.errors, q, ang, tip_mm)
        d = (self.true_centre(s, ang) - nest) * 1e3
        R = tool_transform(self.chain, None, ang)[:, :3, :3]
        read = np.einsum("nji,nj->ni", R, d)
        read = read - read[0] + self.rng.normal(0.0, self.rtest_noise_um, read.shape)
        read[0] = 0.0
        return read


def random_location_errors(chain: KinematicChain, rng: np.random.Generator,
                           loc_um: float = 20.0, loc_urad: float = 50.0) -> FiveAxisErrors:
    """Location errors N(0, loc_um) for positions and N(0, loc_urad) for tilts and zeros."""
    loc = {n: float(rng.normal(0.0, loc_um if i < 2 else loc_urad))
           for ax in chain.rotaries for i, n in enumerate(LOCATION_ERRORS[ax])}
    return FiveAxisErrors(loc)


def sphere_plan(chain: KinematicChain, n_first: int = 5, n_second: int = 6) -> np.ndarray:
    """(n_first * n_second, 2) angle pairs (alphabetical axis order) over 80 % of the
    travel of each rotary axis (a full turn: equally spaced), the probing grid."""
    cols = []
    for ax, n in zip(chain.rotaries, (n_first, n_second)):
        lo, hi = chain.travel_deg[ax]
        if hi - lo >= 360.0:
            cols.append(np.arange(n) * 360.0 / n)
        else:
            lo, hi = max(lo, -90.0), min(hi, 90.0)
            mid, half = (lo + hi) / 2.0, (hi - lo) / 2.0 * 0.8
            cols.append(np.linspace(mid - half, mid + half, n))
    A, B = np.meshgrid(cols[0], cols[1], indexing="ij")
    return np.column_stack([A.ravel(), B.ravel()])


#: Probe directions (machine frame): the pole and six points at 20 degrees latitude.
_LAT = np.deg2rad(20.0)
_PHI = np.arange(6) * np.pi / 3.0
PROBE_DIRECTIONS = np.vstack([[0.0, 0.0, 1.0],
                              np.column_stack([np.cos(_LAT) * np.cos(_PHI),
                                               np.cos(_LAT) * np.sin(_PHI),
                                               np.full(6, np.sin(_LAT))])])


def write_chain_campaign(vm: VirtualChainMachine, out: Path, angles_deg: np.ndarray,
                         sphere_mm: tuple[float, float, float] = (50.0, 20.0, 30.0),
                         sphere_radius_mm: float = 12.5, stylus_radius_mm: float = 1.5,
                         tips_mm: tuple[tuple[float, float, float], ...] = ((0.0, 0.0, 0.0),),
                         heights_mm: tuple[float, ...] = (0.0,), rtest: bool = True,
                         name: str = "virtual chain machine", harmonics: int = 0,
                         sphere_shifts_mm: tuple[tuple[float, float, float], ...] = ((0.0, 0.0, 0.0),)
                         ) -> Path:
    """Simulate a campaign into ``out``: machine.toml ([chain], [probing.S<i>] per sphere
    height and stylus, [rtest.R1]), probe_<i>.csv (trigger points: the machine positions
    at which the stylus, carried by the tool-side axes, touches the sphere along
    :data:`PROBE_DIRECTIONS`; noise per point), rtest.csv, truth.json (location errors and
    error motions). ``harmonics`` > 0 writes ``[chain.fit] harmonics``; ``sphere_shifts_mm``
    places a sphere per shift and height (mm on the table: spheres at several radii).
    Returns the machine file's path."""
    import json

    from abbe.formats.chain import chain_toml
    from abbe.formats.five_axis import probe_csv, rtest_csv

    r1, r2 = vm.chain.rotaries
    out.mkdir(parents=True, exist_ok=True)
    ang = np.asarray(angles_deg, dtype=np.float64).reshape(-1, 2)
    lines = [f'[machine]\nname = "{name}"\n',
             "[axes.X]\ntravel_mm = [-500.0, 500.0]\n[axes.Y]\ntravel_mm = [-500.0, 500.0]\n"
             "[axes.Z]\ntravel_mm = [-600.0, 200.0]\n", "[reference]\npoint_mm = [0.0, 0.0, 0.0]\n",
             chain_toml(vm.chain)]
    reach = sphere_radius_mm + stylus_radius_mm
    k, t = 0, 0.0
    if harmonics:
        lines.append(f"[chain.fit]\nharmonics = {int(harmonics)}\n")
    places = [(sphere_mm[0] + d[0], sphere_mm[1] + d[1], sphere_mm[2] + d[2] + h)
              for d in sphere_shifts_mm for h in heights_mm]
    for s in places:
        for tip in tips_mm:
            k += 1
            centres = vm.probe_centres(s, ang, tip, noise=False)
            pos, ts, aa, pts = [], [], [], []
            for m in range(len(ang)):
                for n in PROBE_DIRECTIONS:
                    t += 4.0
                    pos.append(m)
                    ts.append(t)
                    aa.append(ang[m])
                    pts.append(centres[m] + n * reach
                               + vm.rng.normal(0.0, vm.probe_noise_um * 1e-3, 3))
            fn = f"probe_{k}.csv"
            (out / fn).write_text(probe_csv(r1, np.asarray(pos), np.asarray(ts), np.asarray(aa),
                                            np.asarray(pts), r2), encoding="utf-8")
            lines.append(f'[probing.S{k}]\nfile = "{fn}"\nsphere_mm = {list(map(float, s))!r}\n'
                         f"sphere_radius_mm = {sphere_radius_mm!r}\n"
                         f"stylus_radius_mm = {stylus_radius_mm!r}\n"
                         f"tip_mm = {list(map(float, tip))!r}\n")
    if rtest:
        r = vm.rtest(sphere_mm, ang)
        (out / "rtest.csv").write_text(rtest_csv(r1, t + 60.0 + np.arange(len(ang)), ang, r, r2),
                                       encoding="utf-8")
        lines.append(f'[rtest.R1]\nfile = "rtest.csv"\nsphere_mm = {list(map(float, sphere_mm))!r}\n')
    (out / "machine.toml").write_text("\n".join(lines), encoding="utf-8")
    truth = {"chain": vm.chain.name, "kind": vm.chain.kind,
             "location": {n: float(v) for n, v in vm.errors.location.items()},
             "motions": {f"{ax}.{c}": [float(v) for v in coef]
                         for (ax, c), coef in vm.errors.motions.items()},
             "sphere_offset_mm": list(vm.sphere_offset_mm),
             "probe_noise_um": vm.probe_noise_um, "rtest_noise_um": vm.rtest_noise_um}
    (out / "truth.json").write_text(json.dumps(truth, indent=2) + "\n", encoding="utf-8")
    return out / "machine.toml"

