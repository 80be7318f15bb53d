"""Cases of the second independent generator: build, diagnose, score.

A case is a machine (``machine.random_machine``) measured twice: at
commissioning, three 6D laser lines through the reference point that
``abbe fit`` turns into the model (a real fit with a real fit error), and later
the checks -- four circles (XY at two feeds and at a second Z height, YZ)
and laser lines of X and Y again -- on the machine with the hidden effect(s).
The declared tool offset is right (a presetter's length) except in the tool
cases, where the machine file declares none. Files are the documented ones
(docs/formats.md); the diagnosis reads them as a user's would.

Kinds: ``single`` (one effect at a typical size), ``pair`` (two effects),
``clean`` (nothing changed), ``limit`` (one effect at 0.35-0.5 x the single's size,
meant to be near the documented size threshold of 0.15 um RMS; what that gives depends
on the kind and on the checks: on seed 1909725787 a squareness of Y to Z at 1.2 x the
threshold, of X to Y 1.9 x, a drift or a tool 2.4 x, a cyclic error 3.4 x, a scale or a
backlash on the laser lines 11-19 x, a servo mismatch far above). Each built case carries
its effects' true size on the diagnosis' own basis (``BuiltCase.seen_um``), and the
scorer counts an effect case below the threshold by construction apart
(``unobservable``).
"""
from __future__ import annotations

import copy
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cases.independent2.instruments import (Circle, Effects, ballbar_rows, laser_rows, map_text,
                                           toml_vec, trace_um)
from cases.independent2.machine import AXES, random_machine

SINGLE = ["squareness_xy", "squareness_yz", "backlash_x", "backlash_y",
          "scale_x", "scale_y", "cyclic_x", "cyclic_y", "servo_mismatch_xy",
          "thermal_drift_x", "tool_offset"]
PAIRS = [("squareness_xy", "backlash_y"), ("scale_x", "cyclic_y"),
         ("servo_mismatch_xy", "squareness_yz"), ("backlash_x", "thermal_drift_x"),
         ("squareness_yz", "scale_y"), ("cyclic_x", "squareness_xy")]
LIMIT = ["squareness_xy", "backlash_x", "scale_x", "cyclic_y", "servo_mismatch_xy",
         "thermal_drift_x", "squareness_yz", "tool_offset"]


@dataclass
class Case:
    name: str
    kind: str                       # single | pair | clean | limit
    effects: tuple[str, ...]
    seed: int


@dataclass
class BuiltCase:
    case: Case
    dir: Path
    machine: Path
    model: Path
    truth: dict[str, dict[str, float]] = field(default_factory=dict)
    declared_tool_mm: float = 0.0
    true_tool_mm: float = 0.0
    #: per effect: the RMS (um) of its noise-free contribution on the check where it shows
    #: most, once the set-up the generator randomises is removed (a tool offset: nothing
    #: removed, its size at the tool tip; see ``seen_um``)
    seen_um: dict[str, float] = field(default_factory=dict)


