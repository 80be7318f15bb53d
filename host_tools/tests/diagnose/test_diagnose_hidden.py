"""Proof on hidden effects: seeded virtual machines (abbe.sim.virtual_machine + abbe.sim.instruments) with
catalogue effects hidden in the truth and absent from the model; `abbe diagnose` must
name them (and nothing else), with values within 10 % or inside the 95 % interval, and
shrink the held-out gap. Clean machines must give "nothing is missing".

Small point counts (ballbar every 3 deg, 11 laser targets, 5 runs) keep the suite short;
the larger randomised run is host_tools/bench/bench_diagnose.py.
"""

from __future__ import annotations

import math

import pytest

from abbe.diagnose.selection import diagnose
from cases.hidden_effects import HIDDEN_KEYS, compatible, hidden_case

STEP_DEG = 3.0

SINGLES = [(k, 100 + i) for i, k in enumerate(HIDDEN_KEYS)]
PAIRS = [(("squareness_xy", "backlash_x"), 201), (("servo_mismatch_xy", "squareness_xy"), 202),
         (("cyclic_y", "straightness_yx"), 203), (("scale_z", "tool_offset"), 204),
         (("thermal_drift_x", "backlash_x"), 205), (("backlash_z", "squareness_yz"), 206)]
CLEAN = [301, 302, 303, 304, 305]


def _run(seed: int, keys: tuple[str, ...]):
    case = hidden_case(seed, keys, step_deg=STEP_DEG)
    return case, diagnose(case.model, case.checks)


def _check_named(case, res) -> None:
    named = {e.key: e for e in res.effects}
    assert set(named) == set(case.expected), (case.name, sorted(named), sorted(case.expected))
    for k, true in case.expected.items():
        e = named[k]
        if true is None or (k.startswith("thermal_drift") and e.unit != "um/K"):
            continue
        lo, hi = e.ci95
        assert abs(e.value - true) <= 0.1 * abs(true) or lo <= true <= hi, (k, e.value, true, e.ci95)
        assert not e.tentative
    # the gap shrinks on held-out data: the excess over the noise by >= 70 %
    b, a = res.gap["held_out_before"], res.gap["held_out_after"]
    assert b is not None and a is not None
    # noise floor: the estimated noise of the um-valued channels (ballbar, laser linear)
    sig = math.sqrt(sum(v["sigma"] ** 2 for v in res.noise.values() if v["unit"] == "um")
                    / max(1, sum(1 for v in res.noise.values() if v["unit"] == "um")))
    exc_b = math.sqrt(max(b.rms_um ** 2 - sig ** 2, 1e-12))
    exc_a = math.sqrt(max(a.rms_um ** 2 - sig ** 2, 0.0))
    assert a.rms_um < b.rms_um
    assert exc_a <= 0.3 * exc_b, (case.name, b.rms_um, a.rms_um)


@pytest.mark.parametrize("key,seed", SINGLES, ids=[k for k, _ in SINGLES])
def test_single_hidden_effect_is_named(key: str, seed: int) -> None:
    case, res = _run(seed, (key,))
    _check_named(case, res)


@pytest.mark.parametrize("keys,seed", PAIRS, ids=["+".join(k) for k, _ in PAIRS])
def test_pair_of_hidden_effects_is_named(keys: tuple[str, ...], seed: int) -> None:
    assert compatible(keys)
    case, res = _run(seed, keys)
    _check_named(case, res)


@pytest.mark.parametrize("seed", CLEAN)
def test_clean_machine_nothing_missing(seed: int) -> None:
    case, res = _run(seed, ())
    assert res.effects == []
    assert res.nothing_missing and not res.tentative
    assert any(n.startswith("Nothing is missing") for n in res.notes)
    d = res.to_json("m.bin")
    assert d["effects"] == []
    # the model is unchanged: the gap stays (noise only)
    assert abs(res.gap["after"].rms_um - res.gap["before"].rms_um) < 1e-6
