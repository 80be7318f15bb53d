"""The independent suite: cases, their files, the expected answers, and the score.

:func:`suite` lists the cases (seeded): single effects of every family in shapes of
this generator's own (see :mod:`.physics`), pairs that are hard to tell apart,
clean machines, and ISO 230-2 positioning files (ESS ``.dat``) with constant and
position-dependent reversal, drift and start-up outliers. :func:`build` writes a
case's files into a directory; :func:`run` diagnoses them through the product's
entry points (readers included); :func:`score` compares with the truth.

Expected answers (keys of the diagnose catalogue) and values in the diagnosis'
units: squareness urad, backlash B = mean(+) - mean(-) of the own term (um, -b
here), scale ppm (and bow um), cyclic amplitude um, thermal offset um/K (only with
a temperature), servo mismatch tau_b - tau_a ms per tested plane (a, b) = XY, YZ, ZX,
tool offset norm mm, straightness bow um in the catalogue's definition (the sag of the
least-squares parabola over the axis' travel, :func:`arch_sag_in_catalogue`: this
generator's sine arch of sag b has the catalogue sag 1.0306 b), position-dependent
reversal: RMS over the
targets of its part about the mean (um). A scale seen only on one XY circle may be
named on either axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cases.independent import files
from cases.independent.measure import (
    PLANE_AXES,
    CirclePlan,
    LaserPlan,
    default_map,
    measure_circle,
    measure_laser,
    positioning_runs,
)
from cases.independent.physics import (
    AXES,
    TERM_NAMES,
    LostMotion,
    Machine,
    Servo,
    Thermal,
    random_machine,
    random_term,
)

#: effect families of the machine cases (one per single case, cycled)
SINGLES: tuple[str, ...] = (
    "squareness_xy", "squareness_xz", "squareness_yz",
    "backlash_x", "backlash_y", "backlash_z", "backlash_play", "backlash_long", "backlash_asym",
    "scale_x", "scale_y", "scale_z", "scale_bow", "scale_xy_only",
    "cyclic_x", "cyclic_y", "cyclic_z",
    "thermal_lin", "thermal_exp", "thermal_time",
    "servo_delay", "servo_first_order", "servo_two_feeds",
    "tool_offset", "tool_offset_zx",
    "straightness_xy", "straightness_yx", "straightness_zx",
)
PAIRS: tuple[tuple[str, str], ...] = (
    ("squareness_xy", "servo_delay"), ("backlash_x", "squareness_xy"),
    ("thermal_lin", "scale_x"), ("tool_offset", "squareness_xy"), ("tool_offset", "scale_x"),
    ("cyclic_y", "straightness_yx"), ("backlash_z", "squareness_yz"),
)
#: issue 24's mechanisms (appended after the others so every earlier case keeps its
#: seed): a drift that is not linear in time (it rises and falls), scale and drift
#: together, backlash beside scale, and laser lines with tens of urad of roll on a short
#: axis (its effect: a clean machine whose table must still be fitted and stored)
EXTENDED_SINGLES: tuple[str, ...] = ("thermal_rise_fall", "thermal_rise_fall_time", "roll_short_z")
EXTENDED_PAIRS: tuple[tuple[str, str], ...] = (
    ("thermal_exp", "scale_y"), ("thermal_time", "scale_z"), ("thermal_rise_fall", "scale_x"),
    ("backlash_x", "scale_y"), ("backlash_y", "scale_y"), ("backlash_x", "scale_x"),
    ("roll_short_z", "backlash_z"), ("roll_short_z", "scale_z"),
)
POSITIONING: tuple[str, ...] = (
    "pos_backlash", "pos_backlash_drift", "pos_reversal", "pos_reversal_drift",
    "pos_outlier", "pos_noisy_cycle", "pos_clean", "pos_ess_like",
)


@dataclass
class CaseDef:
    name: str
    seed: int
    parts: tuple[str, ...]
    kind: str = "machine"   # or "positioning"


@dataclass
class Built:
    case: CaseDef
    dir: Path
    expected: dict[str, float | None]
    either: list[set[str]] = field(default_factory=list)   # alternatives counted as one answer
    #: key -> {parameter name: true value} (parameters besides the headline value)
    params: dict[str, dict[str, float]] = field(default_factory=dict)
    #: key -> {shape name: true value} (take-up mm, servo tau_mean ms): reported, not scored
    shapes: dict[str, dict[str, float]] = field(default_factory=dict)
    outlier_runs: set[int] = field(default_factory=set)
    info: dict[str, Any] = field(default_factory=dict)
    #: key -> the effect's true size on the diagnosis' own size basis (um), where computed:
    #: a thermal drift's (:func:`_drift_seen_um`); see :func:`unobservable`
    seen_um: dict[str, float] = field(default_factory=dict)
    machine_file: Path | None = None
    model_file: Path | None = None
    dat_file: Path | None = None


def suite(seed: int = 14, n_clean: int = 12, extended: bool = True) -> list[CaseDef]:
    """Every case of the suite, deterministic in ``seed``; ``extended``: with issue 24's
    cases (named ``x_...``) after the others."""
    rng = np.random.default_rng(seed)
    out = [CaseDef(s, int(rng.integers(1, 2**31 - 1)), (s,)) for s in SINGLES]
    out += [CaseDef("+".join(p), int(rng.integers(1, 2**31 - 1)), p) for p in PAIRS]
    out += [CaseDef(f"clean_{i}", int(rng.integers(1, 2**31 - 1)), ()) for i in range(n_clean)]
    out += [CaseDef(p, int(rng.integers(1, 2**31 - 1)), (p,), "positioning") for p in POSITIONING]
    if extended:
        out += [CaseDef(f"x_{s}", int(rng.integers(1, 2**31 - 1)), (s,)) for s in EXTENDED_SINGLES]
        out += [CaseDef("x_" + "+".join(p), int(rng.integers(1, 2**31 - 1)), p)
                for p in EXTENDED_PAIRS]
        out += [CaseDef(f"x_clean_{i}", int(rng.integers(1, 2**31 - 1)), ()) for i in range(4)]
    return out


# ----------------------------------------------------------------------------- design

@dataclass
class _Design:
    """What the test engineer plans: circles (plane, extra options) and laser axes."""

    circles: list[dict[str, Any]] = field(default_factory=list)
    lasers: list[str] = field(default_factory=list)
    thermal_first: str | None = None
    only_circle: bool = False
    params: dict[str, dict[str, float]] = field(default_factory=dict)
    shapes: dict[str, dict[str, float]] = field(default_factory=dict)


def _sgn(rng: np.random.Generator) -> float:
    return float(rng.choice([-1.0, 1.0]))


def _plane_of(a: str, b: str) -> str:
    for pl, (i, j) in PLANE_AXES.items():
        if {AXES[i], AXES[j]} == {a, b}:
            return pl
    raise ValueError((a, b))


def _apply_part(part: str, rng: np.random.Generator, m: Machine, d: _Design,
                exp: dict[str, float | None], either: list[set[str]],
                hidden_sq: list[float]) -> None:
    e = m.effects
    if part.startswith("squareness_"):
        i = {"xy": 0, "xz": 1, "yz": 2}[part[-2:]]
        v = _sgn(rng) * rng.uniform(8.0, 60.0)
        hidden_sq[i] = v
        exp[part] = v
        d.circles.append({"plane": {"xy": "XY", "xz": "ZX", "yz": "YZ"}[part[-2:]]})
    elif part.startswith("backlash"):
        a = {"backlash_x": "X", "backlash_y": "Y", "backlash_z": "Z"}.get(part) or \
            str(rng.choice(["X", "Y"]))
        b = rng.uniform(2.5, 12.0)
        shape = str(rng.choice(["linear", "exp", "smooth"]))
        L = float(np.exp(rng.uniform(np.log(0.03), np.log(0.5))))
        lu = ld = L
        if part == "backlash_play":
            shape = "play"
        elif part == "backlash_long":
            shape, lu = "exp", float(rng.uniform(1.0, 2.0))
            ld = lu
        elif part == "backlash_asym":
            lu, ld = L, L * rng.uniform(2.5, 4.0)
        e.lost_motion[a] = LostMotion(float(b), shape, lu, ld)
        exp[f"backlash_{a.lower()}"] = -float(b)
        if lu == ld and shape != "exp":
            d.shapes[f"backlash_{a.lower()}"] = {"takeup_mm": float(b) * 1e-3 if shape == "play"
                                                 else lu}
        d.lasers.append(a)
        other = "Y" if a != "Y" else "X"
        d.circles.append({"plane": _plane_of(a, other if a != "Z" else "Y")})
    elif part.startswith("scale"):
        a = {"scale_x": "X", "scale_y": "Y", "scale_z": "Z"}.get(part) or "X"
        k = _sgn(rng) * rng.uniform(6.0, 40.0)
        bow = 0.0
        if part == "scale_bow":
            k = _sgn(rng) * rng.uniform(0.0, 8.0)
            bow = _sgn(rng) * rng.uniform(2.0, 6.0)
        e.scale[a] = (float(k), float(bow))
        if part == "scale_xy_only":
            exp["scale_x"] = float(k)
            either.append({"scale_x", "scale_y"})
            d.only_circle = True
        else:
            exp[f"scale_{a.lower()}"] = float(k) if part != "scale_bow" else None
            if part == "scale_bow":
                d.params[f"scale_{a.lower()}"] = {"bow": float(bow)}
            d.lasers.append(a)
    elif part.startswith("cyclic_"):
        a = part[-1].upper()
        lead = float(rng.choice([4.0, 5.0, 6.35, 8.0, 10.0, 12.7, 16.0, 20.0]))
        amp = rng.uniform(0.8, 3.0)
        e.cyclic[a] = (float(amp), lead, float(rng.uniform(0, 2 * math.pi)), 0.2)
        exp[part] = float(amp)
        d.circles.append({"plane": "XY" if a in "XY" else "YZ"})
        if rng.uniform() < 0.5:
            d.lasers.append(a)
    elif part == "roll_short_z":
        # a short Z (120..200 mm) whose roll varies by tens of urad (about -10..20), lasered
        lo_z = -float(rng.choice([120.0, 150.0, 200.0]))
        m.travel["Z"] = (lo_z, 0.0)
        ref = list(m.reference)
        ref[2] = lo_z * float(rng.uniform(0.25, 0.75))
        m.reference = tuple(ref)  # type: ignore[assignment]
        for name in TERM_NAMES:     # the terms of Z again, on its new travel
            lin = name[0] == "d"
            m.terms[("Z", name)] = random_term(rng, m.travel["Z"], ref[2],
                                               (3.0 if lin else 10.0) * rng.uniform(0.5, 1.5),
                                               lin and name != "dz")
        m.terms[("Z", "ez")] = random_term(rng, m.travel["Z"], ref[2], float(rng.uniform(15.0, 30.0)),
                                           False)
        d.lasers.append("Z")
    elif part.startswith("thermal"):
        a = "Z" if part in ("thermal_time", "thermal_rise_fall_time") else str(rng.choice(["X", "Y", "Z"]))
        lo, hi = m.travel[a]
        fixed = float(lo if rng.uniform() < 0.5 else hi)
        alpha = rng.uniform(5.0, 12.0)
        off = _sgn(rng) * rng.uniform(0.5, 3.0)
        profile = ("linear" if part == "thermal_lin" else
                   "rise_fall" if part.startswith("thermal_rise_fall") else "exp")
        th = Thermal(axis=a, profile=profile,
                     t0_c=float(rng.uniform(19.0, 24.0)), rate_k_per_h=float(rng.uniform(1.5, 4.0)),
                     rise_k=float(rng.uniform(2.0, 5.0)), tau_h=float(rng.uniform(0.4, 1.5)),
                     alpha_ppm_per_k=float(alpha), fixed_mm=fixed, offset_um_per_k=float(off),
                     record_temp=part not in ("thermal_time", "thermal_rise_fall_time"),
                     sensor_k=0.02)
        e.thermal = th
        j = AXES.index(a)
        exp[f"thermal_drift_{a.lower()}"] = (float(off + alpha * (m.reference[j] - fixed) * 1e-3)
                                             if th.record_temp else None)
        d.lasers.append(a)
        d.thermal_first = a
    elif part.startswith("servo"):
        model = "delay"
        base = rng.uniform(1.0, 4.0)      # a delay with feed-forward: a few ms
        if part in ("servo_first_order", "servo_two_feeds"):
            model = "first_order"
            base = rng.uniform(12.0, 35.0)  # 1 / Kv
        taus = [base, base, base]
        ax = int(rng.integers(0, 3)) if part != "servo_delay" else int(rng.integers(0, 2))
        taus[ax] += _sgn(rng) * rng.uniform(0.6, 3.0)
        taus = [max(t, 0.0) for t in taus]
        e.servo = Servo(model, tuple(float(t) for t in taus))  # type: ignore[arg-type]
        feed = float(rng.choice([1500.0, 2500.0, 3000.0])) if model == "first_order" else \
            float(rng.choice([800.0, 1000.0, 2000.0]))
        planes = {"XY"} | ({"YZ" if ax == 2 else "ZX"} if ax == 2 or rng.uniform() < 0.3 else set())
        for pl in sorted(planes):
            d.circles.append({"plane": pl, "feed": feed, "two_feeds": part == "servo_two_feeds"})
    elif part.startswith("tool_offset"):
        t = (0.0, 0.0, float(rng.uniform(60.0, 200.0)))
        if rng.uniform() < 0.3:
            t = (float(rng.uniform(-60, 60)), 0.0, t[2])
        e.tool_offset_mm = t
        exp["tool_offset"] = float(np.linalg.norm(t))
        d.circles.append({"plane": "XY", "z_heights": int(rng.integers(2, 4))})
        if part == "tool_offset_zx":
            d.circles.append({"plane": "ZX"})
    elif part.startswith("straightness_"):
        a, t = part[-2].upper(), "d" + part[-1]
        bow = _sgn(rng) * rng.uniform(1.5, 6.0)
        e.bow[(a, t)] = float(bow)
        exp[part] = arch_sag_in_catalogue(float(bow))
        d.circles.append({"plane": _plane_of(a, t[1].upper())})
        d.lasers.append(a)
    else:
        raise ValueError(part)


def arch_sag_in_catalogue(bow_um: float) -> float:
    """The catalogue's straightness value (um) of this generator's sine arch of sag
    ``bow_um``: the catalogue's bow is the sag of a parabola, bow (1 - u²) over the axis'
    travel (u in [-1, 1], abbe.diagnose.effects: Chebyshev T0 / T2), so the arch
    bow sin(pi s) = bow cos(pi u / 2) is expressed as its least-squares parabola over the
    travel (constant, slope and sag free, uniform weight): sag = 1.0306 bow. Like with
    like: the two shapes differ beyond the parabola, and what a check sees of that
    difference depends on where it samples (docs/diagnose-validation.md, twelfth round)."""
    u, w = np.polynomial.legendre.leggauss(64)
    A = np.stack([np.ones_like(u), u, 1.0 - u * u], axis=1) * np.sqrt(w)[:, None]
    c, *_ = np.linalg.lstsq(A, np.cos(0.5 * math.pi * u) * np.sqrt(w), rcond=None)
    return float(bow_um * c[2])


def _targets(rng: np.random.Generator, lo: float, hi: float, n: int) -> np.ndarray:
    """ISO 230-2 style uneven targets over [lo, hi] (ends included)."""
    base = np.linspace(lo, hi, n)
    sp = (hi - lo) / (n - 1)
    jit = rng.uniform(-0.3, 0.3, n) * sp
    jit[0] = jit[-1] = 0.0
    return np.round(base + jit, 3)


def _circle_plans(rng: np.random.Generator, m: Machine, specs: list[dict[str, Any]]
                  ) -> list[CirclePlan]:
    out: list[CirclePlan] = []
    seen: set[tuple[str, int]] = set()
    noise = float(rng.uniform(0.08, 0.3))
    rho = float(rng.choice([0.0, 0.0, 0.3]))
    step = float(rng.choice([0.5, 1.0, 1.5, 2.0]))
    for sp in specs:
        pl = sp["plane"]
        nz = int(sp.get("z_heights", 1))
        for zi in range(nz):
            if (pl, zi) in seen:
                continue
            seen.add((pl, zi))
            a, b = PLANE_AXES[pl]
            c = [0.5 * (m.travel[ax][0] + m.travel[ax][1]) for ax in AXES]
            span = min(m.travel[AXES[a]][1] - m.travel[AXES[a]][0],
                       m.travel[AXES[b]][1] - m.travel[AXES[b]][0])
            R = float(min(rng.choice([50.0, 100.0, 150.0]), 0.4 * span))
            for k in range(3):
                if k in (a, b):
                    c[k] += rng.uniform(-0.05, 0.05) * (m.travel[AXES[k]][1] - m.travel[AXES[k]][0])
            if nz > 1:
                lo, hi = m.travel["Z"]
                c[2] = lo + (hi - lo) * (0.15 + 0.7 * zi / (nz - 1))
            feed = float(sp.get("feed", rng.choice([600.0, 1000.0, 1500.0, 2000.0])))
            name = f"circle_{pl.lower()}" + (f"_z{zi + 1}" if nz > 1 else "")
            base = dict(plane=pl, center_mm=tuple(float(v) for v in c), radius_mm=R,
                        step_deg=step, arc_deg=float(rng.choice([15.0, 30.0, 45.0])),
                        pause_s=float(rng.uniform(0.5, 3.0)), noise_um=noise, noise_rho=rho)
            out.append(CirclePlan(name=name, feed_mm_min=feed,
                                  setup_um=tuple(rng.normal(0, 4.0, 2)), **base))  # type: ignore[arg-type]
            if sp.get("two_feeds"):
                f2 = float(round(feed / rng.uniform(2.5, 4.0), -1))
                out.append(CirclePlan(name=name + "_slow", feed_mm_min=f2,
                                      setup_um=tuple(rng.normal(0, 4.0, 2)), **base))  # type: ignore[arg-type]
    return out


def _laser_plan(rng: np.random.Generator, m: Machine, a: str) -> LaserPlan:
    j = AXES.index(a)
    lo, hi = m.travel[a]
    marg = 0.02 * (hi - lo)
    T = int(rng.integers(9, 22))
    mp = default_map(a)
    if rng.uniform() < 0.4:   # a head mounted the other way round: linear reads -term
        mp["linear"] = ("-" if mp["linear"][0] == "+" else "+") + mp["linear"][1:]
    if rng.uniform() < 0.4:
        mp["yaw"] = ("-" if mp["yaw"][0] == "+" else "+") + mp["yaw"][1:]
    nl = float(rng.uniform(0.06, 0.2))
    return LaserPlan(axis=a, line_mm=tuple(float(v) for v in m.reference),
                     targets_mm=_targets(rng, lo + marg, hi - marg, T),
                     runs=int(rng.choice([4, 5, 5, 6])), feed_mm_min=float(rng.choice([500.0, 1000.0, 2000.0])),
                     dwell_s=float(rng.uniform(2.0, 6.0)), overrun_mm=float(rng.uniform(3.0, 6.0)),
                     map=mp, misalignment_urad=tuple(float(v) for v in rng.normal(0, 20.0, 2)),
                     noise_lin_um=nl, noise_str_um=1.5 * nl, noise_ang_urad=float(rng.uniform(0.2, 0.5)),
                     repeat_um=float(rng.uniform(0.03, 0.12)))


def build(case: CaseDef, out_dir: str | Path, _no_drift: bool = False) -> Built:
    """Generate the case's machine, measure it and write every file into ``out_dir``.
    ``_no_drift``: the same machine and measurements (the same random draws) with the
    thermal drift's gains zeroed (for :func:`_drift_seen_um`)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(case.seed)
    if case.kind == "positioning":
        return _build_positioning(case, out, rng)
    m = random_machine(rng)
    known_sq = tuple(float(v) for v in rng.normal(0.0, 15.0, 3))
    hidden_sq = [0.0, 0.0, 0.0]
    d = _Design(circles=[{"plane": "XY"}], lasers=["X"])
    exp: dict[str, float | None] = {}
    either: list[set[str]] = []
    for part in case.parts:
        _apply_part(part, rng, m, d, exp, either, hidden_sq)
    m.effects.squareness_urad = tuple(k + h for k, h in zip(known_sq, hidden_sq))  # type: ignore[assignment]
    if _no_drift and m.effects.thermal is not None:   # after every draw: the same stream
        m.effects.thermal.alpha_ppm_per_k = 0.0
        m.effects.thermal.offset_um_per_k = 0.0
    if d.only_circle:
        d.lasers = [x for x in d.lasers if x not in ("X", "Y")]
    model = files.fit_model(m, rng, known_sq)
    circles = _circle_plans(rng, m, d.circles)
    lasers = [_laser_plan(rng, m, a) for a in dict.fromkeys(d.lasers)]
    th = m.effects.thermal
    if d.thermal_first:
        lasers.sort(key=lambda p: p.axis != d.thermal_first)
    # campaign order: the drifting axis' laser first, then the rest of the lasers, circles
    clock = 0.0
    laser_files, circle_files = [], []
    for p in lasers:
        rec = measure_laser(m, p, clock, rng)
        f = f"laser_{p.axis.lower()}.csv"
        order = None if rng.uniform() < 0.7 else ["time_s", "direction", "run", "target_mm"]
        (out / f).write_text(files.laser_csv(rec, order))
        laser_files.append((p, f))
        clock += rec.duration_s + float(rng.uniform(60.0, 900.0))
    for cp in circles:
        if th is not None and not th.record_temp and th.axis in (AXES[i] for i in PLANE_AXES[cp.plane]):
            raise AssertionError("a time-only drift case must not circle the drifting axis")
        rec = measure_circle(m, cp, clock, rng)
        f = f"{cp.name}.csv"
        (out / f).write_text(files.ballbar_csv(rec))
        circle_files.append((cp, f))
        clock += rec.duration_s + float(rng.uniform(30.0, 600.0))
    # servo mismatch expected on every tested plane whose axes lag differently
    if m.effects.servo is not None:
        tau = m.effects.servo.tau_ms
        for cp, _ in circle_files:
            a, b = PLANE_AXES[cp.plane]
            dt = tau[b] - tau[a]
            if abs(dt) > 1e-9:
                key = f"servo_mismatch_{cp.plane.lower()}"
                exp[key] = float(dt)
                if m.effects.servo.model == "first_order":
                    d.shapes[key] = {"tau_mean_ms_if_first_order": 0.5 * (tau[a] + tau[b])}
    (out / "machine.toml").write_text(files.machine_toml(m, laser_files, circle_files, case.name))
    files.write_model(out / "model.bin", model)
    seen = {} if th is None or _no_drift else _drift_seen_um(case, out, th.axis, laser_files,
                                                              circle_files)
    return Built(case, out, exp, either, params=d.params, shapes=d.shapes, seen_um=seen,
                 machine_file=out / "machine.toml",
                 model_file=out / "model.bin",
                 info={"circles": [c.name for c, _ in circle_files],
                       "lasers": [p.axis for p, _ in laser_files],
                       "servo": None if m.effects.servo is None else
                       (m.effects.servo.model, m.effects.servo.tau_ms),
                       "lost_motion": {a: (lm.shape, lm.takeup_up_mm, lm.takeup_down_mm)
                                       for a, lm in m.effects.lost_motion.items()}})


