"""Run the second independent generator's suite (issue 36) and print its figures.

python host_tools/bench/bench_independent2.py [--seed S] [--per-single N] [--per-pair N]
       [--clean N] [--per-limit N] [--json OUT.json]

Without --seed a fresh seed is drawn (and printed) so a report never reuses the
seeds the selection was looked at with.
"""
from __future__ import annotations

import argparse
import json
import secrets
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from cases.independent2.suite import run_suite  # noqa: E402


def summarise(rows: list[dict]) -> dict:
    """The suite's figures. An effect case whose effect the checks cannot show above the
    size threshold by construction (``suite.unobservable``: its true noise-free contribution,
    set-up removed, below 0.15 um RMS on every check) is counted apart: ``unobservable`` lists
    them with what was named, and the figures of the rest are ``observable_*``. A tool
    offset is sized at the tool tip (nothing removed), as the diagnosis sizes it."""
    eff = [r for r in rows if r["kind"] != "clean"]
    clean = [r for r in rows if r["kind"] == "clean"]
    vals = [v for r in rows for v in r["values"]]
    seen = [r for r in eff if not r.get("unobservable")]
    return {
        "observable_effect_cases": len(seen),
        "observable_exact": sum(r["exact"] for r in seen),
        "observable_undecided_with_truth": sum(r["undecided"] for r in seen),
        "unobservable": [f"{r['case']}: {r['unobservable']} true size "
                         f"{ {k: r['seen_um'][k] for k in r['unobservable']} } um, named {r['named']}"
                         for r in eff if r.get("unobservable")],
        "effect_cases": len(eff),
        "exact": sum(r["exact"] for r in eff),
        "undecided_with_truth": sum(r["undecided"] for r in eff),
        "by_kind": {k: [sum(r["exact"] for r in eff if r["kind"] == k),
                        sum(r["undecided"] for r in eff if r["kind"] == k),
                        sum(1 for r in eff if r["kind"] == k)] for k in ("single", "pair", "limit")},
        # a candidate reported possibly present counts as a name on a clean machine (strict)
        "clean": len(clean), "clean_with_a_name": sum(bool(r["named"] or r.get("possible"))
                                                      for r in clean),
        "clean_with_possible_only": sum(bool(r.get("possible")) and not r["named"] for r in clean),
        "declared_tool_changed_where_right": sum(r["tool_changed_where_right"] for r in rows),
        "values_ok": [sum(v[3] for v in vals), len(vals)],
        "errors": [r["case"] + ": " + r["error"] for r in rows if r.get("error")],
        "misses": [f"{r['case']}: truth {r['truth']} named {r['named']}" for r in eff
                   if not (r["exact"] or r["undecided"])] +
                  [f"{r['case']}: named {r['named']} possibly {r.get('possible', [])}"
                   for r in clean if r["named"] or r.get("possible")],
    }


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--per-single", type=int, default=5)
    ap.add_argument("--per-pair", type=int, default=3)
    ap.add_argument("--clean", type=int, default=20)
    ap.add_argument("--per-limit", type=int, default=1)
    ap.add_argument("--json", default=None)
    ap.add_argument("--kinds", default=None, help="comma list of single,pair,clean,limit")
    a = ap.parse_args()
    seed = a.seed if a.seed is not None else secrets.randbelow(2**31)
    print(f"seed {seed}", flush=True)
    t = time.time()
    rows = run_suite(seed, per_single=a.per_single, per_pair=a.per_pair, n_clean=a.clean,
                     per_limit=a.per_limit,
                     kinds=tuple(a.kinds.split(",")) if a.kinds else None)
    s = summarise(rows)
    s["seed"] = seed
    s["seconds"] = round(time.time() - t, 1)
    print(json.dumps(s, indent=1))
    if a.json:
        Path(a.json).write_text(json.dumps({"summary": s, "rows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
