"""Hidden-effect cases for proving ``abbe diagnose`` (tests and bench_diagnose.py).

A case is a virtual machine (:class:`abbe.sim.truth.MachineTruth`, evaluated with the
exact nonlinear kinematics of :class:`abbe.sim.virtual_machine.VirtualMachine`) with one or more
effects hidden in the truth, a model that lacks them (the truth's table without
those effects, optionally with a fit error added), and check measurements
generated from the truth with noise: ballbar traces (servo lag, backlash
direction state with take-up, time) and 6D laser lines (runs over time).

:func:`standard_checks` gives the geometry of the usual tests (ballbar in each
plane, laser line per axis) for a table, used to name the test that would
separate two ambiguous explanations.

Units: mm, um, urad, s, ms.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from abbe.diagnose.checks import BallbarCheck, Check, LaserChannel, LaserCheck
from abbe.model.geometry import PLANE_AXES
from abbe.model.table import AXES, TERMS, Table

TRAVEL_MM = {"X": (0.0, 500.0), "Y": (-400.0, 0.0), "Z": (-300.0, 0.0)}
REFERENCE_MM = (163.626, -212.772, -290.704)
CENTER_MM = (250.0, -200.0, -150.0)
#: Hidden-effect keys the generator knows (catalogue keys).
HIDDEN_KEYS: tuple[str, ...] = (
    "squareness_xy", "squareness_xz", "squareness_yz",
    "backlash_x", "backlash_y", "backlash_z",
    "scale_x", "scale_y", "scale_z",
    "cyclic_x", "cyclic_y", "cyclic_z",
    "thermal_drift_x", "thermal_drift_y", "thermal_drift_z",
    "servo_mismatch_xy", "servo_mismatch_yz", "servo_mismatch_zx",
    "tool_offset",
    "straightness_xy", "straightness_yx", "straightness_zx",
    "reversal_x", "reversal_y", "reversal_z",
)


def _shapes(rng: np.random.Generator, axis: str) -> dict[str, dict[str, Any]]:
    """Smooth, realistic error shapes of one axis (um / urad)."""
    out: dict[str, dict[str, Any]] = {}
    for t in TERMS:
        lin = t in ("dx", "dy", "dz")
        u = "um" if lin else "urad"
        amp = (4.0 if lin else 12.0) * rng.uniform(0.5, 1.5)
        sh: dict[str, Any] = {
            f"slope_{u}_per_m": float(rng.normal(0, amp * 2.0)),
            f"bow_{u}": float(rng.normal(0, amp * 0.5)),
            f"cantilever_{u}": float(rng.normal(0, amp * 0.3)),
            f"wave_{u}": [float(rng.normal(0, amp * 0.3)), float(rng.normal(0, amp * 0.15))],
            "wave_phase_deg": [float(rng.uniform(0, 360)), float(rng.uniform(0, 360))],
        }
        out[t] = sh
    return out


def build_truth(seed: int, effects: Any = None, extra_bow: dict[tuple[str, str], float] | None = None,
                cyclic: dict[str, tuple[float, float, float]] | None = None) -> Any:
    """A virtual machine: realistic smooth terms (seeded) + ``effects`` (abbe.sim.truth.Effects).

    extra_bow[(axis, term)] adds a bow (um) to a straightness term; cyclic[axis] =
    (amplitude um, period mm, phase deg) on the own positioning term.
    """
    from abbe.sim.truth import Effects, MachineTruth, build_axis
    rng = np.random.default_rng(seed)
    axes = {}
    for j, a in enumerate(AXES):
        sh = _shapes(rng, a)
        for (ax, term), b in (extra_bow or {}).items():
            if ax == a:
                sh[term] = dict(sh[term])
                sh[term]["bow_um"] = sh[term].get("bow_um", 0.0) + b
        cy = (cyclic or {}).get(a)
        axes[a] = build_axis(a, TRAVEL_MM[a], REFERENCE_MM[j], sh,
                             wave_period_mm=TRAVEL_MM[a][1] - TRAVEL_MM[a][0],
                             cyclic_um=0.0 if cy is None else cy[0],
                             cyclic_period_mm=10.0 if cy is None else cy[1],
                             cyclic_phase_deg=0.0 if cy is None else cy[2])
    return MachineTruth(name=f"virtual-{seed}", seed=seed, reference_mm=REFERENCE_MM,
                        tool_offset_mm=(0.0, 0.0, 0.0), axes=axes,
                        effects=effects if effects is not None else Effects())


def sim_ballbar(vm: Any, plane: str, t0_s: float, rng: np.random.Generator, *,
                noise_um: float = 0.15, step_deg: float = 2.0, name: str | None = None,
                radius_mm: float = 100.0, feed_mm_min: float = 1000.0,
                center_mm: tuple[float, float, float] = CENTER_MM) -> tuple[BallbarCheck, float]:
    """A ballbar check measured by the simulator's instrument (abbe.sim.instruments)."""
    from abbe.model.geometry import CircleTest
    from abbe.sim.instruments import circle_duration_s, simulate_ballbar
    setup = np.zeros(3)
    a, b = PLANE_AXES[plane]
    setup[[a, b]] = rng.normal(0.0, 3.0, 2)
    test = CircleTest(name=name or f"ballbar_{plane.lower()}", plane=plane,
                      center_mm=tuple(center_mm), radius_mm=radius_mm, feed_mm_min=feed_mm_min,
                      sample_deg=step_deg, feed_arc_deg=10.0, pause_s=1.0,
                      setup_offset_um=tuple(float(v) for v in setup))
    tr = simulate_ballbar(vm, test, t0_s, noise_um, rng, temp_sensor_k=0.01)
    ck = BallbarCheck(test.name, plane, test.center_mm, radius_mm, feed_mm_min, tr.direction,
                      tr.angle_deg, tr.radial_um, tr.time_s, vm.truth.reference_mm,
                      source="<simulated>", temp_c=tr.temp_c)
    return ck, circle_duration_s(test)


