"""Hidden-effect cases for the five-axis discrepancy workflow (abbe.sim.five_axis).

A virtual A/C or B/C trunnion with random location errors, set-up errors and noise
(as the identification tests), probed with the diagnosis plan (4 tilt x 8 C angles, run
twice: the second pass backwards with C half a step on, docs/programs.md), plus one hidden
effect the location-only model lacks: ``clean`` (none), ``cyclic`` (an angular
positioning error of C with k = 1..3 cycles per turn, 10-25 urad), ``drift``
(the tilt axis' line drifting 4-8 um/h in its second position coordinate while
the campaign runs) or ``wobble`` (a once-per-turn tilt error motion of C: a
counter-rotating part of 10-25 urad, what the diagnosis can see, plus a
co-rotating part of 0-25 urad it cannot). ``expected`` is the catalogue key the
diagnosis should name.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from abbe.model.five_axis import LOCATION_ERRORS, TrunnionGeometry
from abbe.sim.five_axis import VirtualFiveAxis, probing_positions, random_errors, write_campaign

KINDS = ("clean", "cyclic", "drift", "wobble")


def make_case(kind: str, seed: int, out: Path, passes: int = 2) -> tuple[Path, str | None, float]:
    """Write the case; (machine file, expected effect key or None, its true amplitude).
    ``passes`` = 1: the identification plan's single pass instead."""
    rng = np.random.default_rng(seed)
    mk = "xyzac-trt" if seed % 2 == 0 else "xyzbc-trt"
    tilt = "A" if mk == "xyzac-trt" else "B"
    off = (0.0, rng.uniform(-30, 30), rng.uniform(-120, -50)) if tilt == "A" else \
        (rng.uniform(-30, 30), 0.0, rng.uniform(-120, -50))
    g = TrunnionGeometry(mk, (rng.uniform(-100, 100), rng.uniform(-100, 100), -300.0), off,
                         120.0, {tilt: (-110.0, 110.0), "C": (-360.0, 360.0)})
    errs = random_errors(g, rng)
    drift: dict[str, float] = {}
    expected, amp = None, 0.0
    if kind == "cyclic":
        k = int(rng.integers(1, 4))
        amp = float(rng.uniform(10, 25))
        ph = rng.uniform(0, 2 * np.pi)
        c = np.zeros(2 * k)
        c[2 * k - 2], c[2 * k - 1] = amp * np.cos(ph), amp * np.sin(ph)
        errs.motions[("C", "C")] = c
        expected = f"cyclic C {k}"
    elif kind == "wobble":
        # (EAC, EBC) as a complex number f e^{i(C + pf)} + b e^{-i(C + pb)}; the product's
        # Fourier order [sin1, cos1]
        amp, f = float(rng.uniform(10, 25)), float(rng.uniform(0, 25))
        pf, pb = rng.uniform(0, 2 * np.pi, 2)
        errs.motions[("C", "A")] = np.array([-f * np.sin(pf) - amp * np.sin(pb),
                                             f * np.cos(pf) + amp * np.cos(pb)])
        errs.motions[("C", "B")] = np.array([f * np.cos(pf) - amp * np.cos(pb),
                                             f * np.sin(pf) - amp * np.sin(pb)])
        expected = "wobble C"
    elif kind == "drift":
        amp = float(rng.uniform(4, 8))
        drift = {LOCATION_ERRORS[tilt][1]: amp}
        expected = f"pivot drift {tilt}"
    vm = VirtualFiveAxis(g, errs, drift_per_h=drift, sphere_offset_mm=tuple(rng.normal(0, 0.05, 3)),
                         sphere_radius_error_mm=float(rng.normal(0, 0.002)),
                         pretravel_um=0.2, pretravel_lobe_um=0.2,
                         probe_noise_um=float(rng.uniform(0.2, 0.5)), seed=seed)
    r = rng.uniform(40, 90)
    u = rng.uniform(0, 2 * np.pi)
    mf = write_campaign(vm, out, positions=probing_positions(g, 4, 8, passes),
                        sphere_mm=(r * np.cos(u), r * np.sin(u), rng.uniform(20, 60)))
    return mf, expected, amp
