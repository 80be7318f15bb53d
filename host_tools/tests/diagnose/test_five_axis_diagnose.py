"""The five-axis discrepancy workflow on hidden effects (cases.five_axis_hidden): a clean
machine gets no name, a cyclic ECC, a pivot drift and a C wobble are named with their values;
what one sphere sees of each (docs/effects.md, section 7)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from abbe.analysis.five_axis.data import load_plan
from abbe.analysis.five_axis.problem import Param, errors_from
from abbe.diagnose.five_axis import diagnose_five_axis
from abbe.formats.machine import load_machine
from abbe.model.five_axis import motion_values
from cases.five_axis_hidden import make_case


@pytest.mark.parametrize("kind, seed", [("clean", 0), ("cyclic", 1), ("drift", 2),
                                        ("wobble", 3)])
def test_hidden_effect_is_named(tmp_path: Path, kind: str, seed: int) -> None:
    mf, expected, amp = make_case(kind, seed, tmp_path)
    spec = load_machine(mf).five_axis
    diag = diagnose_five_axis(spec, load_plan(spec).blocks)
    names = [n.effect.key for n in diag.named]
    assert names == ([expected] if expected else []), diag.tried
    floor = diag.noise_floor_um
    assert floor is not None and floor > 0 and diag.to_json()["noise_floor_um"] == floor
    hf = diag.base.heldout_floor_um
    assert hf is not None and hf >= floor  # the fold estimates' scatter adds to the noise
    if expected:
        n = diag.named[0]
        assert n.exact and not diag.to_json()["named"][0]["ambiguous_with"]
        assert abs(n.amplitude - amp) <= max(n.amplitude_ci95, 0.1 * amp)
        assert diag.final.heldout_after_um < diag.base.heldout_after_um
        assert "Named:" in diag.text() and diag.to_json()["named"][0]["effect"] == expected
        # the gap above what a right model shows shrinks by more than the raw held-out RMS
        assert diag.excess_shrink is not None and diag.excess_shrink > diag.shrink
        assert n.detectable < amp  # the plan could name it
        if expected == "cyclic C 1":
            # a once-per-turn ECC(C) moves an off-axis sphere by a constant (a shift of the C
            # line, EX0C / EY0C) plus a circle at twice the C rate, of equal size: the
            # location-only model takes half of its signature's energy
            assert 0.4 <= n.seen <= 0.6
    else:
        assert diag.shrink == 0.0 and "Nothing named" in diag.text()
        # a clean machine's held-out dispersion is what a right model shows on this plan
        assert 0.75 * hf <= diag.base.heldout_after_um <= 1.3 * hf


def test_wobble_parameters_are_the_counter_rotating_tilt() -> None:
    """wobble C x / y are the tilt (EAC, EBC)(C) = Rz(-C) (wx, wy): it turns against C."""
    ps = [Param("wobble C x", "wobble", "urad", 5.0, "C", "x", 1),
          Param("wobble C y", "wobble", "urad", 5.0, "C", "y", 1)]
    c = np.linspace(0.0, 330.0, 12)
    t = np.deg2rad(c)
    for v, want in (((1.0, 0.0), (np.cos(t), -np.sin(t))), ((0.0, 1.0), (np.sin(t), np.cos(t)))):
        m = motion_values(errors_from(ps, np.array(v), 0), "C", c)
        np.testing.assert_allclose(m[:, 3], want[0], atol=1e-12)
        np.testing.assert_allclose(m[:, 4], want[1], atol=1e-12)


@pytest.mark.parametrize("kind, seed", [("clean", 2), ("cyclic", 2), ("wobble", 1)])
def test_independent_generator_cases(tmp_path: Path, kind: str, seed: int) -> None:
    """The same workflow on the independent generator's campaigns (never tuned on them)."""
    from cases.five_axis_independent import make_diagnose_campaign

    camp, expected, amp = make_diagnose_campaign(kind, seed)
    spec = load_machine(camp.write(tmp_path)).five_axis
    diag = diagnose_five_axis(spec, load_plan(spec).blocks)
    assert [n.effect.key for n in diag.named] == ([expected] if expected else [])
    if expected:
        assert abs(diag.named[0].amplitude - amp) <= max(diag.named[0].amplitude_ci95, 0.1 * amp)


