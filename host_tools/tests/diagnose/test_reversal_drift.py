"""A thermal drift beside a position-dependent reversal on ISO 230-2 positioning runs
(issue 36, tenth round: the team suite's `pos_reversal_drift` and `pos_ess_like`, seed
380921099, were named the backlash alone, "tentative").

Within each bidirectional cycle the forward pass reads the low targets early and the
backward pass reads them late, so a drift's column (the fractional cycle index) has a
part that depends on the position and the direction only, the same in every cycle: a
reversal's shape. With the reversal not yet named, the drift fitted on the early runs
took that part as a rate and failed on the late runs (held-out gain < 0), while the
reversal alone could not reach the evidence level beside the unmodelled drift (s² of
the lack of fit). A drift is judged beside the static effects of its axis
(docs/effects.md §3, drift and scale): its scale and its reversal, free in the base.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from abbe.diagnose.run import diagnose_positioning

TARGETS = np.linspace(-20.0, 20.0, 11)


def _runs(seed: int, slope_um: float, drift_um: float, noise_um: float = 1.2,
          backlash_um: float = -24.0, cycles: int = 5) -> np.ndarray:
    """(cycles, 2, T) deviations (um): a smooth positioning error, a total reversal
    B + slope u (u = target / 20 mm; forward minus backward), a drift growing with the
    fractional cycle index (the ESS .dat order: forward ascending, backward descending)
    and white noise."""
    rng = np.random.default_rng(seed)
    g = 25.0 * np.sin(TARGETS / 11.0) + 0.03 * TARGETS ** 2
    rev = backlash_um + slope_um * TARGETS / 20.0
    v = np.empty((cycles, 2, TARGETS.size))
    for c in range(cycles):
        for d in (0, 1):
            order = np.arange(TARGETS.size) if d == 0 else np.arange(TARGETS.size)[::-1]
            frac = c + 0.5 * d + (order.argsort() + 0.5) / (2.0 * TARGETS.size)
            s = 1.0 if d == 0 else -1.0
            v[c, d] = g + s * rev / 2.0 + drift_um * frac + rng.normal(0.0, noise_um, TARGETS.size)
    return v


def _dat(path: Path, v: np.ndarray) -> Path:
    lines = ["UNIT=mm", f"CYCLES={v.shape[0]}", f"POSITIONS={TARGETS.size}"]
    lines += [f"TGT_DATA[{i + 1}]={t:g}" for i, t in enumerate(TARGETS)]
    for c in range(v.shape[0]):
        for i, t in enumerate(TARGETS):
            lines.append(f"REF_DATA_FWD[{i + 1},{c + 1}]={t + v[c, 0, i] * 1e-3:.9f}")
            lines.append(f"REF_DATA_BWD[{i + 1},{c + 1}]={t + v[c, 1, i] * 1e-3:.9f}")
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("seed", [0, 1])
def test_reversal_and_drift_are_both_named(tmp_path: Path, seed: int) -> None:
    """Backlash 24 um, a reversal rising 8 um over the half travel, a drift of -3 um per
    cycle: the code before named the backlash alone (drift held-out gain -165 / -216)."""
    res = diagnose_positioning(_dat(tmp_path / "x.dat", _runs(seed, 8.0, -3.0)), "X")
    keys = {e.key: e for e in res.effects}
    assert set(keys) == {"backlash_x", "reversal_x", "thermal_drift_x"}
    assert not res.tentative
    # the drift is judged on the split in time (early / late runs) and holds there
    assert res.tested["thermal_drift_x"]["heldout_gain"] > res.tested["thermal_drift_x"]["heldout_need"]
    # the reversal's RMS over the targets (8 um x RMS of u about its mean)
    u = TARGETS / 20.0
    rv = keys["reversal_x"]
    assert rv.ci95[0] - 0.3 < 8.0 * float(np.std(u)) < rv.ci95[1] + 0.3


def test_reversal_without_drift_gets_no_drift(tmp_path: Path) -> None:
    """The static reversal freed beside the drift: no drift is named for it."""
    res = diagnose_positioning(_dat(tmp_path / "x.dat", _runs(2, 8.0, 0.0)), "X")
    assert {e.key for e in res.effects} == {"backlash_x", "reversal_x"}


def test_drift_without_reversal_is_still_named(tmp_path: Path) -> None:
    """A constant reversal (backlash) and a drift: the reversal freed in the drift's base
    does not take the drift away."""
    res = diagnose_positioning(_dat(tmp_path / "x.dat", _runs(3, 0.0, -3.0)), "X")
    assert {e.key for e in res.effects} == {"backlash_x", "thermal_drift_x"}
