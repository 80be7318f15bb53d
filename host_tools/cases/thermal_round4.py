"""Issue 35, fourth round (docs/thermal.md, "Issue 35, fourth round"): model-structure
candidates R4a-R4e (:mod:`abbe.analysis.thermal.structure`), every choice made on hours 0-24
only, then scored once on the held-out hours 24-46 beside the default (R3a) and the static
MLR on 16 temperatures, and the pre-written adoption rule applied.

``python -m cases.thermal_round4 --identification-only`` from host_tools/ prints the
choices on hours 0-24 and each candidate's cost, and computes nothing on hours 24-46.
Without the flag it also prints the held-out table and the rule's verdict (a few minutes).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from abbe.analysis.thermal import structure as s4
from abbe.analysis.thermal.identify import candidates_of, cycles_of, mlr_baseline
from abbe.analysis.thermal.pipeline import TARGET_RATIO
from abbe.formats.machine import load_machine
from abbe.formats.thermal_record import read_thermal_xlsx

ROOT = Path(__file__).resolve().parents[2]
REAL_XLSX = ROOT / "third_party" / "spindle-thermal" / "data.xlsx"
REAL_MACHINE = ROOT / "examples" / "spindle_thermal" / "machine.toml"

ELIGIBLE = ("R4a", "R4b", "R4c", "R4d")  # R4e: seen post hoc in round 3, reported only
#: Candidates whose adoption needs a runtime feature the C block lacks (speed^n, n != 1).
NEEDS_C = {"R4a"}


def _rms(v: np.ndarray) -> float:
    return float(np.sqrt(np.mean(v ** 2)))


def identify_all(rec, spec):
    """Every candidate's fits per channel on hours 0-24: {name: [(fit, cands), ...]}, the
    chosen n, and the seconds each candidate cost (beyond the default)."""
    h = rec.hours
    ident = (h >= spec.identify_hours[0]) & (h < spec.identify_hours[1])
    cycle_s = spec.cycle_hours * 3600.0
    cyc = cycles_of(rec.time_s, ident, cycle_s)
    t = rec.time_s
    cands = candidates_of(rec.temps_c, list(rec.temp_names), rec.speed_rpm)
    ys = [rec.disp_um[:, k] - rec.disp_um[0, k] for k in range(len(rec.channel_names))]
    names = rec.channel_names
    out: dict[str, list] = {}
    cost: dict[str, float] = {}
    t0 = time.perf_counter()
    out["R3a"] = [(s4.default_fit(n, t, y, cands, ident, cycle_s), cands)
                  for n, y in zip(names, ys)]
    cost["R3a"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    by_n = {1.0: out["R3a"]}
    score = {}
    for n in s4.SPEED_EXPONENTS:
        cn = s4.speed_candidates(cands, n)
        if n not in by_n:
            by_n[n] = [(s4.default_fit(c, t, y, cn, ident, cycle_s), cn)
                       for c, y in zip(names, ys)]
        score[n] = sum(s4.loco_rms(t, y, cn, f.terms, cyc) / _rms(y[ident] - y[ident].mean())
                       for (f, cn), y in zip(by_n[n], ys))
    n_best = min(s4.SPEED_EXPONENTS, key=lambda n: (score[n], n))
    out["R4a"] = by_n[n_best]
    cost["R4a"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    pairs = []
    for (d, _), n, y in zip(out["R3a"], names, ys):
        allowed = (s4.heated_inputs(t, cands, ident) if d.input_set == "heated" else None)
        pairs.append(s4.pair_start(n, t, y, cands, ident, cycle_s, allowed=allowed))
    out["R4b"] = [(s4.by_loco(t, y, cands, ident, cycle_s, d, p), cands)
                  for (d, _), p, y in zip(out["R3a"], pairs, ys)]
    cost["R4b"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    rooms = [s4.room_term(n, t, y, cands, ident, cycle_s) for n, y in zip(names, ys)]
    out["R4d"] = [(s4.by_loco(t, y, cands, ident, cycle_s, d, r), cands)
                  for (d, _), r, y in zip(out["R3a"], rooms, ys)]
    cost["R4d"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    out["R4c"] = [(s4.by_forward_chain(t, y, cands, ident, cycle_s,
                                       [out["R3a"][k][0], out["R4b"][k][0], out["R4d"][k][0]]),
                   cands) for k, y in enumerate(ys)]
    cost["R4c"] = time.perf_counter() - t0 + cost["R4b"] + cost["R4d"]

    t0 = time.perf_counter()
    shared = []
    for k, y in enumerate(ys):
        best = min(out["R3a"], key=lambda fc: s4.loco_rms(t, y, cands, fc[0].terms, cyc))
        f = s4._finish(names[k], t, y, cands, [(tt.input, tt.tau_s) for tt in best[0].terms],
                       ident, cyc, "shared")
        shared.append((f, cands))
    out["R4e"] = shared
    cost["R4e"] = time.perf_counter() - t0
    return out, n_best, score, cost, ident, cyc


def describe(out, rec, ident, cyc, n_best, score, cost) -> None:
    t = rec.time_s
    print(f"[hours 0-24] R4a: sum of CV/RMS by speed exponent "
          + ", ".join(f"n={n:g}: {v:.3f}" for n, v in score.items()) + f" -> n = {n_best:g}")
    for v, fits in out.items():
        for k, (f, cn) in enumerate(fits):
            y = rec.disp_um[:, k] - rec.disp_um[0, k]
            terms = "; ".join(f"{cn[tt.input].name} {tt.tau_s / 60:.0f} min {tt.gain:+.2f}"
                              for tt in f.terms)
            print(f"[hours 0-24] {v} {rec.channel_names[k]} ({f.input_set}): LOCO CV "
                  f"{s4.loco_rms(t, y, cn, f.terms, cyc):.2f} um, forward chain "
                  f"{s4.forward_chain_rms(t, y, cn, f.terms, cyc):.2f} um; {terms}")
        print(f"[cost] {v}: {cost[v]:.1f} s")


def held_out(out, rec, ident, valid) -> None:
    t = rec.time_s
    print("\nheld-out hours 24-46 (computed once):")
    print("| channel | uncompensated | MLR on 16 T | " + " | ".join(out) + " |")
    res: dict[str, list[tuple[float, bool]]] = {v: [] for v in out}
    for k, ch in enumerate(rec.channel_names):
        y = rec.disp_um[:, k] - rec.disp_um[0, k]
        unc = _rms(y[valid])
        mlr = _rms((y - mlr_baseline(rec.temps_c, y, ident))[valid])
        cells = []
        for v, fits in out.items():
            f, cn = fits[k]
            pred = f.offset_um + (s4.states_of(t, cn, f.terms) @ np.array([tt.gain for tt in f.terms])
                                  if f.terms else 0.0)
            r = _rms((y - pred)[valid])
            res[v].append((r, r / unc <= TARGET_RATIO and r < mlr, r / unc))
            cells.append(f"{r:.2f} um ({100 * r / unc:.0f} %)")
        print(f"| {ch} | {unc:.2f} um | {mlr:.2f} um ({100 * mlr / unc:.0f} %) | "
              + " | ".join(cells) + " |")
    base = res["R3a"]
    qual = []
    for v in ELIGIBLE:
        new = res[v]
        lowers = any(n[0] < b[0] - 1e-9 for b, n in zip(base, new))
        grows = [rec.channel_names[k] for k, (b, n) in enumerate(zip(base, new))
                 if n[0] > 1.05 * b[0]]
        lost = [rec.channel_names[k] for k, (b, n) in enumerate(zip(base, new))
                if b[1] and not n[1]]
        ok = lowers and not grows and not lost
        meets = sum(n[1] for n in new)
        largest = max(n[2] for n in new)
        print(f"{v}: lowers a channel {lowers}; grows > 5 %: {grows}; stops meeting: {lost}; "
              f"qualifies: {ok}; meets {meets}/5; largest ratio {largest:.3f}"
              + ("; needs the C block's speed exponent" if v in NEEDS_C else ""))
        if ok:
            qual.append((-meets, largest, v))
    print("qualifying, in the rule's order:", [q[2] for q in sorted(qual)] or "none")


def main() -> None:
    spec = load_machine(REAL_MACHINE).extra["thermal"]
    rec = read_thermal_xlsx(REAL_XLSX)
    out, n_best, score, cost, ident, cyc = identify_all(rec, spec)
    describe(out, rec, ident, cyc, n_best, score, cost)
    if "--identification-only" in sys.argv:
        return
    h = rec.hours
    valid = (h >= spec.validate_hours[0]) & (h <= spec.validate_hours[1])
    held_out(out, rec, ident, valid)


if __name__ == "__main__":
    main()