def suite(seed: int, per_single: int = 5, per_pair: int = 3, n_clean: int = 20,
          per_limit: int = 1) -> list[Case]:
    """The case list; every case gets its own seed drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    out: list[Case] = []

    def s() -> int:
        return int(rng.integers(0, 2**31 - 1))
    for e in SINGLE:
        out += [Case(f"{e}_{i}", "single", (e,), s()) for i in range(per_single)]
    for a, b in PAIRS:
        out += [Case(f"{a}+{b}_{i}", "pair", (a, b), s()) for i in range(per_pair)]
    out += [Case(f"clean_{i}", "clean", (), s()) for i in range(n_clean)]
    for e in LIMIT:
        out += [Case(f"limit_{e}_{i}", "limit", (e,), s()) for i in range(per_limit)]
    return out


def _apply(e: str, rng: np.random.Generator, eff: Effects, sq: dict[str, float],
           limit: bool) -> tuple[dict[str, float], float]:
    """Set effect ``e`` on the machine; returns its truth (catalogue value) and tool change."""
    f = 0.35 if limit else 1.0
    sg = float(rng.choice([-1.0, 1.0]))
    if e.startswith("squareness"):
        v = sg * float(rng.uniform(15, 45)) * f
        sq[e.split("_")[1]] = v
        return {"value": v}, 0.0
    if e.startswith("backlash"):
        a = e[-1].upper()
        b = float(rng.uniform(4, 12)) * (0.5 if limit else 1.0)
        eff.play_um[a] = b
        return {"value": b}, 0.0                   # ISO reversal of d_x / d_y: +b
    if e.startswith("scale"):
        a = e[-1].upper()
        k = sg * float(rng.uniform(10, 30)) * f
        eff.scale_ppm[a] = k
        return {"value": k}, 0.0
    if e.startswith("cyclic"):
        a = e[-1].upper()
        amp = float(rng.uniform(1.0, 3.0)) * (0.4 if limit else 1.0)
        per = float(rng.uniform(5.0, 16.0))
        eff.cyclic[a] = (amp, per, float(rng.uniform(0, 2 * np.pi)))
        return {"value": amp, "period_mm": per}, 0.0
    if e.startswith("servo"):
        d = sg * float(rng.uniform(1.0, 3.0)) * (0.4 if limit else 1.0)
        eff.lag_ms["Y"] = eff.lag_ms["X"] + d
        return {"value": d}, 0.0
    if e.startswith("thermal"):
        r = sg * float(rng.uniform(4.0, 10.0)) * (0.4 if limit else 1.0)
        eff.drift_um_per_h["X"] = r
        return {"value": r}, 0.0
    if e == "tool_offset":
        t = float(rng.uniform(80, 160)) * (0.5 if limit else 1.0)
        return {"value": t}, t
    raise ValueError(e)


def _only(e: str, eff: Effects, sq: dict[str, float], tool_mm: np.ndarray,
          base: Effects, declared_mm: float) -> tuple[Effects, dict[str, float], np.ndarray]:
    """The checks' state with effect ``e`` alone (from the case's ``eff``, ``sq``, tool)
    on the effect-free ``base``: what ``e`` contributes, apart from its companion."""
    one = copy.deepcopy(base)
    sq1 = {k: 0.0 for k in sq}
    tool = np.array([0.0, 0.0, declared_mm])
    ax = e[-1].upper()
    if e.startswith("squareness"):
        sq1[e.split("_")[1]] = sq[e.split("_")[1]]
    elif e.startswith("backlash"):
        one.play_um[ax] = eff.play_um[ax]
    elif e.startswith("scale"):
        one.scale_ppm[ax] = eff.scale_ppm[ax]
    elif e.startswith("cyclic"):
        one.cyclic[ax] = eff.cyclic[ax]
    elif e.startswith("servo"):
        one.lag_ms = dict(eff.lag_ms)
    elif e.startswith("thermal"):
        one.drift_um_per_h = dict(eff.drift_um_per_h)
    elif e == "tool_offset":
        tool = np.asarray(tool_mm, float).copy()
    return one, sq1, tool


def _seen_rms(d_um: np.ndarray, angle_deg: np.ndarray | None, setup: bool = True) -> float:
    """RMS (um) of a check's noise-free contribution once the set-up the generator
    randomises is fitted to it and removed: a circle's centre and bar length (1, cos,
    sin of the angle), a laser line's zero (a constant); ``setup=False``: nothing removed."""
    if not setup:
        return float(np.sqrt(np.mean(d_um * d_um)))
    if angle_deg is None:
        A = np.ones((len(d_um), 1))
    else:
        th = np.radians(angle_deg)
        A = np.column_stack([np.ones_like(th), np.cos(th), np.sin(th)])
    r = d_um - A @ np.linalg.lstsq(A, d_um, rcond=None)[0]
    return float(np.sqrt(np.mean(r * r)))