def _csv_columns(path: Path) -> dict[str, np.ndarray]:
    """The numeric columns of a CSV file written by :mod:`.files`, by header name."""
    import csv
    with open(path, newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    out = {}
    for k in rows[0]:
        try:
            out[k] = np.array([float(r[k]) for r in rows])
        except ValueError:
            continue
    return out


def _drift_seen_um(case: CaseDef, out: Path, axis: str, laser_files: list[tuple[Any, str]],
                   circle_files: list[tuple[Any, str]]) -> dict[str, float]:
    """A thermal drift's true size on the diagnosis' size basis (docs/effects.md section 3,
    "Size"; the second generator's ``BuiltCase.seen_um``): the case built again with the
    drift's gains zeroed (the same random draws, so the same noise), and its noise-free
    image, the difference of the two files, sized as the diagnosis sizes a drift: on a
    laser line of the drifting axis (repeated runs) its linear reading with nothing removed,
    on a circle its radial deviation with the centre and radius removed; the largest."""
    import tempfile
    best = 0.0
    with tempfile.TemporaryDirectory(prefix="abbe-ind-nodrift-") as tmp:
        build(case, tmp, _no_drift=True)
        for p, f in laser_files:
            if p.axis == axis:
                d = _csv_columns(out / f)["linear_um"] - _csv_columns(Path(tmp) / f)["linear_um"]
                best = max(best, float(np.sqrt(np.mean(d * d))))
        for _, f in circle_files:
            a, b = _csv_columns(out / f), _csv_columns(Path(tmp) / f)
            th = np.radians(a["angle_deg"])
            A = np.column_stack([np.ones_like(th), np.cos(th), np.sin(th)])
            d = a["radial_um"] - b["radial_um"]
            r = d - A @ np.linalg.lstsq(A, d, rcond=None)[0]
            best = max(best, float(np.sqrt(np.mean(r * r))))
    return {f"thermal_drift_{axis.lower()}": best}


def unobservable(b: Built) -> list[str]:
    """The case's effects below the diagnosis' documented size threshold by construction
    (``min_effect_um``, 0.15 um) on every check, as the second generator's
    :func:`cases.independent2.suite.unobservable`; only effects with a ``seen_um`` (a
    thermal drift) can be. The summary counts such a case apart, it does not drop it."""
    from abbe.diagnose.results import DiagnoseOptions
    floor = DiagnoseOptions().min_effect_um
    return sorted(k for k, v in b.seen_um.items() if v < floor and k in b.expected)


def _build_positioning(case: CaseDef, out: Path, rng: np.random.Generator) -> Built:
    """An ISO 230-2 .dat of one stage axis (X), the ESS file family: few targets, microns of
    repeatability, a reversal of tens of microns."""
    part = case.parts[0]
    m = random_machine(rng)
    small = rng.uniform() < 0.6
    if small:
        lo, hi = -20.0, 20.0
        m.travel["X"] = (-25.0, 25.0)
    else:
        lo, hi = 0.0, 300.0
        m.travel["X"] = (-10.0, 310.0)
    T = int(rng.choice([9, 11, 13])) if small else int(rng.choice([11, 15, 21]))
    targets = _targets(rng, lo, hi, T)
    # rescale the smooth positioning term to a stage's tens of microns
    tm = m.terms[("X", "dx")]
    tm.travel = m.travel["X"]
    tm.leg = tm.leg * rng.uniform(3.0, 10.0)
    tm.sine_amp *= 5.0
    tm.sine_wl_mm = (hi - lo) * rng.uniform(0.3, 0.8)
    exp: dict[str, float | None] = {}
    outl: set[int] = set()
    b = rng.uniform(8.0, 35.0)
    leg: tuple[float, ...] = ()
    drift = mid = 0.0
    outliers: list[tuple[int, str, int, float]] = []
    noisy = None
    noise = float(rng.uniform(0.4, 2.0))
    if part in ("pos_reversal", "pos_reversal_drift", "pos_ess_like"):
        leg = (float(_sgn(rng) * rng.uniform(3.0, 9.0)), float(_sgn(rng) * rng.uniform(1.0, 6.0)))
    if part in ("pos_backlash_drift", "pos_reversal_drift", "pos_ess_like"):
        drift = _sgn(rng) * rng.uniform(1.5, 4.0)
        if part == "pos_ess_like":
            mid = _sgn(rng) * rng.uniform(1.0, 3.0)
    if part in ("pos_outlier", "pos_ess_like"):
        k = rng.choice(T, 2, replace=False)
        outliers = [(1, "fwd", int(i), float(_sgn(rng) * rng.uniform(60.0, 110.0))) for i in k]
        outl.add(1)
    if part == "pos_noisy_cycle":
        c = int(rng.integers(1, 6))
        noisy = (c, 8.0)
        outl.add(c)
    if part != "pos_clean":
        m.effects.lost_motion["X"] = LostMotion(float(b), "linear", 0.05, 0.05, leg)
        exp["backlash_x"] = -float(b) if not leg else None
        if leg:
            lm = m.effects.lost_motion["X"]
            rev = -lm.b_at(targets, m.travel["X"])
            exp["reversal_x"] = float(np.sqrt(np.mean((rev - rev.mean()) ** 2)))
    if drift or mid:
        exp["thermal_drift_x"] = None
    fw, bw = positioning_runs(m, "X", targets, 5, rng, noise, drift, mid, outliers=outliers,
                              noisy_cycle=noisy)
    path = out / "x_iso230_2.dat"
    path.write_text(files.ess_dat(targets, fw, bw, f"independent generator {case.name}"))
    return Built(case, out, exp, outlier_runs=outl, dat_file=path,
                 info={"noise_um": noise, "outliers": outliers, "noisy": noisy, "b": b, "leg": leg,
                       "travel_mm": m.travel["X"]})


# ----------------------------------------------------------------------------- run + score

def run(b: Built, backend: str = "auto") -> Any:
    """Diagnose the case's files as a user would (readers included)."""
    from abbe.diagnose.results import DiagnoseOptions
    from abbe.diagnose.run import diagnose_machine, diagnose_positioning
    opts = DiagnoseOptions(backend=backend)
    if b.case.kind == "positioning":
        return diagnose_positioning(b.dat_file, "X", None, opts)
    return diagnose_machine(b.machine_file, b.model_file, options=opts)


def score(b: Built, res: Any) -> dict[str, Any]:
    """Named exactly? false names, value checks, held-out shrink, outliers. Every
    component of a multi-component entry counts as a name (a spurious one is an extra)."""
    from abbe.diagnose.results import named_by_key
    named = named_by_key(res.effects)
    exp = dict(b.expected)
    # an either-group counts as one answer: accept any one member
    for grp in b.either:
        hit = [k for k in named if k in grp]
        want = [k for k in exp if k in grp]
        if hit and want and hit[0] not in exp:
            exp[hit[0]] = exp.pop(want[0])
    sign = {}
    for grp in b.either:   # an XY circle sees kx - ky: scale_y = -scale_x
        for k in grp:
            if k in exp and k not in b.expected:
                sign[k] = -1.0
    hits = [k for k in exp if k in named]
    misses = [k for k in exp if k not in named]
    extra = [k for k in named if k not in exp]
    vals = {}
    for k in hits:
        tv = exp[k]
        if tv is None:
            continue
        e = named[k]
        if k.startswith("thermal_drift") and e.unit != "um/K":
            continue
        tv = tv * sign.get(k, 1.0)
        lo, hi = e.ci95
        ok = abs(e.value - tv) <= 0.1 * abs(tv) or lo <= tv <= hi
        vals[k] = {"true": tv, "named": e.value, "ci95": [lo, hi], "ok": bool(ok)}
    for k, pars in b.params.items():
        if k not in named:
            continue
        got = {p["name"]: p for p in named[k].params}
        for pn, tv in pars.items():
            p = got.get(pn)
            if p is None:
                vals[f"{k}.{pn}"] = {"true": tv, "named": float("nan"), "ci95": [None, None],
                                     "ok": False}
                continue
            ok = abs(p["value"] - tv) <= 0.1 * abs(tv) or p["ci95"][0] <= tv <= p["ci95"][1]
            vals[f"{k}.{pn}"] = {"true": tv, "named": p["value"], "ci95": p["ci95"], "ok": bool(ok)}
    shapes = {}
    for k, sh in b.shapes.items():
        if k not in named:
            continue
        e = named[k]
        for sn, tv in sh.items():
            if sn == "takeup_mm":
                v = (e.scan or {}).get("takeup_mm")
                ci = (e.scan_ci95 or {}).get("takeup_mm") or [None, None]
            else:
                v = (e.shape or {}).get(sn)
                ci = (e.shape or {}).get(sn + "_ci95") or [None, None]
            if v is None:
                shapes[f"{k}.{sn}"] = {"true": tv, "named": None, "ok": False}
                continue
            lo = -math.inf if ci[0] is None else ci[0]
            hi = math.inf if ci[1] is None else ci[1]
            shapes[f"{k}.{sn}"] = {"true": tv, "named": v, "ci95": ci,
                                   "ok": bool(abs(v - tv) <= 0.1 * abs(tv) or lo <= tv <= hi)}
    named_out = {o.run for o in getattr(res, "outliers", []) or [] if o.excluded}
    out_ok = named_out == b.outlier_runs
    g = res.gap
    shrink = None
    if exp and g.get("held_out_before") is not None and g.get("held_out_after") is not None:
        bb, aa = g["held_out_before"].rms_um, g["held_out_after"].rms_um
        um = [v["sigma"] for v in res.noise.values() if v["unit"] == "um"]
        sig = math.sqrt(sum(x * x for x in um) / max(len(um), 1))
        exc_b = math.sqrt(max(bb * bb - sig * sig, 1e-12))
        exc_a = math.sqrt(max(aa * aa - sig * sig, 0.0))
        shrink = {"raw": 1.0 - aa / bb if bb > 0 else 0.0, "excess": 1.0 - exc_a / exc_b,
                  "before_um": bb, "after_um": aa}
    return {"case": b.case.name, "kind": b.case.kind, "expected": sorted(exp), "named": sorted(named),
            "hits": hits, "misses": misses, "extra": extra, "values": vals,
            "exact": not misses and not extra and out_ok, "outliers_expected": sorted(b.outlier_runs),
            "outliers_named": sorted(named_out), "shrink": shrink, "shapes": shapes, "tentative": bool(res.tentative),
            "ambiguous": {k: [x["key"] for x in named[k].ambiguous_with] for k in named
                          if named[k].ambiguous_with},
            "unobservable": unobservable(b), "seen_um": {k: round(v, 4) for k, v in b.seen_um.items()}}
