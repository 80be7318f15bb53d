"""The period refinement's parabola (abbe.analysis.fit.scan) next to a frequency where the
model is inadmissible. A 3-harmonic model needs f <= 1 / (3 x samples per wavelength x
spacing); a wave just below that limit puts the zoomed grid's best point beside one whose
SSE is +inf, and the parabola's inf - inf made the frequency NaN: a 0/0 RuntimeWarning and
the paper's Fourier fit of the term reported as impossible ("none"). Found by the fit fuzz
test; 78 of 400 seeded waves of the case below did it before the guard."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from abbe.analysis.fit.options import FitOptions
from abbe.analysis.fit.scan import _parabola_shift, make_design, scan, search_period_each

POS = np.linspace(0.0, 500.0, 26)  # mm, 20 mm spacing


def _wave(seed: int, design) -> np.ndarray:
    """A wave (1st and 2nd harmonic, um) within 5 % of the 3-harmonic limit, noise 0.2 um."""
    rng = np.random.default_rng(seed)
    limit = 1.0 / (3 * design.samples_per_wavelength * design.spacing_mm)
    f = limit * (1 + rng.uniform(-0.05, 0.05))
    return (3.0 * np.sin(2 * np.pi * f * POS + rng.uniform(0, 6))
            + 0.5 * np.sin(4 * np.pi * f * POS) + rng.normal(0.0, 0.2, POS.size))


@pytest.mark.parametrize("seed", [0, 6, 7])  # seeds that gave None before the guard
def test_period_beside_an_inadmissible_frequency_is_kept(seed: int) -> None:
    design = make_design(POS, FitOptions())
    y = _wave(seed, design)[:, None]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the 0/0 of the old parabola fails here
        (f,) = search_period_each(design, POS, y, 0, 3)
    assert f is not None and np.isfinite(f)
    assert design.hmax(f) >= 3  # the 3-harmonic model is admissible at the answer
    # no worse than the best point of the coarse grid (the zooms only improve on it)
    coarse = scan(design, POS, y, design.freqs, (0,), 3, want_sse=True, want_cv=False)
    at_f = scan(design, POS, y, np.array([f]), (0,), 3, want_sse=True, want_cv=False)
    assert at_f.sse[0, 0, 3, 0] <= np.min(coarse.sse[:, 0, 3, 0]) * (1 + 1e-12)


def test_parabola_shift() -> None:
    # the vertex of e = (x - 0.3)^2 sampled at -1, 0, 1 (step 2 mm: -0.6 mm offset doubled)
    e = np.array([(x - 0.3) ** 2 for x in (-1.0, 0.0, 1.0)])
    assert _parabola_shift(e, 1.0) == pytest.approx(0.3)
    assert _parabola_shift(e, 2.0) == pytest.approx(0.6)
    assert _parabola_shift(np.array([1.0, 0.5, np.inf]), 1.0) == 0.0  # inadmissible neighbour
    assert _parabola_shift(np.array([np.inf, 0.5, np.inf]), 1.0) == 0.0
    assert _parabola_shift(np.array([1.0, 1.0, 1.0]), 1.0) == 0.0  # flat: no vertex
    assert _parabola_shift(np.array([0.0, 1.0, 0.0]), 1.0) == 0.0  # a maximum, not a minimum