def sim_laser(vm: Any, axis: str, t0_s: float, rng: np.random.Generator, *,
              noise_um: float = 0.15, n_targets: int = 11, runs: int = 5,
              channels: tuple[str, ...] = ("linear", "straight_h", "straight_v"),
              with_time: bool = True, feed_mm_min: float = 200.0, dwell_s: float = 5.0) -> tuple[LaserCheck, float]:
    """A 6D laser line through the reference point measured by the simulator's instrument
    (ISO 230-2 cycle, targets evenly spaced over the travel minus 5 mm at each end)."""
    from abbe.sim.instruments import simulate_laser_line
    from abbe.sim.spec import DEFAULT_MAPS, LaserLinePlan, NoiseSpec
    j = AXES.index(axis)
    lo, hi = TRAVEL_MM[axis]
    lo, hi = lo + 5.0, hi - 5.0
    start = list(REFERENCE_MM)
    end = list(REFERENCE_MM)
    start[j], end[j] = lo, hi
    plan = LaserLinePlan(axis=axis, file="", start_mm=tuple(start), end_mm=tuple(end),
                         spacing_mm=(hi - lo) / (n_targets - 1), runs=runs, feed_mm_min=feed_mm_min,
                         dwell_s=dwell_s, overrun_mm=2.0, map=dict(DEFAULT_MAPS[axis]),
                         misalignment_urad=tuple(float(v) for v in rng.normal(0, 15.0, 2)))
    noise = NoiseSpec(laser_linear_um=noise_um, laser_straightness_um=noise_um * 1.5,
                      laser_angle_urad=0.3, ballbar_um=0.0,
                      repeatability_um=(noise_um, noise_um, noise_um), temp_sensor_k=0.01)
    run = simulate_laser_line(vm, plan, t0_s, noise, rng)
    tg = plan.targets_mm()
    T = tg.size
    n_r = plan.runs
    # rows are in measuring order: (run, +/-, target) -> (n_runs, 2, T) ascending targets
    order = np.zeros((n_r, 2, T), dtype=np.int64)
    k = 0
    for r in range(n_r):
        order[r, 0] = np.arange(k, k + T)
        order[r, 1] = np.arange(k + 2 * T - 1, k + T - 1, -1)
        k += 2 * T

    def grid(v: np.ndarray) -> np.ndarray:
        return np.asarray(v)[order]
    pm = plan.parsed_map()
    chans = [LaserChannel(ch, pm[ch][1], pm[ch][0], grid(run.channels[ch])) for ch in channels]
    ck = LaserCheck(f"laser_{axis}", axis, tuple(start), tg, chans, order, vm.truth.reference_mm,
                    time_s=grid(run.time_s) if with_time else None,
                    temp_c=None if run.temp_c is None else grid(run.temp_c),
                    source="<simulated>")
    return ck, run.duration_s


