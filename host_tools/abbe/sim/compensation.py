"""Compensation in the loop: the C compensator correcting the virtual machine at 1 kHz.

The paper's §4 last step: run the circle again on the virtual machine with the
compensator correcting each interpolation cycle, and measure it with the
ballbar. Units: positions and corrections mm at the interface, nm inside the
compensator; radial deviations um.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Callable

import numpy as np

from abbe.formats.ballbar_csv import BallbarTrace
from abbe.model import clib
from abbe.model.geometry import CircleTest, circle_points, tangent_units
from abbe.sim.instruments import CircleTimeline, simulate_circle
from abbe.sim.virtual_machine import VirtualMachine

# Compensator settings for the virtual machine's 1 kHz interpolation cycle: the
# same safety layer a drive would run (limits, rate limit, fades, watchdog).
DEMO_COMP_CONFIG: dict[str, Any] = {
    "warn_nm": 30_000, "limit_nm": 100_000,   # 30 um warning, 100 um fault
    "rate_nm_per_cycle": 500,                 # 0.5 um per ms
    "fade_cycles": 500, "stale_cycles": 5, "axis_sign": 1,
}


def compensated_circle(truth_path: str | Path, test: CircleTest, blob: bytes, start_time_s: float,
                       noise_um: float, seed: int,
                       config: dict[str, Any] | None = None) -> tuple[BallbarTrace, dict[str, int]]:
    """Run ``test`` on the virtual machine of ``truth_path`` with the C compensator
    (model ``blob``) in the loop at 1 kHz, and measure it with the ballbar.

    Returns the measured trace and the compensator's counters.
    """
    from abbe.sim.compensation import ccompensator_step, run_circle_with_compensation
    from abbe.sim.truth import load_truth
    from abbe.sim.virtual_machine import VirtualMachine

    vm = VirtualMachine(load_truth(truth_path))
    comp = clib.CCompensator(config or DEMO_COMP_CONFIG)
    comp.load_model(blob)
    comp.enable()
    trace = run_circle_with_compensation(vm, test, ccompensator_step(comp), start_time_s=start_time_s,
                                         noise_um=noise_um, rng=np.random.default_rng(seed))
    return trace, comp.stats()


def campaign_test(truth_path: str | Path, name: str) -> tuple[CircleTest, float, float, float]:
    """The simulated test ``name`` as the campaign ran it (with its simulation
    settings), its end time (s), the gap between tests (s) and the ballbar noise (um)."""
    from abbe.errors import AbbeInputError
    from abbe.formats.limits import TRUTH_JSON_MAX_BYTES
    from abbe.formats.structured import load_json
    d, _ = load_json(truth_path, what="truth file", max_bytes=TRUTH_JSON_MAX_BYTES)
    try:
        entry = d["campaign"][f"ballbar.{name}"]
    except (KeyError, TypeError):
        raise AbbeInputError(f"no campaign entry for ballbar test {name!r}: not the truth file "
                             "of this campaign", file=str(truth_path),
                             field=f"campaign.ballbar.{name}") from None
    fields = {k: v for k, v in entry.items() if k not in ("start_s", "end_s")}
    for k in ("center_mm", "setup_offset_um"):
        if k in fields:
            fields[k] = tuple(fields[k])
    test = CircleTest(name=name, **fields)
    return test, float(entry["end_s"]), float(d.get("gap_s", 0.0)), float(d["noise"]["ballbar_um"])


CompensatorStep = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


def run_circle_with_compensation(vm: VirtualMachine, test: CircleTest,
                                 compensator_step: CompensatorStep, cycle_hz: float = 1000.0,
                                 start_time_s: float = 0.0, noise_um: float = 0.0,
                                 rng: np.random.Generator | None = None) -> BallbarTrace:
    """Run the circle with a compensator in the loop and measure it with the ballbar.

    Each interpolation cycle k (``cycle_hz``) the controller's nominal position
    q_k (mm), its per-axis direction of motion d_k (-1/0/+1) and the machine
    temperature T_k (3,) deg C go to ``compensator_step(q_k, d_k, T_k)``, which
    returns the correction (3,) mm added to the commanded axis positions for that
    cycle (zero-order hold); the drives follow with their servo lags.
    ``abbe.model.clib.CCompensator`` fits via :func:`ccompensator_step`.
    """
    rng = rng if rng is not None else np.random.default_rng(0)
    tl = CircleTimeline.of(test)
    ncyc = int(math.ceil(tl.t_end * cycle_hz)) + 1
    tk = np.arange(ncyc) / cycle_hz
    q = circle_points(test, tl.theta(tk))
    dirs = tangent_units(test.plane, tl.theta(tk)) * tl.theta_rate_sign(tk)[:, None]
    dirs[np.abs(dirs) < 1e-9] = 0.0
    dirs = np.sign(dirs).astype(np.int64)
    temps = np.repeat(vm.truth.temperature_c(start_time_s + tk)[:, None], 3, axis=1)
    corr = np.zeros((ncyc, 3))
    for k in range(ncyc):
        corr[k] = np.asarray(compensator_step(q[k], dirs[k], temps[k]), dtype=np.float64)
    return simulate_circle(vm, test, start_time_s, noise_um, rng, corr=corr, cycle_hz=cycle_hz)


def ccompensator_step(comp: Any) -> CompensatorStep:
    """Adapter: an enabled ``abbe.model.clib.CCompensator`` as a compensator_step (nm -> mm)."""
    def step(pos_mm: np.ndarray, dir_: np.ndarray, temp_c: np.ndarray) -> np.ndarray:
        out = comp.step_f32(pos_mm, temp_c, dir_)
        return np.asarray(out["corr_nm"], dtype=np.float64) * 1e-6
    return step


def model_compensator_step(model: Any) -> CompensatorStep:
    """An ideal compensator: correction = -E_model(q) (mm) from a Table / CModel / callable,
    direction state = the commanded direction of motion."""
    from abbe.model.evaluate import model_error_um

    def step(pos_mm: np.ndarray, dir_: np.ndarray, temp_c: np.ndarray) -> np.ndarray:
        e = model_error_um(model, np.asarray(pos_mm).reshape(1, 3),
                           np.asarray(dir_, dtype=np.float64).reshape(1, 3),
                           np.asarray(temp_c, dtype=np.float64).reshape(1, 3))
        return -e[0] * 1e-3
    return step