def seen_um(m: Any, eff: Effects, sq: dict[str, float], base: Effects, declared_mm: float,
            effects: tuple[str, ...], lasers: dict[str, list[float]],
            circles: list[tuple[Circle, list[dict[str, Any]]]]) -> dict[str, float]:
    """Per effect, its true size on the basis the diagnosis' size rule uses
    (docs/effects.md section 3, "Size"): the largest RMS (um) over the checks of its
    noise-free contribution (the machine with the effect alone minus the machine without
    it, traced on the same samples) once each check's set-up is removed (``_seen_rms``),
    i.e. what the checks can see of it at all; a tool offset, which the diagnosis sizes
    at the tool tip, with nothing removed. The laser lines read their own terms (no tool, no squareness):
    their contribution is the effect's part of the linear reading (``lasers``, recorded
    with every effect on; an effect of one axis shows on that axis' line only)."""
    out: dict[str, float] = {}
    sq_true, tool_true = dict(m.squareness_urad), m.tool_mm.copy()
    for e in effects:
        one, sq1, tool1 = _only(e, eff, sq, tool_true, base, declared_mm)
        best = 0.0
        for a, vals in lasers.items():
            if e.endswith("_" + a.lower()) and not e.startswith("squareness"):
                best = max(best, _seen_rms(np.asarray(vals), None))
        for c, runs in circles:
            diffs, angs = [], []
            for r in runs:
                args = (c, r["direction"], r["arc"], r["step"], r["phase"], r["t0_h"], r["t_start"])
                m.squareness_urad, m.tool_mm = sq1, tool1
                ts, with_e = trace_um(m, one, *args)
                m.squareness_urad = {k: 0.0 for k in sq}
                m.tool_mm = np.array([0.0, 0.0, declared_mm])
                _, without = trace_um(m, base, *args)
                sgn = 1.0 if r["direction"] == "ccw" else -1.0
                th0 = -r["arc"] if r["direction"] == "ccw" else 360.0 + r["arc"]
                angs.append(th0 + sgn * np.degrees(c.feed / 60.0 * ts / c.radius))
                diffs.append(with_e - without)
            best = max(best, _seen_rms(np.concatenate(diffs), np.concatenate(angs),
                                       setup=e != "tool_offset"))
        out[e] = best
    m.squareness_urad, m.tool_mm = sq_true, tool_true
    return out