@dataclass
class Case:
    """One hidden-effect case: model (lacking the hidden effects), checks, expectation.

    expected: key -> true value in the diagnosis' units (None if not directly comparable).
    """

    name: str
    seed: int
    hidden: tuple[str, ...]
    model: Table
    checks: list[Check]
    expected: dict[str, float | None]
    truth: Any = None
    info: dict[str, Any] = field(default_factory=dict)


def _sign(rng: np.random.Generator) -> float:
    return float(rng.choice([-1.0, 1.0]))


def hidden_case(seed: int, hidden: tuple[str, ...] = (), *, noise_um: float = 0.15,
                model_error_um: float = 0.0, step_deg: float = 2.0, n_targets: int = 11,
                checks: tuple[str, ...] | None = None, takeup_mm: float = 0.1,
                feeds_mm_min: tuple[float, ...] = (1000.0,)) -> Case:
    """Build a case with the catalogue effects ``hidden`` (keys) in the truth only.

    Magnitudes are drawn at random (seeded) in realistic ranges (notes.md §7).
    ``checks``: names like "ballbar_xy", "laser_x" (default: the tests that see the
    hidden effects, plus one ballbar XY and laser X). ``takeup_mm``: the backlash
    take-up of the truth; ``feeds_mm_min``: every ballbar test is run at each of these
    feeds (the same circle; the second and later named ``..._f<feed>``).
    """
    from abbe.sim.truth import Effects, truth_table
    from abbe.sim.virtual_machine import VirtualMachine
    rng = np.random.default_rng(seed)
    kw: dict[str, Any] = {"backlash_takeup_mm": (takeup_mm, takeup_mm, takeup_mm)}
    expected: dict[str, float | None] = {}
    extra_bow: dict[tuple[str, str], float] = {}
    cyclic: dict[str, tuple[float, float, float]] = {}
    want_checks: list[str] = []
    thermal_axis = None
    reversal_hidden: list[tuple[int, list[float]]] = []
    for key in hidden:
        suf = key.rpartition("_")[2]
        if key.startswith("squareness_"):
            i = {"xy": 0, "xz": 1, "yz": 2}[suf]
            v = _sign(rng) * rng.uniform(12.0, 50.0)
            sq = list(kw.get("squareness_urad", (0.0, 0.0, 0.0)))
            sq[i] = v
            kw["squareness_urad"] = tuple(sq)
            expected[key] = v
            want_checks += [{"xy": "ballbar_xy", "xz": "ballbar_zx", "yz": "ballbar_yz"}[suf]]
        elif key.startswith("backlash_"):
            j = "xyz".index(suf)
            b = rng.uniform(3.0, 10.0)
            bl = list(kw.get("backlash_um", (0.0, 0.0, 0.0)))
            bl[j] = b
            kw["backlash_um"] = tuple(bl)
            expected[key] = float(b if j < 2 else -b)  # table reversal B = -sigma b
            want_checks += [f"laser_{suf}"]
        elif key.startswith("reversal_"):
            # a constant lost motion the model knows, and its variation along the travel
            # (odd Chebyshev shapes: zero mean over the symmetric laser targets) hidden
            j = "xyz".index(suf)
            b = rng.uniform(4.0, 10.0)
            bl = list(kw.get("backlash_um", (0.0, 0.0, 0.0)))
            bl[j] = b
            kw["backlash_um"] = tuple(bl)
            var = list(kw.get("backlash_variation_um", (0.0,) * 9))
            var[3 * j] = _sign(rng) * rng.uniform(2.0, 5.0)
            var[3 * j + 2] = _sign(rng) * rng.uniform(0.0, 2.0)
            kw["backlash_variation_um"] = tuple(var)
            reversal_hidden.append((j, var[3 * j:3 * j + 3]))
            want_checks += [f"laser_{suf}"]
        elif key.startswith("scale_"):
            j = "xyz".index(suf)
            k = _sign(rng) * rng.uniform(10.0, 30.0)
            sc = list(kw.get("scale_change_ppm", (0.0, 0.0, 0.0)))
            sc[j] = k
            kw["scale_change_ppm"] = tuple(sc)
            kw["scale_change_from_s"] = 0.0
            expected[key] = k
            want_checks += [f"laser_{suf}"]
        elif key.startswith("cyclic_"):
            a = suf.upper()
            amp = rng.uniform(1.0, 3.0)
            per = float(rng.choice([5.0, 6.0, 8.0, 10.0, 12.0, 16.0]))
            cyclic[a] = (amp, per, float(rng.uniform(0, 360)))
            expected[key] = amp
            want_checks += [{"X": "ballbar_xy", "Y": "ballbar_xy", "Z": "ballbar_yz"}[a]]
        elif key.startswith("thermal_drift_"):
            j = "xyz".index(suf)
            thermal_axis = AXES[j]
            kw["thermal_rise_k"] = rng.uniform(2.0, 4.0)
            kw["thermal_time_constant_s"] = 3600.0
            off = [0.0, 0.0, 0.0]
            exp_ = [0.0, 0.0, 0.0]
            off[j] = _sign(rng) * rng.uniform(1.5, 3.0)
            exp_[j] = rng.uniform(6.0, 12.0)
            kw["thermal_offset_um_per_k"] = tuple(off)
            kw["thermal_expansion_ppm_per_k"] = tuple(exp_)
            expected[key] = off[j]  # um/K when the checks carry a temperature
            want_checks += [f"laser_{suf}"]
        elif key.startswith("servo_mismatch_"):
            plane = suf.upper()
            a, b = PLANE_AXES[plane]
            dt = _sign(rng) * rng.uniform(0.5, 2.0)
            lag = list(kw.get("servo_lag_ms", (0.0, 0.0, 0.0)))
            lag[b] += dt
            kw["servo_lag_ms"] = tuple(lag)
            expected[key] = dt
            want_checks += [f"ballbar_{suf}"]
        elif key == "tool_offset":
            t = (0.0, 0.0, float(rng.uniform(80.0, 150.0)))
            kw["tool_offset_mm"] = t
            expected[key] = float(np.linalg.norm(t))
            want_checks += ["ballbar_xy", "ballbar_zx"]
        elif key.startswith("straightness_"):
            a, d = suf[0].upper(), "d" + suf[1]
            bow = _sign(rng) * rng.uniform(2.0, 5.0)
            extra_bow[(a, d)] = bow
            expected[key] = bow
            pl = "".join(sorted({a, suf[1].upper()}, key="XYZ".index))
            want_checks += [{"XY": "ballbar_xy", "YZ": "ballbar_yz", "XZ": "ballbar_zx"}[pl],
                            f"laser_{suf[0]}"]
        else:
            raise ValueError(f"unknown hidden effect {key!r}")
    eff_truth = Effects(**kw)
    truth = build_truth(seed, eff_truth, extra_bow, cyclic)
    # The model: the same machine without the hidden effects.
    model_truth = build_truth(seed, Effects(backlash_takeup_mm=(0.1, 0.1, 0.1),
                                            **{k: v for k, v in _visible(kw, hidden).items()}),
                              {k: v for k, v in extra_bow.items() if not _is_hidden_bow(k, hidden)},
                              {k: v for k, v in cyclic.items() if f"cyclic_{k.lower()}" not in hidden})
    model = truth_table(model_truth)
    if model_error_um > 0:
        model = _perturb(model, rng, model_error_um)
    if checks is None:
        names = sorted(set(want_checks + ["ballbar_xy", "laser_x"]))
    else:
        names = list(checks)
    vm = VirtualMachine(truth)
    out: list[Check] = []
    t_clock = 0.0
    # thermal: the laser of the drifting axis first, at campaign time 0; no ballbar in a
    # plane of that axis (its scale has changed by then: that would be a true scale error)
    if thermal_axis is not None:
        first = f"laser_{thermal_axis.lower()}"
        names = [first] + [n for n in names if n != first and not
                           (n.startswith("ballbar_") and thermal_axis.lower() in n[8:])]
    for nm in names:
        if nm.startswith("ballbar_"):
            for k, feed in enumerate(feeds_mm_min):
                ck, dur = sim_ballbar(vm, nm[8:].upper(), t_clock, rng, noise_um=noise_um,
                                      step_deg=step_deg, name=nm if k == 0 else f"{nm}_f{feed:g}",
                                      feed_mm_min=feed)
                out.append(ck)
                t_clock += dur + 60.0
        elif nm.startswith("laser_"):
            ck, dur = sim_laser(vm, nm[6:].upper(), t_clock, rng, noise_um=max(noise_um, 0.1),
                                n_targets=n_targets)
            out.append(ck)
            t_clock += dur + 60.0
        else:
            raise ValueError(f"unknown check {nm!r}")
    # Position-dependent reversal: RMS over the laser targets of the hidden part of the
    # reversal B_j(p) = -sigma_j b_j(p) (the table's sign, docs/formats.md)
    for j, c in reversal_hidden:
        a = AXES[j]
        tg = [ck.targets for ck in out if isinstance(ck, LaserCheck) and ck.axis == a]
        lo, hi = TRAVEL_MM[a]
        u = (2.0 * np.concatenate(tg) - lo - hi) / (hi - lo)
        part = np.polynomial.chebyshev.chebval(u, np.concatenate([[0.0], c]))
        expected[f"reversal_{a.lower()}"] = float(np.sqrt(np.mean(part ** 2)))
    # A lag on one axis shows in every tested plane containing it (tau_b - tau_a).
    lag = np.asarray(kw.get("servo_lag_ms", (0.0, 0.0, 0.0)), dtype=np.float64)
    if np.any(lag):
        for k in [k for k in expected if k.startswith("servo_mismatch_")]:
            del expected[k]
        for nm in names:
            if nm.startswith("ballbar_"):
                plane = nm[8:].upper()
                a, b = PLANE_AXES[plane]
                d = float(lag[b] - lag[a])
                if abs(d) > 1e-9:
                    expected[f"servo_mismatch_{plane.lower()}"] = d
    return Case(name="+".join(hidden) or "clean", seed=seed, hidden=tuple(hidden), model=model,
                checks=out, expected=expected, truth=truth,
                info={"checks": names, "noise_um": noise_um, "model_error_um": model_error_um})


