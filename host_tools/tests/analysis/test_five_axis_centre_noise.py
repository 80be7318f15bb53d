"""The sphere-centre noise floor (SphereCentres.centre_noise_um) against a Monte Carlo of the
probing cycle: the floor the discrepancy workflow subtracts must be the centres' real scatter,
estimated from the points alone (no truth)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from abbe.analysis.five_axis.spheres import sphere_centres
from abbe.formats.five_axis import ProbePoints


def _cycle(n_side: int, elevation_deg: float) -> np.ndarray:
    """A controller's probing cycle: the pole and ``n_side`` points at one elevation."""
    e = math.radians(elevation_deg)
    u = np.arange(n_side) * 2 * math.pi / n_side
    side = np.column_stack([math.cos(e) * np.cos(u), math.cos(e) * np.sin(u),
                            np.full(n_side, math.sin(e))])
    return np.vstack([[0.0, 0.0, 1.0], side])


@pytest.mark.parametrize("n_side, elevation, sigma_um, pretravel_um",
                         [(4, 30.0, 0.5, 0.0), (6, 20.0, 0.3, 0.0), (8, 0.0, 0.8, 0.0),
                          (4, 30.0, 0.4, 1.0), (6, 20.0, 0.3, 0.6)])
def test_floor_matches_monte_carlo(n_side: int, elevation: float, sigma_um: float,
                                   pretravel_um: float) -> None:
    """With a direction-dependent pre-travel (the same at every position: the cycle's
    directions are machine-fixed) the residuals grow but the centres scatter no more; the
    floor takes the common pattern out and still matches the centres' real scatter."""
    rng = np.random.default_rng(n_side)
    dirs = _cycle(n_side, elevation)
    m = 400
    centres = rng.uniform(-200, 200, (m, 3))
    reach = 14.0
    pre = 1e-3 * pretravel_um * (dirs[:, 0] ** 2 - dirs[:, 1] ** 2 + 0.5 * dirs[:, 0])
    pts = (centres[:, None, :] + (reach - pre)[None, :, None] * dirs[None, :, :]
           + rng.normal(0.0, 1e-3 * sigma_um, (m, len(dirs), 3))).reshape(-1, 3)
    n = len(dirs)
    pp = ProbePoints(np.repeat(np.arange(m), n), np.arange(m * n, dtype=float),
                     np.zeros((m * n, 2)), pts, np.arange(m * n), "mc.csv")
    sc = sphere_centres(pp, reach, 0.01)
    assert sc.radius_ok.all() and (sc.n_points == n).all()
    floor = sc.centre_noise_um()
    dev = 1e3 * (sc.centre_mm - centres)
    real = float(np.sqrt(np.mean(np.sum((dev - dev.mean(axis=0)) ** 2, axis=1))))  # bias out
    # point noise is 3-D here but only its normal part moves a fit: the radial sigma is sigma
    assert floor == pytest.approx(real, rel=0.12), (floor, real)
    # a sparser cycle scatters the centre more than the point noise (the pole/radius trade)
    assert floor > sigma_um
    # the covariance per centre (the held-out floor's input) has the same trace
    cov = sc.centre_cov_um2()
    assert cov is not None and cov.shape == (m, 3, 3)
    assert float(np.sqrt(np.mean(np.trace(cov, axis1=1, axis2=2)))) == pytest.approx(floor,
                                                                                      rel=1e-9)
    if pretravel_um:
        raw = float(np.sqrt(np.sum(sc.n_points * sc.rms_um ** 2) / np.sum(sc.n_points - 4)))
        assert raw > 1.2 * sc.point_noise_um(), "the pattern must have inflated the residuals"


def test_no_floor_without_redundant_points() -> None:
    dirs = _cycle(3, 30.0)  # 4 points, 4 unknowns
    pts = np.vstack([14.0 * dirs, 14.0 * dirs + 1.0])
    pp = ProbePoints(np.repeat([0, 1], 4), np.arange(8, dtype=float), np.zeros((8, 2)), pts,
                     np.arange(8), "four.csv")
    assert sphere_centres(pp, 14.0, 0.01).centre_noise_um() is None