def build(case: Case, out_dir: str | Path, fit: bool = True) -> BuiltCase:
    """Write the case's files and fit its model with ``abbe fit`` (``fit=False``: the
    files and the truth only, e.g. to recompute ``seen_um`` of a case built earlier:
    every draw is the same)."""
    rng = np.random.default_rng(case.seed)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    tool_len = float(np.round(rng.uniform(60, 200), 3))
    m, targets = random_machine(rng, np.array([0.0, 0.0, tool_len]))
    eff = Effects()
    common_lag = float(rng.uniform(8, 25))
    eff.lag_ms = {a: common_lag for a in AXES}
    sq = {"xy": 0.0, "xz": 0.0, "yz": 0.0}
    truth: dict[str, dict[str, float]] = {}
    tool_change = 0.0
    for e in case.effects:
        tr, dt = _apply(e, rng, eff, sq, case.kind == "limit")
        truth[e] = tr
        tool_change += dt
    if "servo_mismatch_xy" in truth:
        # Y's lag differs from Z's too: the YZ circle sees a mismatch of its own
        truth["servo_mismatch_yz"] = {"value": eff.lag_ms["Z"] - eff.lag_ms["Y"]}
    declared = tool_len
    if tool_change:
        # the machine file declares no tool; the checks ran with one of tool_change mm
        declared = 0.0
        m.tool_mm = np.array([0.0, 0.0, tool_change])
    noise = {"laser_um": float(rng.uniform(0.05, 0.2)), "straight_um": float(rng.uniform(0.1, 0.3)),
             "angle_urad": float(rng.uniform(0.2, 0.5)), "ballbar_um": float(rng.uniform(0.08, 0.25)),
             "corr_s": float(rng.uniform(0.02, 0.15))}
    # --- commissioning: laser lines, abbe fit
    signs = {a: {ch: float(rng.choice([-1.0, 1.0])) for ch in ("linear", "straight_h", "straight_v",
                                                               "pitch", "yaw", "roll")} for a in AXES}
    (out / "laser").mkdir(exist_ok=True)
    (out / "ballbar").mkdir(exist_ok=True)
    head = ["[machine]", f'name = "ind2_{case.seed}"', ""]
    for a in AXES:
        lo, hi = m.travel[a]
        head += [f"[axes.{a}]", f"travel_mm = [{lo:.3f}, {hi:.3f}]", ""]
    head += ["[reference]", f"point_mm = {toml_vec(m.ref)}", ""]
    if declared:
        head += ["[tool]", f"offset_mm = [0.0, 0.0, {declared:.3f}]", ""]
    fit_lines = list(head)
    t_h = 0.0
    for a in AXES:
        rows, dur = laser_rows(rng, m, None, a, targets[a], signs[a], 5, t_h, noise)
        t_h += dur
        (out / "laser" / f"fit_{a.lower()}.csv").write_text("\n".join(rows) + "\n")
        start = m.ref.copy()
        end = m.ref.copy()
        start[AXES.index(a)] = targets[a][0]
        end[AXES.index(a)] = targets[a][-1]
        fit_lines += [f"[laser.{a}]", f'file = "laser/fit_{a.lower()}.csv"',
                      f"start_mm = {toml_vec(start)}", f"end_mm = {toml_vec(end)}",
                      f"map = {map_text(a, signs[a])}", ""]
    (out / "fit.toml").write_text("\n".join(fit_lines))
    r = subprocess.run([sys.executable, "-m", "abbe.cli", "fit", str(out / "fit.toml"), "-o",
                        str(out / "model"), "--no-report", "-q"], capture_output=True,
                       text=True) if fit else None
    if r is not None and r.returncode != 0:
        raise RuntimeError(f"abbe fit failed for {case.name}: {r.stderr[-2000:]}")
    # --- the checks, weeks later: the machine with the effect
    m.squareness_urad = sq
    lines = list(head)
    t_h = 0.0
    lasers: dict[str, list[float]] = {}
    circles: list[tuple[Circle, list[dict[str, Any]]]] = []
    for a in ("X", "Y"):
        lasers[a] = []
        rows, dur = laser_rows(rng, m, eff, a, targets[a], signs[a], 5, t_h, noise, lasers[a])
        t_h += dur
        (out / "laser" / f"check_{a.lower()}.csv").write_text("\n".join(rows) + "\n")
        start = m.ref.copy()
        end = m.ref.copy()
        start[AXES.index(a)] = targets[a][0]
        end[AXES.index(a)] = targets[a][-1]
        lines += [f"[laser.{a}]", f'file = "laser/check_{a.lower()}.csv"',
                  f"start_mm = {toml_vec(start)}", f"end_mm = {toml_vec(end)}",
                  f"map = {map_text(a, signs[a])}", ""]
    for c in _circles(rng, m):
        bnoise = dict(noise)
        bnoise["setup_mm"] = rng.normal(0, 0.015, 3)
        bnoise["bar_um"] = float(rng.normal(0, 3.0))
        circles.append((c, []))
        rows = ballbar_rows(rng, m, eff, c, t_h, bnoise, wrap=bool(rng.integers(0, 2)),
                            runs_out=circles[-1][1])
        t_h += 0.1
        (out / "ballbar" / f"{c.name}.csv").write_text("\n".join(rows) + "\n")
        lines += [f"[ballbar.{c.name}]", f'file = "ballbar/{c.name}.csv"', f'plane = "{c.plane}"',
                  f"center_mm = {toml_vec(c.center)}", f"radius_mm = {c.radius:.3f}",
                  f"feed_mm_min = {c.feed:.1f}", ""]
    (out / "machine.toml").write_text("\n".join(lines))
    base = Effects()
    base.lag_ms = {a: common_lag for a in AXES}
    seen = seen_um(m, eff, sq, base, declared, case.effects, lasers, circles)
    return BuiltCase(case, out, out / "machine.toml", out / "model" / "model.bin", truth,
                     declared, float(m.tool_mm[2]), seen)


def _circles(rng: np.random.Generator, m: Any) -> list[Circle]:
    tr = m.travel
    mid = np.array([(lo + hi) / 2 for lo, hi in tr.values()])
    span = np.array([hi - lo for lo, hi in tr.values()])
    rxy = float(min(150.0, 0.4 * min(span[0], span[1])))
    rz = float(min(100.0, 0.4 * min(span[2], span[0], span[1])))
    f1 = float(rng.uniform(1000, 1500))
    f2 = f1 * float(rng.uniform(2.5, 3.0))
    c = mid + rng.uniform(-0.1, 0.1, 3) * span
    z1 = tr["Z"][0] + 0.2 * span[2]
    z2 = tr["Z"][0] + 0.8 * span[2]
    cxy1 = np.array([c[0], c[1], z1])
    cxy2 = np.array([c[0], c[1], z2])
    return [Circle("xy_slow", "XY", cxy1, rxy, f1), Circle("xy_fast", "XY", cxy1, rxy, f2),
            Circle("xy_high", "XY", cxy2, rxy, f1), Circle("yz", "YZ", c, rz, f1)]