def checks_for(key: str) -> set[str]:
    """The tests a case with hidden effect ``key`` includes (besides ballbar XY, laser X)."""
    suf = key.rpartition("_")[2]
    if key.startswith("squareness_"):
        return {{"xy": "ballbar_xy", "xz": "ballbar_zx", "yz": "ballbar_yz"}[suf]}
    if key.startswith(("backlash_", "reversal_", "scale_", "thermal_drift_")):
        return {f"laser_{suf}"}
    if key.startswith("cyclic_"):
        return {{"x": "ballbar_xy", "y": "ballbar_xy", "z": "ballbar_yz"}[suf]}
    if key.startswith("servo_mismatch_"):
        return {f"ballbar_{suf}"}
    if key == "tool_offset":
        return {"ballbar_xy", "ballbar_zx"}
    if key.startswith("straightness_"):
        pl = "".join(sorted({suf[0].upper(), suf[1].upper()}, key="XYZ".index))
        return {{"XY": "ballbar_xy", "YZ": "ballbar_yz", "XZ": "ballbar_zx"}[pl], f"laser_{suf[0]}"}
    raise ValueError(key)


def compatible(keys: tuple[str, ...]) -> bool:
    """A set of hidden effects the generator can test together: distinct, at most one
    thermal drift, and none whose test is a ballbar in a plane of the drifting axis (the
    generator leaves those out: by then the axis has a true scale change)."""
    th = [k for k in keys if k.startswith("thermal_drift_")]
    if len(th) > 1:
        return False
    if len(set(keys)) < len(keys):
        return False
    # a hidden reversal comes with a constant lost motion the model knows: not with a
    # hidden backlash of the same axis
    for k in keys:
        if k.startswith("reversal_") and f"backlash_{k[-1]}" in keys:
            return False
    if th:
        a = th[0][-1]
        for k in keys:
            if k in th:
                continue
            if any(c.startswith("ballbar_") and a in c[8:] for c in checks_for(k)):
                return False
    return True


