"""Issue 36, values: the team suite's straightness truth in the catalogue's definition.

The independent generator (cases/independent) bends a straightness term by a sine arch of
sag b; the catalogue's straightness (abbe.diagnose.effects) is the sag of a parabola,
bow (1 - u²) over the axis' travel (Chebyshev T0 / T2). The scorer compares like with like:
the arch's least-squares parabola over the travel, sag 1.0306 b (docs/diagnose-validation.md, "Values
within their interval"); the twelfth round compared the arch's sag itself (`straightness_xy`
-2.553 for -2.271, outside)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import cases.independent.suite as S


def test_the_catalogue_sag_of_an_arch_is_its_least_squares_parabola() -> None:
    """Independently of the suite's quadrature: a dense uniform grid over a travel, the
    arch sin(pi s) fitted by constant + slope + the catalogue's own shape 1 - u²."""
    lo, hi = -120.0, 480.0
    p = np.linspace(lo, hi, 20001)
    s = (p - lo) / (hi - lo)
    u = 2.0 * s - 1.0
    A = np.stack([np.ones_like(u), u, 1.0 - u * u], axis=1)
    c, *_ = np.linalg.lstsq(A, 2.5 * np.sin(math.pi * s), rcond=None)
    assert S.arch_sag_in_catalogue(2.5) == pytest.approx(float(c[2]), rel=1e-4)
    assert S.arch_sag_in_catalogue(1.0) == pytest.approx(1.0306, abs=1e-4)


def test_the_suite_states_the_straightness_truth_in_that_definition(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The expected value of a straightness case goes through arch_sag_in_catalogue."""
    case = next(c for c in S.suite(665122612) if c.name == "straightness_xy")
    plain = S.build(case, tmp_path / "a").expected["straightness_xy"]
    monkeypatch.setattr(S, "arch_sag_in_catalogue", lambda b: 1000.0 * b)
    marked = S.build(case, tmp_path / "b").expected["straightness_xy"]
    assert marked / plain == pytest.approx(1000.0 / 1.0306279, rel=1e-6)
    assert plain == pytest.approx(-2.3400408, abs=1e-6)   # the twelfth round: the arch -2.2705