def test_catalogue_signatures_are_distinct(tmp_path: Path) -> None:
    """On a 4 x 8 one-sphere plan, one pass or the diagnosis plan's two, no candidate's
    signature (beyond the location errors) is reproduced by another's to the ambiguity
    level, in any phase; a one-cycle ECC keeps half of its signature, the others most of
    theirs except the drifts, whose share the second pass raises (in one pass campaign time
    follows the tilt and the location errors take most of a drift)."""
    import dataclasses

    from abbe.analysis.five_axis.identify import identify
    from abbe.analysis.five_axis.problem import build_params
    from abbe.diagnose.five_axis import _Signatures, catalogue

    from abbe.diagnose.five_axis import _tilt_one_way

    drift_seen = {}
    for passes in (1, 2):
        mf, _e, _a = make_case("clean", 1, tmp_path / f"p{passes}", passes)
        spec = load_machine(mf).five_axis
        spec = dataclasses.replace(spec, fit=dataclasses.replace(spec.fit, harmonics=0))
        blocks = load_plan(spec).blocks
        assert _tilt_one_way(blocks) == (passes == 1)  # the report's plan note
        base = identify(spec, blocks, build_params(spec, blocks))
        cands = catalogue(spec, 8 * passes, blocks)
        keys = {e.key for e in cands}
        assert {"cyclic C 1", "cyclic C 3", "pivot drift B", "wobble C"} <= keys
        assert ("cyclic C 4" in keys) == (passes == 2)  # 16 C angles resolve 4 per turn
        sig = _Signatures(spec, blocks, base, cands)
        for eff in cands:
            for ph in np.linspace(0.0, np.pi, 4, endpoint=False):
                v = np.array([np.cos(ph), np.sin(ph)])
                assert sig.ambiguity(eff, v, cands) == [], (eff.key, ph)
                seen = sig.seen(eff, v)
                if eff.key == "cyclic C 1":
                    assert 0.4 <= seen <= 0.6
                elif eff.key.startswith(("cyclic", "wobble")):
                    assert seen > 0.9, (eff.key, seen)
                else:
                    drift_seen.setdefault((passes, eff.key), []).append(seen)
    for key in ("pivot drift B", "pivot drift C"):
        one, two = np.mean(drift_seen[(1, key)]), np.mean(drift_seen[(2, key)])
        assert two > 1.5 * one, (key, one, two)


def test_heldout_beta_tells_a_confirmed_change_from_a_fitted_one() -> None:
    """heldout_beta: 1 when the held-out residuals lose exactly the change the effect makes
    to the predictions, about 0 when the change is unrelated to them (fitted to other
    positions' noise), NaN without a change."""
    from abbe.analysis.five_axis.identify import FitResult
    from abbe.diagnose.five_axis import heldout_beta

    rng = np.random.default_rng(5)
    noise = rng.normal(0.0, 1.0, (400, 3))
    signal = np.column_stack([np.sin(np.arange(400) / 7.0), np.cos(np.arange(400) / 5.0),
                              np.zeros(400)])

    def fit(r: np.ndarray) -> FitResult:
        return FitResult([], np.zeros(0), np.zeros(0), np.zeros((0, 0)), None, [], 0,  # type: ignore[arg-type]
                         heldout_residuals_um=r)

    before = fit(signal + noise)
    assert heldout_beta(before, fit(noise)) == pytest.approx(1.0, abs=0.1)
    spurious = rng.normal(0.0, 0.5, (400, 3))
    assert abs(heldout_beta(before, fit(signal + noise - spurious))) < 0.15
    assert np.isnan(heldout_beta(before, before))
    assert np.isnan(heldout_beta(before, fit(noise[:10])))  # not the same positions


def test_two_drifts_add(tmp_path: Path) -> None:
    """A drift candidate's two components move the sphere centres independently: the
    prediction with both is the base plus each one's own move (to the model's 1e-4
    linearity). Each move was once measured from the centre the other had already moved,
    which put a bilinear term as large as the drifts into the fit (a clean machine's C-line
    drift came out at 18 um/h with residuals of 30-47 um)."""
    from abbe.analysis.five_axis.problem import build_params, predict_block
    from abbe.diagnose.five_axis import catalogue

    mf, _e, _a = make_case("clean", 3, tmp_path)
    spec = load_machine(mf).five_axis
    blocks = load_plan(spec).blocks
    eff = next(e for e in catalogue(spec, 16, blocks) if e.key == "pivot drift C")
    params = build_params(spec, blocks) + list(eff.params)
    x0 = np.zeros(len(params))
    x0[:10] = np.linspace(-30.0, 40.0, 10)  # location errors (um, urad) of a real size
    b = next(b for b in blocks if b.kind == "probe")
    g, h = spec.geometry, spec.fit.harmonics
    base = predict_block(g, params, x0, h, b)
    moves = []
    for i in (len(params) - 2, len(params) - 1):
        x = x0.copy()
        x[i] = 20.0  # um/h
        moves.append(predict_block(g, params, x, h, b) - base)
    x = x0.copy()
    x[-2:] = 20.0
    both = predict_block(g, params, x, h, b) - base
    largest = max(float(np.max(np.abs(m))) for m in moves)
    assert largest > 5e-3  # mm: 20 um/h over the campaign moves the centres by micrometres
    np.testing.assert_allclose(both, moves[0] + moves[1], atol=1e-4 * largest)
