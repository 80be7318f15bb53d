#!/usr/bin/env python3
"""How often a diagnosed value's 95 % interval holds the truth, on one case kind of the
team's independent suite redrawn with fresh case seeds (not run by the tests).

A round of the suite states each value once; a value outside its interval there may be
the 5 % a calibrated interval leaves, or a bias. This redraws the case kind (the same
generator, the same pipeline: ``cases.independent.suite.build`` and ``run``) N times
and counts the truth inside the interval of the named effect whose key starts with
KEY (e.g. ``thermal_drift``: the generator draws the axis), and the values both more
than 10 % off and outside (the done-when's miss).

Run from host_tools/:
    ../.venv/bin/python bench/bench_value_coverage.py x_thermal_rise_fall thermal_rise_fall \\
        thermal_drift --draws 60 --seed 23
"""

from __future__ import annotations

import argparse
import random
import shutil
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from cases.independent.suite import CaseDef, build, run, score  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("case", help="the case's name in the suite (e.g. x_thermal_rise_fall)")
    ap.add_argument("hidden", help="the hidden effect drawn (e.g. thermal_rise_fall)")
    ap.add_argument("key", help="the start of the named effect's key (e.g. thermal_drift)")
    ap.add_argument("--draws", type=int, default=60)
    ap.add_argument("--seed", type=int, default=1, help="seeds the case seeds")
    a = ap.parse_args()
    rng = random.Random(a.seed)
    named = inside = off_and_outside = 0
    for _ in range(a.draws):
        case_seed = rng.randrange(2**31)
        work = Path(tempfile.mkdtemp(prefix="abbe-coverage-"))
        try:
            b = build(CaseDef(a.case, case_seed, (a.hidden,)), work / "case")
            res = run(b)
            s = score(b, res)
        finally:
            shutil.rmtree(work, ignore_errors=True)
        keys = [k for k in s["values"] if k.startswith(a.key)]
        if not keys:
            print(f"{case_seed}: no {a.key}* value named ({s['named']})", flush=True)
            continue
        v = s["values"][keys[0]]
        lo, hi = next(e["ci95"] for e in res.to_json()["effects"] if e["key"] == keys[0])
        ins = lo <= v["true"] <= hi
        off = abs(v["named"] - v["true"]) > 0.1 * abs(v["true"])
        named += 1
        inside += ins
        off_and_outside += off and not ins
        print(f"{case_seed}: {keys[0]} true {v['true']:.4f}, named {v['named']:.4f} "
              f"[{lo:.4f}, {hi:.4f}], inside {ins}", flush=True)
    print(f"named {named} / {a.draws}; truth inside its 95 % interval {inside} / {named}; "
          f"more than 10 % off and outside {off_and_outside} / {named}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