def run(b: BuiltCase) -> Any:
    from abbe.diagnose.run import diagnose_machine
    return diagnose_machine(b.machine, b.model)


def _named(res: Any) -> dict[str, Any]:
    return {e.key: e for e in res.effects}


def unobservable(b: BuiltCase) -> list[str]:
    """The case's effects that the checks cannot show above the diagnosis' documented size
    threshold by construction: the true, noise-free contribution, with the set-up the
    generator randomises removed (a tool offset: at the tool tip, nothing removed, as the
    diagnosis sizes it), has an RMS below ``min_effect_um`` (0.15 um, docs/effects.md
    section 3, "Size") on every check (``BuiltCase.seen_um``). Such a case is counted apart
    by the summary, not dropped: a name there is still reported."""
    from abbe.diagnose.results import DiagnoseOptions
    floor = DiagnoseOptions().min_effect_um
    return sorted(e for e, v in b.seen_um.items() if v < floor)


def score(b: BuiltCase, res: Any) -> dict[str, Any]:
    """Exact / undecided-with-truth / missed; false names; declared tool changed; values."""
    d = res.to_json() if hasattr(res, "to_json") else res
    effects = d["effects"]
    names = set()
    undecided_ok = set()
    for e in effects:
        key = e["key"]
        if key == "servo_mismatch":
            key = "servo_mismatch_xy"
        names.add(key)
        alts = {k for k in (e.get("undecided_between") or [])}
        if alts:
            undecided_ok |= alts | {key}
    expected = set(b.truth)

    def canon(k: str) -> str:
        return "thermal_drift_x" if k.startswith("thermal_drift") else k
    names = {canon(k) for k in names}
    undecided_ok = {canon(k) for k in undecided_ok}
    # a candidate reported possibly present (never a name): one of the candidates
    possible = {canon(p["key"]) for p in d.get("possibly_present") or []}
    exact = names == expected and not possible
    undecided = (not exact) and expected <= (names | undecided_ok | possible) and all(
        n in expected or n in undecided_ok for n in names)
    tool_changed = any(e["key"] == "tool_offset" or e["id"] == "tool_offset" for e in effects)
    values_ok = []
    for e in effects:
        k = canon(e["key"] if e["key"] != "servo_mismatch" else "servo_mismatch_xy")
        if k in b.truth and (e.get("undecided_between") is None):
            tv = b.truth[k]["value"]
            v = e["value"]
            lo, hi = (e.get("ci95") or [None, None])
            ok = abs(v - tv) <= 0.1 * abs(tv) or (lo is not None and hi is not None and lo <= tv <= hi)
            values_ok.append((k, v, tv, ok))
    below = unobservable(b)
    return {"case": b.case.name, "kind": b.case.kind, "truth": sorted(expected), "named": sorted(names),
            "exact": exact, "undecided": undecided, "possible": sorted(possible),
            "unobservable": below,
            "seen_um": {k: round(v, 4) for k, v in b.seen_um.items()},
            "false_names": sorted(names - expected - undecided_ok) if b.case.kind != "clean" else sorted(names),
            "tool_changed_where_right": tool_changed and "tool_offset" not in expected,
            "values": values_ok}


def run_suite(seed: int, work: str | Path | None = None, limit: int | None = None,
              progress: bool = True, kinds: tuple[str, ...] | None = None,
              **kw: Any) -> list[dict[str, Any]]:
    cases = suite(seed, **kw)
    if kinds:
        cases = [c for c in cases if c.kind in kinds]
    if limit:
        cases = cases[:limit]
    tmp = Path(work) if work else Path(tempfile.mkdtemp(prefix="ind2_"))
    out = []
    for c in cases:
        d = tmp / c.name
        try:
            b = build(c, d)
            res = run(b)
            s = score(b, res)
        except Exception as exc:   # a failure of the case is a result too
            s = {"case": c.name, "kind": c.kind, "truth": list(c.effects), "named": [], "exact": False,
                 "undecided": False, "false_names": [], "tool_changed_where_right": False,
                 "values": [], "error": f"{type(exc).__name__}: {exc}"[:500]}
        out.append(s)
        if progress:
            print(f"{s['case']:40s} {s['kind']:6s} exact={s['exact']!s:5s} und={s['undecided']!s:5s} "
                  f"named={s['named']} {s.get('error', '')}", flush=True)
        if not work:
            shutil.rmtree(d, ignore_errors=True)
    return out
