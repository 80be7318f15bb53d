#!/usr/bin/env python3
"""Points per second of the C library from Python (ctypes), point by point
and in one batch call, on the paper golden table. Run by scripts/bench.sh
(scripts/bench_report.py puts the result in bench/results.md).

Wall-clock times: unlike the instruction counts of the other sections they
vary with the machine and its load, so each figure is the best of several
runs over the same points.

  point by point: what host_tools/abbe/clib.py did before the batch entry
                  points (one ctypes call of abbe_error_eval_f32/_q per
                  point, its input struct filled from numpy), kept here as
                  the reference;
  batch:          CModel.error_f32 / error_q, which now hand all points to
                  abbe_error_eval_batch_f32/_q in one call.

  bench_python.py [--lib PATH] [--points N] [--json]
"""

from __future__ import annotations

import argparse
import ctypes as C
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "host_tools"))


def point_by_point_f32(cm, pos: np.ndarray) -> np.ndarray:
    """The pre-batch binding loop (clib.py before the batch entry points)."""
    from abbe.model import clib

    n = pos.shape[0]
    ds = np.zeros((n, 3), dtype=np.float32)
    tc = np.tile(cm.tref_c(), (n, 1)).astype(np.float32)
    err = np.zeros((n, 3))
    flags = np.zeros(n, dtype=np.uint32)
    inp, out = clib.InputF32(), clib.ErrorF32()
    fn = cm._lib.abbe_error_eval_f32
    for i in range(n):
        inp.pos_mm[:] = [float(v) for v in pos[i]]
        inp.dir_state[:] = [float(v) for v in ds[i]]
        inp.temp_c[:] = [float(v) for v in tc[i]]
        if fn(C.byref(cm._model), C.byref(inp), C.byref(out)) != 0:
            raise RuntimeError("abbe_error_eval_f32 failed")
        err[i] = list(out.error_um)
        flags[i] = out.flags
    return err


def point_by_point_q(cm, pos_nm: np.ndarray) -> np.ndarray:
    from abbe.model import clib

    n = pos_nm.shape[0]
    ds = np.zeros((n, 3), dtype=np.int64)
    tc = np.tile(cm.tref_mdegc(), (n, 1))
    err = np.zeros((n, 3), dtype=np.int64)
    inp, out = clib.InputQ(), clib.ErrorQ()
    fn = cm._lib.abbe_error_eval_q
    for i in range(n):
        inp.pos_nm[:] = [int(v) for v in pos_nm[i]]
        inp.dir_state_q30[:] = [int(v) for v in ds[i]]
        inp.temp_mdegc[:] = [int(v) for v in tc[i]]
        fn(C.byref(cm._model), C.byref(inp), C.byref(out))
        err[i] = list(out.error_nm)
    return err


def best_rate(fn, arg, n: int, repeats: int) -> float:
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn(arg)
        best = min(best, time.perf_counter() - t0)
    return n / best


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lib", type=Path, help="libabbe.so (default: $ABBE_LIB or build/lib)")
    ap.add_argument("--points", type=int, default=20000)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    if args.lib:
        os.environ["ABBE_LIB"] = str(args.lib)
    from abbe.formats import blob, golden
    from abbe.model import clib
    from abbe.model.table import AXES

    t = blob.quantize(golden.paper_table())
    cm = clib.CModel(blob.write_blob(t))
    lo = np.array([t.axes[a].travel_mm[0] for a in AXES])
    hi = np.array([t.axes[a].travel_mm[1] for a in AXES])
    rng = np.random.default_rng(16)
    pos = (lo + (hi - lo) * rng.random((args.points, 3))).astype(np.float32)
    pos_nm = np.round(pos.astype(np.float64) * 1e6).astype(np.int64)

    # the batch and the loop give the same numbers
    ref = point_by_point_f32(cm, pos[:500])
    got, _ = cm.error_f32(pos[:500])
    if not np.array_equal(ref, got):
        raise SystemExit("bench_python: batch and point-by-point f32 results differ")
    if not np.array_equal(point_by_point_q(cm, pos_nm[:500]), cm.error_q(pos_nm[:500])[0]):
        raise SystemExit("bench_python: batch and point-by-point q results differ")

    n = args.points
    res = {
        "points": n,
        "f32_point_by_point": best_rate(lambda a: point_by_point_f32(cm, a), pos[: n // 4], n // 4, 3),
        "f32_batch": best_rate(cm.error_f32, pos, n, 5),
        "q_point_by_point": best_rate(lambda a: point_by_point_q(cm, a), pos_nm[: n // 4], n // 4, 3),
        "q_batch": best_rate(cm.error_q, pos_nm, n, 5),
        "simd": int(cm._model.simd),
    }
    if args.json:
        print(json.dumps(res))
    else:
        for k in ("f32", "q"):
            pb, b = res[f"{k}_point_by_point"], res[f"{k}_batch"]
            print(f"{k}: point by point {pb:,.0f} points/s, batch {b:,.0f} points/s ({b / pb:.0f}x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
