#!/usr/bin/env python3
"""The Klipper module's host cost: seconds per G-code move with abbe on, against
the same moves passed on untouched (stock), on this machine.

Klipper's host (klippy) plans every move in Python; what abbe adds per move is
the split into segments and one compensator step (C, through ctypes) per
segment. This drives the module's move() with a stand-in for the next transform
that only counts (so the figure is abbe's own cost, not Klipper's planning),
over a program of random moves inside the table's travel, and prints moves per
second, segments per move and the ratio. Usage:

    python3 port/klipper/bench_cost.py TABLE.bin [--lib build/lib/libabbe.so] [--moves 20000]
"""

from __future__ import annotations

import argparse
import importlib.util
import random
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def _module():
    spec = importlib.util.spec_from_file_location("abbe_klipper", HERE / "abbe.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _stubs():
    spec = importlib.util.spec_from_file_location("abbe_klipper_stubs", HERE / "stubs.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


class _Counter:
    """The next transform, counting only (no list kept: the figure is abbe's cost)."""

    def __init__(self):
        self.n = 0
        self.pos = [0.0, 0.0, 0.0, 0.0]

    def move(self, pos, speed):
        self.n += 1

    def get_position(self):
        return list(self.pos)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("table", type=Path)
    ap.add_argument("--lib", default=str(HERE.parents[1] / "build" / "lib" / "libabbe.so"))
    ap.add_argument("--moves", type=int, default=20000)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    mod = _module()
    stubs = _stubs()
    comp = mod.AbbeCompensation(stubs.Config(stubs.Printer(), {"table": str(args.table),
                                                               "library": args.lib}))
    comp.next_transform = _Counter()
    comp._enable()
    travel = comp.table.travel
    rng = random.Random(args.seed)
    # a print's moves: mostly short (0.2-5 mm) with some long travel moves
    prog = []
    p = [(lo + hi) / 2 for lo, hi in travel]
    for i in range(args.moves):
        step = 50.0 if i % 20 == 0 else rng.uniform(0.2, 5.0)
        p = [min(hi, max(lo, p[a] + rng.uniform(-step, step))) for a, (lo, hi) in enumerate(travel)]
        prog.append(p + [0.0])
    results = {}
    for label in ("stock", "abbe"):
        if label == "stock":
            comp.lib.lib.abbe_comp_disable(comp.comp)
            comp.enabled, comp.state, comp.corr_mm = False, mod.COMP_OFF, [0.0, 0.0, 0.0]
        else:
            comp._enable()
        comp.next_transform.n = 0
        t0 = time.perf_counter()
        for q in prog:
            comp.move(q, 100.0)
        dt = time.perf_counter() - t0
        results[label] = (dt, comp.next_transform.n)
    s_dt, s_n = results["stock"]
    a_dt, a_n = results["abbe"]
    print(f"table {args.table}: kappa {comp.kappa:.4f} um/mm^2, split {comp.split_mm:.2f} mm")
    print(f"stock (module passes moves on): {args.moves / s_dt:,.0f} moves/s ({s_dt / args.moves * 1e6:.1f} us/move)")
    print(f"abbe on: {args.moves / a_dt:,.0f} moves/s ({a_dt / args.moves * 1e6:.1f} us/move), "
          f"{a_n / args.moves:.2f} segments/move")
    print(f"abbe's added cost: {(a_dt - s_dt) / args.moves * 1e6:.1f} us per move")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