def _visible(kw: dict[str, Any], hidden: tuple[str, ...]) -> dict[str, Any]:
    """Effects kwargs the model knows about (hidden ones removed)."""
    out = dict(kw)
    drop = set()
    for key in hidden:
        if key.startswith("squareness_"):
            drop.add("squareness_urad")
        elif key.startswith("backlash_"):
            # only the hidden axis' lost motion: a reversal case of another axis keeps its
            # constant lost motion in the model
            j = "xyz".index(key[-1])
            bl = list(out.get("backlash_um", (0.0, 0.0, 0.0)))
            bl[j] = 0.0
            out["backlash_um"] = tuple(bl)
        elif key.startswith("reversal_"):
            drop.add("backlash_variation_um")
        elif key.startswith("scale_"):
            drop |= {"scale_change_ppm", "scale_change_from_s"}
        elif key.startswith("thermal_drift_"):
            drop |= {"thermal_rise_k", "thermal_offset_um_per_k", "thermal_expansion_ppm_per_k",
                     "thermal_time_constant_s"}
        elif key.startswith("servo_mismatch_"):
            drop.add("servo_lag_ms")
        elif key == "tool_offset":
            drop.add("tool_offset_mm")
    out.pop("backlash_takeup_mm", None)
    return {k: v for k, v in out.items() if k not in drop}


def _is_hidden_bow(k: tuple[str, str], hidden: tuple[str, ...]) -> bool:
    a, term = k
    return f"straightness_{a.lower()}{term[1]}" in hidden


def _perturb(table: Table, rng: np.random.Generator, rms_um: float) -> Table:
    """Add a smooth random fit error (low Chebyshev rows) of about ``rms_um`` (linear) /
    ``3 x rms_um`` urad (angular) to every term."""
    import copy
    t = copy.deepcopy(table)
    for a in AXES:
        ax = t.axes[a]
        n = min(ax.n_trend(), 4)
        for term, c in ax.coef.items():
            s = rms_um if term in ("dx", "dy", "dz") else 3.0 * rms_um
            c = np.asarray(c, dtype=np.float64).copy()
            c[:n] += rng.normal(0, s / math.sqrt(max(n, 1)), n)
            ax.coef[term] = c
    return t
