"""The five-axis discrepancy workflow on hidden effects (cases.five_axis_hidden): a clean
machine gets no name, a worm-gear cyclic ECC and a pivot drift are named with their values."""

from __future__ import annotations

from pathlib import Path

import pytest

from abbe.analysis.five_axis.data import load_plan
from abbe.diagnose.five_axis import diagnose_five_axis
from abbe.formats.machine import load_machine
from cases.five_axis_hidden import make_case


@pytest.mark.parametrize("kind, seed", [("clean", 0), ("cyclic", 1), ("drift", 2)])
def test_hidden_effect_is_named(tmp_path: Path, kind: str, seed: int) -> None:
    mf, expected, amp = make_case(kind, seed, tmp_path)
    spec = load_machine(mf).five_axis
    diag = diagnose_five_axis(spec, load_plan(spec).blocks)
    names = [n.effect.key for n in diag.named]
    assert names == ([expected] if expected else []), diag.tried
    floor = diag.noise_floor_um
    assert floor is not None and floor > 0 and diag.to_json()["noise_floor_um"] == floor
    if expected:
        n = diag.named[0]
        assert abs(n.amplitude - amp) <= max(n.amplitude_ci95, 0.1 * amp)
        assert diag.final.heldout_after_um < diag.base.heldout_after_um
        assert "Named:" in diag.text() and diag.to_json()["named"][0]["effect"] == expected
        # the gap above the noise floor shrinks by more than the raw gap
        assert diag.excess_shrink is not None and diag.excess_shrink > diag.shrink
    else:
        assert diag.shrink == 0.0 and "Nothing named" in diag.text()
        # a clean machine's held-out gap is the sphere centres' noise, as the fits estimate it
        assert 0.8 * floor <= diag.base.heldout_after_um <= 1.4 * floor


@pytest.mark.parametrize("kind, seed", [("clean", 2), ("cyclic", 2)])
def test_independent_generator_cases(tmp_path: Path, kind: str, seed: int) -> None:
    """The same workflow on the independent generator's campaigns (never tuned on them)."""
    from cases.five_axis_independent import make_diagnose_campaign

    camp, expected, amp = make_diagnose_campaign(kind, seed)
    spec = load_machine(camp.write(tmp_path)).five_axis
    diag = diagnose_five_axis(spec, load_plan(spec).blocks)
    assert [n.effect.key for n in diag.named] == ([expected] if expected else [])
    if expected:
        assert abs(diag.named[0].amplitude - amp) <= max(diag.named[0].amplitude_ci95, 0.1 * amp)
