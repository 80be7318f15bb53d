#!/usr/bin/env python3
"""Benchmark of the five-axis discrepancy workflow (abbe.diagnose.five_axis) on hidden effects
(cases.five_axis_hidden: clean, cyclic ECC, pivot drift, C wobble): named exactly, false names on clean
machines, value within its 95 % interval, median held-out shrink.

    python bench_five_axis_diagnose.py --per-kind 8 [--suite independent]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from abbe.analysis.five_axis.data import load_plan  # noqa: E402
from abbe.diagnose.five_axis import diagnose_five_axis  # noqa: E402
from abbe.formats.machine import load_machine  # noqa: E402
from cases.five_axis_hidden import KINDS, make_case  # noqa: E402


def run(per_kind: int, first_seed: int = 0, passes: int = 2) -> list[dict]:
    rows = []
    with tempfile.TemporaryDirectory(prefix="abbe-5ax-diag-") as d:
        for kind in KINDS:
            for seed in range(first_seed, first_seed + per_kind):
                mf, expected, amp = make_case(kind, seed, Path(d) / f"{kind}{seed}", passes)
                spec = load_machine(mf).five_axis
                diag = diagnose_five_axis(spec, load_plan(spec).blocks)
                names = [n.effect.key for n in diag.named]
                n0 = diag.named[0] if diag.named else None
                amb = any(n.ambiguous_with for n in diag.named)
                rows.append({"kind": kind, "seed": seed, "kin": spec.geometry.kind,
                             "expected": expected, "named": names, "ambiguous": amb,
                             "exact": names == ([expected] if expected else []) and not amb,
                             "amp_true": amp, "amp": n0.amplitude if n0 else None,
                             "amp_ci": n0.amplitude_ci95 if n0 else None,
                             "before": diag.base.heldout_after_um,
                             "after": diag.final.heldout_after_um, "shrink": diag.shrink,
                             "floor": diag.noise_floor_um, "excess": diag.excess_shrink,
                             "gap_before": diag.gap_before_um, "gap_after": diag.gap_after_um})
    return rows


def _twin(r: dict) -> float:
    """Shrink of the gap above the clean twin's held-out gap f (independent suite):
    1 - sqrt(max(a^2 - f^2, 0) / (b^2 - f^2)); nan when b <= f."""
    f, b, a = r["twin"], r["before"], r["after"]
    return 1.0 - float(np.sqrt(max(a * a - f * f, 0.0) / (b * b - f * f))) if b > f else float("nan")


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--per-kind", type=int, default=8)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--passes", type=int, default=2, choices=(1, 2),
                    help="probing passes: 2 = the diagnosis plan (default), 1 = the grid once")
    ap.add_argument("--suite", choices=("hidden", "independent"), default="hidden",
                    help="hidden: cases.five_axis_hidden (abbe.sim); independent: "
                         "cases.five_axis_independent (its own kinematics and writers)")
    a = ap.parse_args()
    if a.suite == "independent":
        from cases.five_axis_suite import diagnose_cases
        with tempfile.TemporaryDirectory(prefix="abbe-5ax-diag-") as d:
            rows = diagnose_cases(a.per_kind, Path(d), a.first_seed, a.passes)
    else:
        rows = run(a.per_kind, a.first_seed, a.passes)
    print("| kind | seed | expected | named | amplitude true | named (95 %) | held-out before um "
          "| after um | raw shrink | centre noise um | gap before um | gap after um | gap shrink "
          "| clean twin um | twin excess shrink |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        amp = "-" if r["amp"] is None else f"{r['amp']:.2f} +- {r['amp_ci']:.2f}"
        gb = "-" if r["gap_before"] is None else f"{r['gap_before']:.3f}"
        ga = "-" if r["gap_after"] is None else f"{r['gap_after']:.3f}"
        named = ", ".join(r["named"]) + (" (ambiguous)" if r["ambiguous"] else "")
        print(f"| {r['kind']} | {r['seed']} | {r['expected'] or '-'} | {named or '-'} "
              f"| {r['amp_true']:.2f} | {amp} | {r['before']:.3f} | {r['after']:.3f} | "
              f"{r['shrink']:.0%} | {r['floor']:.3f} | {gb} | {ga} | "
              + ("-" if r["excess"] is None else f"{r['excess']:.0%}") + " | "
              + ("-" if r.get("twin") is None else f"{r['twin']:.3f} | {_twin(r):.0%}") + " |")
    eff = [r for r in rows if r["expected"]]
    clean = [r for r in rows if not r["expected"]]
    within = [r for r in eff if r["exact"] and abs(r["amp"] - r["amp_true"]) <= max(r["amp_ci"],
                                                                                    0.1 * r["amp_true"])]
    exc = [r["excess"] for r in eff if r["excess"] is not None]
    tw = [_twin(r) for r in eff if r.get("twin") is not None]
    print(f"\nnamed exactly: {sum(r['exact'] for r in eff)} / {len(eff)}; false names on clean: "
          f"{sum(bool(r['named']) for r in clean)} / {len(clean)}; amplitude within 95 % "
          f"(or 10 %): {len(within)} / {len(eff)}; median held-out shrink with an effect: "
          f"{np.median([r['shrink'] for r in eff]):.0%} (raw), "
          f"{np.median(exc) if exc else float('nan'):.0%} of the gap (held-out above a right "
          f"model's floor; {len(exc)} cases with a gap); kinematics: "
          f"{sum(r['kin'] == 'xyzac-trt' for r in rows)} A/C, "
          f"{sum(r['kin'] == 'xyzbc-trt' for r in rows)} B/C")
    print("\n| kind | cases | named exactly | false / other names | median raw shrink "
          "| median gap shrink (cases with a gap) | median twin excess shrink |")
    print("|---|---|---|---|---|---|---|")
    for kind in dict.fromkeys(r["kind"] for r in rows):
        rk = [r for r in rows if r["kind"] == kind]
        ex_k = [r["excess"] for r in rk if r["excess"] is not None]
        tw_k = [_twin(r) for r in rk if r.get("twin") is not None and r["expected"]]
        tw_k = [x for x in tw_k if np.isfinite(x)]
        print(f"| {kind} | {len(rk)} | {sum(r['exact'] for r in rk)} | "
              f"{sum(bool(r['named']) and not r['exact'] for r in rk)} | "
              f"{np.median([r['shrink'] for r in rk]):.0%} | "
              + (f"{np.median(ex_k):.0%} ({len(ex_k)})" if ex_k else "-") + " | "
              + (f"{np.median(tw_k):.0%}" if tw_k else "-") + " |")
    if tw:
        tw_ok = [x for x in tw if np.isfinite(x)]
        print(f"shrink of the gap above the clean twin's (same machine and noise): median "
              f"{np.median(tw_ok):.0%} over {len(tw_ok)} effect cases with a gap above it, "
              f">= 70 % in {sum(x >= 0.7 for x in tw_ok)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
